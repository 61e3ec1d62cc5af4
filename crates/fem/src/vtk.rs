//! ParaView output and read-back: VTK XML `.vtu` (unstructured grid) and `.pvd` (collection).
//!
//! [`UnstructuredGrid`] is a data model independent of [`Mesh`], so any piece can be written: the
//! fluid mesh, the solid mesh, interface segments. [`UnstructuredGrid::from_mesh`] maps a mesh's
//! cells to VTK cell types; our node order *is* VTK's (see [`crate::element`]), so connectivity
//! is copied unchanged.
//!
//! Files are VTK XML version 1.0 with `header_type="UInt64"`, little-endian, every array inline
//! with `format="binary"`: base64 of `[u64 byte length][little-endian data]` (one base64 stream).
//! Points and data are `Float64`, connectivity and offsets `Int64`, types `UInt8`.
//!
//! Writes are atomic: the file is written next to its destination under a `.tmp` name, synced,
//! and renamed onto the destination, so a crash never leaves a half-written `.vtu` or `.pvd`.
//! Non-finite values (NaN, inf) are refused with an error naming the array.
//!
//! [`PvdSeries`] writes a time series (`stem_<part>_<index:06>.vtu`) and rewrites `stem.pvd`
//! after each file, so a run killed at any moment leaves a valid collection that lists only
//! completely written files.
//!
//! [`read_vtu`] and [`read_pvd`] read back what the writers write (and ASCII arrays, `UInt32`
//! headers, any integer/float array type), for tests and post-processing.

use crate::element::ReferenceCell;
use crate::mesh::{GeometryOrder, Mesh};
use base64::engine::general_purpose::STANDARD;
use base64::Engine as _;
use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Errors of the VTK writers and readers.
#[derive(Debug, Error)]
pub enum VtkError {
    /// An I/O operation on `path` failed.
    #[error("{}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    /// An array holds NaN or an infinity; nothing was written.
    #[error("array '{array}' has the non-finite value {value} at index {index}; refusing to write it")]
    NonFinite { array: String, index: usize, value: f64 },
    /// An array's length does not match the grid.
    #[error("array '{array}' has {got} values, expected {expected}")]
    LengthMismatch { array: String, expected: usize, got: usize },
    /// The grid or an argument is inconsistent (bad cell, duplicate array name, bad file name...).
    #[error("{0}")]
    Invalid(String),
    /// A file could not be read as a `.vtu`/`.pvd`.
    #[error("{}: {message}", .path.display())]
    Read { path: PathBuf, message: String },
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> VtkError + '_ {
    move |source| VtkError::Io { path: path.to_path_buf(), source }
}

/// The VTK cell types used here, with their VTK ids.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum VtkCellType {
    Vertex = 1,
    Line = 3,
    Triangle = 5,
    Quad = 9,
    Tetra = 10,
    Hexahedron = 12,
    QuadraticEdge = 21,
    QuadraticTriangle = 22,
    QuadraticQuad = 23,
    QuadraticTetra = 24,
    BiquadraticQuad = 28,
    TriquadraticHexahedron = 29,
}

impl VtkCellType {
    /// All supported cell types.
    pub const ALL: [VtkCellType; 12] = [
        VtkCellType::Vertex,
        VtkCellType::Line,
        VtkCellType::Triangle,
        VtkCellType::Quad,
        VtkCellType::Tetra,
        VtkCellType::Hexahedron,
        VtkCellType::QuadraticEdge,
        VtkCellType::QuadraticTriangle,
        VtkCellType::QuadraticQuad,
        VtkCellType::QuadraticTetra,
        VtkCellType::BiquadraticQuad,
        VtkCellType::TriquadraticHexahedron,
    ];

    /// Number of nodes of a cell of this type.
    pub fn num_nodes(self) -> usize {
        use VtkCellType::*;
        match self {
            Vertex => 1,
            Line => 2,
            Triangle => 3,
            Quad => 4,
            Tetra => 4,
            Hexahedron => 8,
            QuadraticEdge => 3,
            QuadraticTriangle => 6,
            QuadraticQuad => 8,
            QuadraticTetra => 10,
            BiquadraticQuad => 9,
            TriquadraticHexahedron => 27,
        }
    }

    /// The VTK id (`types` array value).
    pub fn id(self) -> u8 {
        self as u8
    }

    /// The cell type of VTK id `id`, if supported.
    pub fn from_id(id: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.id() == id)
    }

    /// The VTK type of a mesh cell at a geometric order.
    pub fn from_cell(cell: ReferenceCell, order: GeometryOrder) -> Self {
        use GeometryOrder::*;
        use ReferenceCell::*;
        match (cell, order) {
            (Segment, Linear) => VtkCellType::Line,
            (Segment, Quadratic) => VtkCellType::QuadraticEdge,
            (Triangle, Linear) => VtkCellType::Triangle,
            (Triangle, Quadratic) => VtkCellType::QuadraticTriangle,
            (Quadrilateral, Linear) => VtkCellType::Quad,
            (Quadrilateral, Quadratic) => VtkCellType::BiquadraticQuad,
            (Tetrahedron, Linear) => VtkCellType::Tetra,
            (Tetrahedron, Quadratic) => VtkCellType::QuadraticTetra,
            (Hexahedron, Linear) => VtkCellType::Hexahedron,
            (Hexahedron, Quadratic) => VtkCellType::TriquadraticHexahedron,
        }
    }
}

/// A named point or cell array: `values[i * components + k]` is component `k` of tuple `i`.
#[derive(Clone, Debug, PartialEq)]
pub struct DataArray {
    pub name: String,
    pub components: usize,
    pub values: Vec<f64>,
}

impl DataArray {
    /// A new array (unchecked; the grid checks it when it is added or written).
    pub fn new(name: impl Into<String>, components: usize, values: Vec<f64>) -> Self {
        DataArray { name: name.into(), components, values }
    }
}

/// An unstructured grid in VTK's layout: points in 3D, cells as flat connectivity with end
/// offsets (cell `c` is `connectivity[offsets[c-1]..offsets[c]]`, with `offsets[-1] = 0`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UnstructuredGrid {
    pub points: Vec<[f64; 3]>,
    pub connectivity: Vec<usize>,
    pub offsets: Vec<usize>,
    pub cell_types: Vec<VtkCellType>,
    pub point_data: Vec<DataArray>,
    pub cell_data: Vec<DataArray>,
}

impl UnstructuredGrid {
    /// A grid with `points` and no cells.
    pub fn new(points: Vec<[f64; 3]>) -> Self {
        UnstructuredGrid { points, ..Default::default() }
    }

    /// The grid of a mesh: its nodes (2D padded with `z = 0`) and cells in VTK types.
    ///
    /// # Panics
    /// If `D > 3`.
    pub fn from_mesh<const D: usize>(mesh: &Mesh<D>) -> Self {
        assert!(D <= 3, "VTK points have at most 3 coordinates, the mesh has {D}");
        let points = mesh.points.iter().map(|p| std::array::from_fn(|d| if d < D { p[d] } else { 0.0 })).collect();
        let n = mesh.nodes_per_cell();
        let nc = mesh.num_cells();
        UnstructuredGrid {
            points,
            connectivity: mesh.cell_nodes[..nc * n].to_vec(),
            offsets: (1..=nc).map(|c| c * n).collect(),
            cell_types: vec![VtkCellType::from_cell(mesh.cell_type, mesh.order); nc],
            point_data: Vec::new(),
            cell_data: Vec::new(),
        }
    }

    /// Number of points.
    pub fn num_points(&self) -> usize {
        self.points.len()
    }

    /// Number of cells.
    pub fn num_cells(&self) -> usize {
        self.cell_types.len()
    }

    /// Nodes of cell `c`.
    pub fn cell(&self, c: usize) -> &[usize] {
        let start = if c == 0 { 0 } else { self.offsets[c - 1] };
        &self.connectivity[start..self.offsets[c]]
    }

    /// Appends a cell; its node count must match its type.
    pub fn push_cell(&mut self, cell_type: VtkCellType, nodes: &[usize]) -> Result<(), VtkError> {
        if nodes.len() != cell_type.num_nodes() {
            return Err(VtkError::Invalid(format!("a {cell_type:?} cell has {} nodes, got {}", cell_type.num_nodes(), nodes.len())));
        }
        self.connectivity.extend_from_slice(nodes);
        self.offsets.push(self.connectivity.len());
        self.cell_types.push(cell_type);
        Ok(())
    }

    /// Adds a point array of `components` components (`num_points() * components` values).
    pub fn add_point_data(&mut self, name: &str, components: usize, values: Vec<f64>) -> Result<(), VtkError> {
        let array = checked_array(&self.point_data, name, components, values, self.num_points())?;
        self.point_data.push(array);
        Ok(())
    }

    /// Adds a cell array of `components` components (`num_cells() * components` values).
    pub fn add_cell_data(&mut self, name: &str, components: usize, values: Vec<f64>) -> Result<(), VtkError> {
        let array = checked_array(&self.cell_data, name, components, values, self.num_cells())?;
        self.cell_data.push(array);
        Ok(())
    }

    /// The point array named `name`.
    pub fn point_array(&self, name: &str) -> Option<&DataArray> {
        self.point_data.iter().find(|a| a.name == name)
    }

    /// The cell array named `name`.
    pub fn cell_array(&self, name: &str) -> Option<&DataArray> {
        self.cell_data.iter().find(|a| a.name == name)
    }

    /// Checks the structure (offsets, node counts and indices, array lengths and names) and that
    /// every value is finite. [`write_vtu`] calls this before it creates any file.
    pub fn validate(&self) -> Result<(), VtkError> {
        self.check_structure()?;
        self.check_finite()
    }

    /// Structural checks (everything in [`Self::validate`] except finiteness).
    fn check_structure(&self) -> Result<(), VtkError> {
        self.check_cells()?;
        check_arrays(&self.point_data, self.num_points(), "point")?;
        check_arrays(&self.cell_data, self.num_cells(), "cell")
    }

    /// Offsets, node counts per type, node indices.
    fn check_cells(&self) -> Result<(), VtkError> {
        if self.offsets.len() != self.cell_types.len() {
            return Err(VtkError::LengthMismatch { array: "offsets".into(), expected: self.cell_types.len(), got: self.offsets.len() });
        }
        let mut start = 0;
        for (c, (&end, &ty)) in self.offsets.iter().zip(&self.cell_types).enumerate() {
            if end < start || end > self.connectivity.len() || end - start != ty.num_nodes() {
                return Err(VtkError::Invalid(format!(
                    "cell {c} ({ty:?}, {} nodes) has offsets {start}..{end} (connectivity length {})",
                    ty.num_nodes(),
                    self.connectivity.len()
                )));
            }
            start = end;
        }
        if start != self.connectivity.len() {
            return Err(VtkError::LengthMismatch { array: "connectivity".into(), expected: start, got: self.connectivity.len() });
        }
        let np = self.num_points();
        match self.connectivity.iter().position(|&n| n >= np) {
            Some(i) => {
                Err(VtkError::Invalid(format!("connectivity entry {i} refers to node {}, but the grid has {np} points", self.connectivity[i])))
            }
            None => Ok(()),
        }
    }

    /// Every point coordinate and data value is finite.
    fn check_finite(&self) -> Result<(), VtkError> {
        check_finite("Points", self.points.iter().flatten().copied())?;
        for a in self.point_data.iter().chain(&self.cell_data) {
            check_finite(&a.name, a.values.iter().copied())?;
        }
        Ok(())
    }
}

/// Builds an array after checking its name (non-empty, unique among `existing`) and length.
fn checked_array(existing: &[DataArray], name: &str, components: usize, values: Vec<f64>, tuples: usize) -> Result<DataArray, VtkError> {
    if existing.iter().any(|a| a.name == name) {
        return Err(VtkError::Invalid(format!("an array named '{name}' already exists")));
    }
    let array = DataArray::new(name, components, values);
    check_array(&array, tuples)?;
    Ok(array)
}

/// Name, component count and length of one array with `tuples` tuples.
fn check_array(a: &DataArray, tuples: usize) -> Result<(), VtkError> {
    if a.name.is_empty() {
        return Err(VtkError::Invalid("a data array has an empty name".into()));
    }
    if a.components == 0 {
        return Err(VtkError::Invalid(format!("array '{}' has 0 components", a.name)));
    }
    let expected = tuples * a.components;
    if a.values.len() != expected {
        return Err(VtkError::LengthMismatch { array: a.name.clone(), expected, got: a.values.len() });
    }
    Ok(())
}

/// Checks every array of a list (`kind` is "point" or "cell", for messages) and name uniqueness.
fn check_arrays(arrays: &[DataArray], tuples: usize, kind: &str) -> Result<(), VtkError> {
    for (i, a) in arrays.iter().enumerate() {
        check_array(a, tuples)?;
        if arrays[..i].iter().any(|b| b.name == a.name) {
            return Err(VtkError::Invalid(format!("two {kind} arrays are named '{}'", a.name)));
        }
    }
    Ok(())
}

/// The first non-finite value of an array, as an error naming the array.
fn check_finite(array: &str, values: impl Iterator<Item = f64>) -> Result<(), VtkError> {
    for (index, value) in values.enumerate() {
        if !value.is_finite() {
            return Err(VtkError::NonFinite { array: array.to_string(), index, value });
        }
    }
    Ok(())
}

// ------------------------------------------------------------------------------------------------
// Writing
// ------------------------------------------------------------------------------------------------

/// Writes `grid` to `path` as a VTK XML unstructured grid (binary inline, UInt64 headers),
/// atomically. Refuses grids that fail [`UnstructuredGrid::validate`] (e.g. NaN values) before
/// creating any file.
pub fn write_vtu(path: &Path, grid: &UnstructuredGrid) -> Result<(), VtkError> {
    grid.validate()?;
    write_atomically(path, |w| write_vtu_body(w, grid))
}

/// Runs `body` on a buffered writer to a temporary file beside `path`, syncs it and renames it
/// onto `path`; the temporary file is removed if anything fails.
fn write_atomically(path: &Path, body: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>) -> Result<(), VtkError> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut w = BufWriter::new(File::create(&tmp).map_err(io_err(&tmp))?);
        body(&mut w).map_err(io_err(&tmp))?;
        let file = w.into_inner().map_err(|e| io_err(&tmp)(e.into_error()))?;
        file.sync_all().map_err(io_err(&tmp))?;
        fs::rename(&tmp, path).map_err(io_err(path))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    } else {
        sync_parent_dir(path);
    }
    result
}

/// `path` with `.tmp` appended to its file name (same directory, so the rename is atomic).
fn temp_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(".tmp");
    path.with_file_name(name)
}

/// Best-effort sync of the directory holding `path`, so the rename itself is durable.
fn sync_parent_dir(path: &Path) {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// The XML of a `.vtu` file.
fn write_vtu_body<W: Write>(w: &mut W, grid: &UnstructuredGrid) -> io::Result<()> {
    writeln!(w, r#"<?xml version="1.0"?>"#)?;
    writeln!(w, r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#)?;
    writeln!(w, "  <UnstructuredGrid>")?;
    writeln!(w, r#"    <Piece NumberOfPoints="{}" NumberOfCells="{}">"#, grid.num_points(), grid.num_cells())?;
    write_data_section(w, "PointData", &grid.point_data)?;
    write_data_section(w, "CellData", &grid.cell_data)?;
    writeln!(w, "      <Points>")?;
    let coords = grid.points.iter().flatten().map(|v| v.to_le_bytes());
    write_binary_array(w, "Float64", "Points", 3, grid.num_points() * 3, coords)?;
    writeln!(w, "      </Points>")?;
    write_cells(w, grid)?;
    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </UnstructuredGrid>")?;
    writeln!(w, "</VTKFile>")
}

/// A `<PointData>`/`<CellData>` section with its Float64 arrays.
fn write_data_section<W: Write>(w: &mut W, tag: &str, arrays: &[DataArray]) -> io::Result<()> {
    writeln!(w, "      <{tag}>")?;
    for a in arrays {
        let bytes = a.values.iter().map(|v| v.to_le_bytes());
        write_binary_array(w, "Float64", &a.name, a.components, a.values.len(), bytes)?;
    }
    writeln!(w, "      </{tag}>")
}

/// The `<Cells>` section: Int64 connectivity and offsets, UInt8 types.
fn write_cells<W: Write>(w: &mut W, grid: &UnstructuredGrid) -> io::Result<()> {
    writeln!(w, "      <Cells>")?;
    let conn = grid.connectivity.iter().map(|&n| (n as i64).to_le_bytes());
    write_binary_array(w, "Int64", "connectivity", 1, grid.connectivity.len(), conn)?;
    let offsets = grid.offsets.iter().map(|&n| (n as i64).to_le_bytes());
    write_binary_array(w, "Int64", "offsets", 1, grid.offsets.len(), offsets)?;
    let types = grid.cell_types.iter().map(|t| [t.id()]);
    write_binary_array(w, "UInt8", "types", 1, grid.cell_types.len(), types)?;
    writeln!(w, "      </Cells>")
}

/// One inline binary `<DataArray>` of `count` values of `N` bytes each.
fn write_binary_array<W: Write, const N: usize>(
    w: &mut W,
    vtk_type: &str,
    name: &str,
    components: usize,
    count: usize,
    values: impl Iterator<Item = [u8; N]>,
) -> io::Result<()> {
    write!(w, r#"        <DataArray type="{vtk_type}" Name="{}" NumberOfComponents="{components}" format="binary">"#, xml_escape(name))?;
    write_base64_block(w, (count * N) as u64, values)?;
    writeln!(w, "</DataArray>")
}

/// Base64 of `[nbytes as u64 LE][values...]`, as one stream.
fn write_base64_block<W: Write, const N: usize>(w: &mut W, nbytes: u64, values: impl Iterator<Item = [u8; N]>) -> io::Result<()> {
    const CHUNK: usize = 1 << 15;
    let mut enc = base64::write::EncoderWriter::new(&mut *w, &STANDARD);
    enc.write_all(&nbytes.to_le_bytes())?;
    let mut buf = Vec::with_capacity(CHUNK + N);
    for v in values {
        buf.extend_from_slice(&v);
        if buf.len() >= CHUNK {
            enc.write_all(&buf)?;
            buf.clear();
        }
    }
    enc.write_all(&buf)?;
    enc.finish()?;
    Ok(())
}

/// Escapes a string for an XML attribute value.
fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            _ => out.push(ch),
        }
    }
    out
}

// ------------------------------------------------------------------------------------------------
// PVD collections
// ------------------------------------------------------------------------------------------------

/// One data set of a `.pvd` collection.
#[derive(Clone, Debug, PartialEq)]
pub struct PvdEntry {
    /// Time step value.
    pub time: f64,
    /// Part index (ParaView shows each part as a block).
    pub part: usize,
    /// Part name, e.g. `"fluid"`.
    pub name: String,
    /// File, relative to the `.pvd`'s directory.
    pub file: String,
}

impl PvdEntry {
    /// The entry's file resolved against the directory of the collection at `pvd_path`.
    pub fn resolve(&self, pvd_path: &Path) -> PathBuf {
        pvd_path.parent().unwrap_or(Path::new("")).join(&self.file)
    }
}

/// Writes a ParaView collection (`type="Collection"`) listing `entries`, atomically.
pub fn write_pvd(path: &Path, entries: &[PvdEntry]) -> Result<(), VtkError> {
    for e in entries {
        check_finite(&format!("timestep of '{}'", e.file), std::iter::once(e.time))?;
    }
    write_atomically(path, |w| write_pvd_body(w, entries))
}

/// The XML of a `.pvd` file.
fn write_pvd_body<W: Write>(w: &mut W, entries: &[PvdEntry]) -> io::Result<()> {
    writeln!(w, r#"<?xml version="1.0"?>"#)?;
    writeln!(w, r#"<VTKFile type="Collection" version="1.0" byte_order="LittleEndian">"#)?;
    writeln!(w, "  <Collection>")?;
    for e in entries {
        writeln!(
            w,
            r#"    <DataSet timestep="{}" part="{}" name="{}" file="{}"/>"#,
            format_time(e.time),
            e.part,
            xml_escape(&e.name),
            xml_escape(&e.file)
        )?;
    }
    writeln!(w, "  </Collection>")?;
    writeln!(w, "</VTKFile>")
}

/// Shortest round-trip decimal form of a time (plain for moderate magnitudes, else exponent).
fn format_time(t: f64) -> String {
    let a = t.abs();
    if a == 0.0 || (1e-4..1e15).contains(&a) {
        format!("{t}")
    } else {
        format!("{t:e}")
    }
}

/// A time series of one or more parts: each [`PvdSeries::add`] writes `stem_<part>_<index>.vtu`
/// in `dir` (index counted per part, 6 digits) and then rewrites `stem.pvd`, so the collection
/// always lists only completely written files.
///
/// A new series starts at index 0 and overwrites the files of an earlier series of the same stem.
#[derive(Clone, Debug)]
pub struct PvdSeries {
    dir: PathBuf,
    stem: String,
    /// Part names in order of first appearance (the part index) and their file counts.
    parts: Vec<(String, usize)>,
    entries: Vec<PvdEntry>,
}

impl PvdSeries {
    /// A series writing into `dir` (created on the first [`Self::add`]) under the name `stem`.
    pub fn new(dir: &Path, stem: &str) -> Self {
        PvdSeries { dir: dir.to_path_buf(), stem: stem.to_string(), parts: Vec::new(), entries: Vec::new() }
    }

    /// Continues the series `dir/stem.pvd` of an interrupted run: keeps its entries up to time
    /// `until` (inclusive) and rewrites the `.pvd` with them; later `.vtu` files are overwritten
    /// by the next [`Self::add`]s. A missing `.pvd` gives an empty series.
    pub fn resume(dir: &Path, stem: &str, until: f64) -> Result<Self, VtkError> {
        let mut series = Self::new(dir, stem);
        let path = series.pvd_path();
        if !path.exists() {
            return Ok(series);
        }
        for mut entry in read_pvd(&path)? {
            if entry.time > until {
                continue;
            }
            let part = series.part_index(&entry.name);
            series.parts[part].1 += 1;
            entry.part = part;
            series.entries.push(entry);
        }
        write_pvd(&path, &series.entries)?;
        Ok(series)
    }

    /// Path of the collection file, `dir/stem.pvd`.
    pub fn pvd_path(&self) -> PathBuf {
        self.dir.join(format!("{}.pvd", self.stem))
    }

    /// Entries written so far.
    pub fn entries(&self) -> &[PvdEntry] {
        &self.entries
    }

    /// Writes `grid` as part `part_name` at `time`, rewrites the `.pvd`, and returns the path of
    /// the `.vtu` written.
    pub fn add(&mut self, time: f64, part_name: &str, grid: &UnstructuredGrid) -> Result<PathBuf, VtkError> {
        check_file_name_part("stem", &self.stem)?;
        check_file_name_part("part name", part_name)?;
        check_finite("time", std::iter::once(time))?;
        fs::create_dir_all(&self.dir).map_err(io_err(&self.dir))?;
        let part = self.part_index(part_name);
        let file = format!("{}_{}_{:06}.vtu", self.stem, part_name, self.parts[part].1);
        let path = self.dir.join(&file);
        write_vtu(&path, grid)?;
        self.parts[part].1 += 1;
        self.entries.push(PvdEntry { time, part, name: part_name.to_string(), file });
        write_pvd(&self.pvd_path(), &self.entries)?;
        Ok(path)
    }

    /// Index of part `name`, registering it if new.
    fn part_index(&mut self, name: &str) -> usize {
        match self.parts.iter().position(|(n, _)| n == name) {
            Some(i) => i,
            None => {
                self.parts.push((name.to_string(), 0));
                self.parts.len() - 1
            }
        }
    }
}

/// A stem or part name must be a non-empty run of ASCII letters, digits, `_`, `-`, `.`.
fn check_file_name_part(what: &str, s: &str) -> Result<(), VtkError> {
    let ok = !s.is_empty() && s != "." && s != ".." && s.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
    if ok {
        Ok(())
    } else {
        Err(VtkError::Invalid(format!("{what} '{s}' is not a valid file-name part (use letters, digits, _ - .)")))
    }
}

// ------------------------------------------------------------------------------------------------
// Reading
// ------------------------------------------------------------------------------------------------

/// Reads a `.vtu` file: inline `binary` (UInt64 or UInt32 headers, uncompressed) or `ascii`
/// arrays of any VTK scalar type. Errors name the file. Non-finite values are read as they are.
pub fn read_vtu(path: &Path) -> Result<UnstructuredGrid, VtkError> {
    let text = fs::read_to_string(path).map_err(io_err(path))?;
    parse_vtu(&text).map_err(|message| VtkError::Read { path: path.to_path_buf(), message })
}

/// Reads a `.pvd` collection's entries (missing `timestep`/`part`/`name` default to 0, 0, "").
pub fn read_pvd(path: &Path) -> Result<Vec<PvdEntry>, VtkError> {
    let text = fs::read_to_string(path).map_err(io_err(path))?;
    parse_pvd(&text).map_err(|message| VtkError::Read { path: path.to_path_buf(), message })
}

/// Parses XML, with a hint when it is not well formed.
fn parse_xml(text: &str) -> Result<roxmltree::Document<'_>, String> {
    roxmltree::Document::parse(text).map_err(|e| format!("not well-formed XML (truncated file?): {e}"))
}

/// Checks the root `<VTKFile type="...">`.
fn check_root(doc: &roxmltree::Document, file_type: &str) -> Result<(), String> {
    let root = doc.root_element();
    if root.tag_name().name() != "VTKFile" {
        return Err(format!("root element is <{}>, expected <VTKFile>", root.tag_name().name()));
    }
    match root.attribute("type") {
        Some(t) if t == file_type => Ok(()),
        t => Err(format!("VTKFile type is {t:?}, expected \"{file_type}\"")),
    }
}

/// The unique child element of `node` named `tag`, if any.
fn child<'a, 'i>(node: roxmltree::Node<'a, 'i>, tag: &str) -> Option<roxmltree::Node<'a, 'i>> {
    node.children().find(|n| n.is_element() && n.tag_name().name() == tag)
}

/// Child elements of `node` named `tag`.
fn children<'a, 'i: 'a>(node: roxmltree::Node<'a, 'i>, tag: &'a str) -> impl Iterator<Item = roxmltree::Node<'a, 'i>> + 'a {
    node.children().filter(move |n| n.is_element() && n.tag_name().name() == tag)
}

/// A required attribute parsed as `T`.
fn attr<T: std::str::FromStr>(node: roxmltree::Node, name: &str) -> Result<T, String> {
    let tag = node.tag_name().name();
    let raw = node.attribute(name).ok_or_else(|| format!("<{tag}> has no {name} attribute"))?;
    raw.trim().parse().map_err(|_| format!("<{tag}> has an invalid {name}=\"{raw}\""))
}

/// An optional attribute parsed as `T`, `default` when absent.
fn attr_or<T: std::str::FromStr>(node: roxmltree::Node, name: &str, default: T) -> Result<T, String> {
    if node.attribute(name).is_some() {
        attr(node, name)
    } else {
        Ok(default)
    }
}

/// Parses the text of a `.pvd`.
fn parse_pvd(text: &str) -> Result<Vec<PvdEntry>, String> {
    let doc = parse_xml(text)?;
    check_root(&doc, "Collection")?;
    let coll = child(doc.root_element(), "Collection").ok_or("missing <Collection>")?;
    children(coll, "DataSet")
        .map(|ds| {
            Ok(PvdEntry {
                time: attr_or(ds, "timestep", 0.0)?,
                part: attr_or(ds, "part", 0)?,
                name: ds.attribute("name").unwrap_or("").to_string(),
                file: ds.attribute("file").ok_or("<DataSet> has no file attribute")?.to_string(),
            })
        })
        .collect()
}

/// File-level settings that govern array decoding.
#[derive(Clone, Copy)]
struct Encoding {
    /// Bytes of the binary length header (8 for UInt64, 4 for UInt32).
    header: usize,
}

/// Reads the encoding settings of the root element, refusing what is not supported.
fn encoding(root: roxmltree::Node) -> Result<Encoding, String> {
    if let Some(order) = root.attribute("byte_order") {
        if order != "LittleEndian" {
            return Err(format!("byte_order=\"{order}\" is not supported (only LittleEndian)"));
        }
    }
    if let Some(c) = root.attribute("compressor") {
        return Err(format!("compressed data (compressor=\"{c}\") is not supported"));
    }
    let header = match root.attribute("header_type").unwrap_or("UInt32") {
        "UInt64" => 8,
        "UInt32" => 4,
        h => return Err(format!("header_type=\"{h}\" is not supported")),
    };
    Ok(Encoding { header })
}

/// Parses the text of a `.vtu`.
fn parse_vtu(text: &str) -> Result<UnstructuredGrid, String> {
    let doc = parse_xml(text)?;
    check_root(&doc, "UnstructuredGrid")?;
    let root = doc.root_element();
    let enc = encoding(root)?;
    let ug = child(root, "UnstructuredGrid").ok_or("missing <UnstructuredGrid>")?;
    let mut pieces = children(ug, "Piece");
    let piece = pieces.next().ok_or("missing <Piece>")?;
    if pieces.next().is_some() {
        return Err("files with more than one <Piece> are not supported".into());
    }
    parse_piece(piece, enc)
}

/// Parses one `<Piece>`.
fn parse_piece(piece: roxmltree::Node, enc: Encoding) -> Result<UnstructuredGrid, String> {
    let np: usize = attr(piece, "NumberOfPoints")?;
    let nc: usize = attr(piece, "NumberOfCells")?;
    let mut grid = UnstructuredGrid::new(parse_points(piece, enc, np)?);
    parse_cells(piece, enc, nc, &mut grid)?;
    grid.point_data = parse_data_section(piece, enc, "PointData", np)?;
    grid.cell_data = parse_data_section(piece, enc, "CellData", nc)?;
    grid.check_structure().map_err(|e| e.to_string())?;
    Ok(grid)
}

/// The `<Points>` array (3 components, `np` tuples).
fn parse_points(piece: roxmltree::Node, enc: Encoding, np: usize) -> Result<Vec<[f64; 3]>, String> {
    let pts = child(piece, "Points").ok_or("missing <Points>")?;
    let da = child(pts, "DataArray").ok_or("<Points> has no <DataArray>")?;
    let comps: usize = attr_or(da, "NumberOfComponents", 1)?;
    if comps != 3 {
        return Err(format!("<Points> has NumberOfComponents=\"{comps}\", expected 3"));
    }
    let v = read_f64_array(da, enc, "Points", np * 3)?;
    Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// The `<Cells>` arrays (`connectivity`, `offsets`, `types`) into `grid`.
fn parse_cells(piece: roxmltree::Node, enc: Encoding, nc: usize, grid: &mut UnstructuredGrid) -> Result<(), String> {
    let cells = match child(piece, "Cells") {
        Some(c) => c,
        None if nc == 0 => return Ok(()),
        None => return Err("missing <Cells>".into()),
    };
    let named =
        |name: &str| children(cells, "DataArray").find(|d| d.attribute("Name") == Some(name)).ok_or_else(|| format!("<Cells> has no '{name}' array"));
    let offsets = read_index_array(named("offsets")?, enc, "offsets", Some(nc))?;
    let conn_len = offsets.last().copied().unwrap_or(0);
    grid.connectivity = read_index_array(named("connectivity")?, enc, "connectivity", Some(conn_len))?;
    grid.offsets = offsets;
    grid.cell_types = read_int_array(named("types")?, enc, "types", Some(nc))?
        .into_iter()
        .map(|id| u8::try_from(id).ok().and_then(VtkCellType::from_id).ok_or_else(|| format!("unknown VTK cell type {id}")))
        .collect::<Result<_, _>>()?;
    Ok(())
}

/// The arrays of a `<PointData>`/`<CellData>` section (`tuples` tuples each), if present.
fn parse_data_section(piece: roxmltree::Node, enc: Encoding, tag: &str, tuples: usize) -> Result<Vec<DataArray>, String> {
    let Some(section) = child(piece, tag) else { return Ok(Vec::new()) };
    children(section, "DataArray")
        .map(|da| {
            let name = da.attribute("Name").ok_or_else(|| format!("a <{tag}> array has no Name"))?.to_string();
            let components: usize = attr_or(da, "NumberOfComponents", 1)?;
            let values = read_f64_array(da, enc, &name, tuples * components)?;
            Ok(DataArray { name, components, values })
        })
        .collect()
}

/// VTK scalar types.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Scalar {
    /// The scalar type of a `type="..."` attribute.
    fn parse(s: &str) -> Option<Self> {
        use Scalar::*;
        Some(match s {
            "Int8" => I8,
            "UInt8" => U8,
            "Int16" => I16,
            "UInt16" => U16,
            "Int32" => I32,
            "UInt32" => U32,
            "Int64" => I64,
            "UInt64" => U64,
            "Float32" => F32,
            "Float64" => F64,
            _ => return None,
        })
    }

    /// Size in bytes.
    fn size(self) -> usize {
        use Scalar::*;
        match self {
            I8 | U8 => 1,
            I16 | U16 => 2,
            I32 | U32 | F32 => 4,
            I64 | U64 | F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes one little-endian value as f64 (`b.len() == self.size()`).
    fn decode_f64(self, b: &[u8]) -> f64 {
        use Scalar::*;
        match self {
            F32 => f32::from_le_bytes(b.try_into().unwrap()) as f64,
            F64 => f64::from_le_bytes(b.try_into().unwrap()),
            _ => self.decode_i128(b) as f64,
        }
    }

    /// Decodes one little-endian integer (`b.len() == self.size()`, integer type).
    fn decode_i128(self, b: &[u8]) -> i128 {
        use Scalar::*;
        match self {
            I8 => i8::from_le_bytes(b.try_into().unwrap()) as i128,
            U8 => b[0] as i128,
            I16 => i16::from_le_bytes(b.try_into().unwrap()) as i128,
            U16 => u16::from_le_bytes(b.try_into().unwrap()) as i128,
            I32 => i32::from_le_bytes(b.try_into().unwrap()) as i128,
            U32 => u32::from_le_bytes(b.try_into().unwrap()) as i128,
            I64 => i64::from_le_bytes(b.try_into().unwrap()) as i128,
            U64 => u64::from_le_bytes(b.try_into().unwrap()) as i128,
            F32 | F64 => unreachable!("float decoded as integer"),
        }
    }
}

/// The raw content of a `<DataArray>`: decoded binary bytes or ASCII text.
enum Raw<'a> {
    Binary(Vec<u8>),
    Ascii(&'a str),
}

/// The scalar type and raw content of array `name`.
fn raw_array<'a>(da: roxmltree::Node<'a, '_>, enc: Encoding, name: &str) -> Result<(Scalar, Raw<'a>), String> {
    let ty = da.attribute("type").ok_or_else(|| format!("array '{name}' has no type attribute"))?;
    let scalar = Scalar::parse(ty).ok_or_else(|| format!("array '{name}' has unknown type \"{ty}\""))?;
    let text = da.text().unwrap_or("");
    let raw = match da.attribute("format") {
        Some("binary") => Raw::Binary(decode_binary(text, enc, name, scalar)?),
        Some("ascii") => Raw::Ascii(text),
        Some(f) => return Err(format!("array '{name}' has format=\"{f}\"; only binary (inline) and ascii are supported")),
        None => return Err(format!("array '{name}' has no format attribute")),
    };
    Ok((scalar, raw))
}

/// Decodes an inline binary block to its data bytes, checking the length header.
fn decode_binary(text: &str, enc: Encoding, name: &str, scalar: Scalar) -> Result<Vec<u8>, String> {
    let clean: String = text.chars().filter(|c| !c.is_ascii_whitespace()).collect();
    let bytes = decode_base64(&clean, enc.header).map_err(|e| format!("array '{name}' has bad base64: {e}"))?;
    if bytes.len() < enc.header {
        return Err(format!("array '{name}' is shorter than its {}-byte length header", enc.header));
    }
    let (head, data) = bytes.split_at(enc.header);
    let mut h = [0u8; 8];
    h[..enc.header].copy_from_slice(head);
    let declared = u64::from_le_bytes(h);
    if declared != data.len() as u64 {
        return Err(format!("array '{name}': header declares {declared} bytes, the data has {}", data.len()));
    }
    if data.len() % scalar.size() != 0 {
        return Err(format!("array '{name}': {} bytes is not a whole number of {scalar:?} values", data.len()));
    }
    Ok(data.to_vec())
}

/// Base64 of header and data in one stream, or (as some writers do) encoded separately.
fn decode_base64(clean: &str, header: usize) -> Result<Vec<u8>, base64::DecodeError> {
    STANDARD.decode(clean).or_else(|err| {
        let hl = header.div_ceil(3) * 4;
        match (clean.get(..hl), clean.get(hl..)) {
            (Some(h), Some(d)) if !d.is_empty() => {
                let mut out = STANDARD.decode(h).map_err(|_| err.clone())?;
                out.extend(STANDARD.decode(d).map_err(|_| err.clone())?);
                Ok(out)
            }
            _ => Err(err),
        }
    })
}

/// Checks the value count of array `name`.
fn check_count(name: &str, got: usize, expected: usize) -> Result<(), String> {
    if got == expected {
        Ok(())
    } else {
        Err(format!("array '{name}' has {got} values, expected {expected}"))
    }
}

/// Reads an array as f64 values, `expected` of them.
fn read_f64_array(da: roxmltree::Node, enc: Encoding, name: &str, expected: usize) -> Result<Vec<f64>, String> {
    let values: Vec<f64> = match raw_array(da, enc, name)? {
        (s, Raw::Binary(b)) => b.chunks_exact(s.size()).map(|c| s.decode_f64(c)).collect(),
        (_, Raw::Ascii(t)) => {
            t.split_ascii_whitespace().map(|w| w.parse().map_err(|_| format!("array '{name}' has a bad number \"{w}\""))).collect::<Result<_, _>>()?
        }
    };
    check_count(name, values.len(), expected)?;
    Ok(values)
}

/// Reads an integer array (`expected` values, if given).
fn read_int_array(da: roxmltree::Node, enc: Encoding, name: &str, expected: Option<usize>) -> Result<Vec<i128>, String> {
    let values: Vec<i128> = match raw_array(da, enc, name)? {
        (s, _) if s.is_float() => return Err(format!("array '{name}' must have an integer type, not {s:?}")),
        (s, Raw::Binary(b)) => b.chunks_exact(s.size()).map(|c| s.decode_i128(c)).collect(),
        (_, Raw::Ascii(t)) => t
            .split_ascii_whitespace()
            .map(|w| w.parse().map_err(|_| format!("array '{name}' has a bad integer \"{w}\"")))
            .collect::<Result<_, _>>()?,
    };
    if let Some(n) = expected {
        check_count(name, values.len(), n)?;
    }
    Ok(values)
}

/// Reads a non-negative index array.
fn read_index_array(da: roxmltree::Node, enc: Encoding, name: &str, expected: Option<usize>) -> Result<Vec<usize>, String> {
    read_int_array(da, enc, name, expected)?
        .into_iter()
        .map(|v| usize::try_from(v).map_err(|_| format!("array '{name}' has the invalid index {v}")))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::ReferenceElement;

    /// A scratch directory removed on drop.
    struct TestDir(PathBuf);

    impl TestDir {
        fn new(tag: &str) -> Self {
            let p = std::env::temp_dir().join(format!("fdfsi-vtk-test-{}-{tag}", std::process::id()));
            let _ = fs::remove_dir_all(&p);
            fs::create_dir_all(&p).unwrap();
            TestDir(p)
        }
        fn path(&self, name: &str) -> PathBuf {
            self.0.join(name)
        }
        fn listing(&self) -> Vec<String> {
            let mut v: Vec<String> = fs::read_dir(&self.0).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
            v.sort();
            v
        }
    }

    impl Drop for TestDir {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    /// Two 6-node triangles on the unit square (9 nodes, VTK order: vertices then mid-edges).
    fn tri6_mesh() -> Mesh<2> {
        Mesh {
            points: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.0], [1.0, 0.5], [0.5, 0.5], [0.5, 1.0], [0.0, 0.5]],
            cell_type: ReferenceCell::Triangle,
            order: GeometryOrder::Quadratic,
            cell_nodes: vec![0, 1, 2, 4, 5, 6, 0, 2, 3, 6, 7, 8],
            cell_tags: vec![1, 1],
            region_names: vec![("fluid".into(), 1)],
            boundary: vec![],
            boundary_names: vec![],
        }
    }

    /// Two 27-node hexahedra side by side in x (nodes not shared; fine for I/O).
    fn hex27_mesh() -> Mesh<3> {
        let reference = ReferenceElement::<3>::q2_hexahedron();
        let mut points = Vec::new();
        for shift in [0.0, 1.0] {
            points.extend(reference.nodes().iter().map(|p| [p[0] + shift, 0.5 * p[1], 2.0 * p[2] - 0.25]));
        }
        Mesh {
            points,
            cell_type: ReferenceCell::Hexahedron,
            order: GeometryOrder::Quadratic,
            cell_nodes: (0..54).collect(),
            cell_tags: vec![2, 2],
            region_names: vec![("solid".into(), 2)],
            boundary: vec![],
            boundary_names: vec![],
        }
    }

    /// A grid with a 3-component point array and a scalar cell array of awkward values.
    fn with_data(mut grid: UnstructuredGrid) -> UnstructuredGrid {
        let np = grid.num_points();
        let nc = grid.num_cells();
        let u = (0..3 * np).map(|i| (i as f64 * 0.1).sin() / 3.0 + 1e-300 * i as f64).collect();
        grid.add_point_data("velocity", 3, u).unwrap();
        grid.add_cell_data("region", 1, (0..nc).map(|c| c as f64 + 0.1).collect()).unwrap();
        grid.add_point_data("p & <q>", 1, (0..np).map(|i| -(i as f64) / 7.0).collect()).unwrap();
        grid
    }

    #[test]
    fn tri6_round_trip_is_exact() {
        let dir = TestDir::new("tri6");
        let mesh = tri6_mesh();
        mesh.check().unwrap();
        let grid = with_data(UnstructuredGrid::from_mesh(&mesh));
        assert_eq!(grid.cell_types, vec![VtkCellType::QuadraticTriangle; 2]);
        assert_eq!(grid.points[4], [0.5, 0.0, 0.0]);
        assert_eq!(grid.cell(1), &[0, 2, 3, 6, 7, 8]);
        let path = dir.path("tri6.vtu");
        write_vtu(&path, &grid).unwrap();
        let back = read_vtu(&path).unwrap();
        assert_eq!(back, grid);
        assert_eq!(back.point_array("velocity").unwrap().components, 3);
    }

    #[test]
    fn hex27_round_trip_is_exact() {
        let dir = TestDir::new("hex27");
        let mesh = hex27_mesh();
        mesh.check().unwrap();
        let grid = with_data(UnstructuredGrid::from_mesh(&mesh));
        assert_eq!(grid.cell_types, vec![VtkCellType::TriquadraticHexahedron; 2]);
        assert_eq!(grid.offsets, vec![27, 54]);
        let path = dir.path("hex27.vtu");
        write_vtu(&path, &grid).unwrap();
        let back = read_vtu(&path).unwrap();
        assert_eq!(back, grid);
        let text = fs::read_to_string(&path).unwrap();
        assert!(text.contains(r#"header_type="UInt64""#) && text.contains(r#"format="binary""#));
        assert!(text.contains(r#"Name="p &amp; &lt;q&gt;""#));
    }

    #[test]
    fn binary_layout_matches_independent_encoding() {
        // Expected strings computed with Python: b64encode(struct.pack('<Q', nbytes) + data).
        let dir = TestDir::new("golden");
        let mut g = UnstructuredGrid::new(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        g.push_cell(VtkCellType::Triangle, &[0, 1, 2]).unwrap();
        write_vtu(&dir.path("g.vtu"), &g).unwrap();
        let text = fs::read_to_string(dir.path("g.vtu")).unwrap();
        assert!(text.contains(r#"Name="types" NumberOfComponents="1" format="binary">AQAAAAAAAAAF</DataArray>"#));
        assert!(text.contains(">GAAAAAAAAAAAAAAAAAAAAAEAAAAAAAAAAgAAAAAAAAA=</DataArray>"));
        assert!(text.contains(">SAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAADwPwAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAPA/AAAAAAAAAAA=<"));
    }

    #[test]
    fn from_mesh_maps_every_cell_type() {
        use GeometryOrder::*;
        use ReferenceCell::*;
        for cell in [Segment, Triangle, Quadrilateral, Tetrahedron, Hexahedron] {
            for order in [Linear, Quadratic] {
                let t = VtkCellType::from_cell(cell, order);
                assert_eq!(t.num_nodes(), crate::mesh::geometry_nodes(cell, order), "{cell:?} {order:?}");
                assert_eq!(VtkCellType::from_id(t.id()), Some(t));
            }
        }
        assert_eq!(VtkCellType::from_cell(Quadrilateral, Quadratic), VtkCellType::BiquadraticQuad);
        assert_eq!(VtkCellType::from_id(7), None);
    }

    #[test]
    fn mixed_cells_and_empty_grid_round_trip() {
        let dir = TestDir::new("mixed");
        let mut g = UnstructuredGrid::new(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.0, 0.0]]);
        g.push_cell(VtkCellType::Triangle, &[0, 1, 2]).unwrap();
        g.push_cell(VtkCellType::QuadraticEdge, &[0, 1, 3]).unwrap();
        g.push_cell(VtkCellType::Vertex, &[2]).unwrap();
        assert!(g.push_cell(VtkCellType::Line, &[0, 1, 2]).is_err());
        write_vtu(&dir.path("m.vtu"), &g).unwrap();
        assert_eq!(read_vtu(&dir.path("m.vtu")).unwrap(), g);
        let empty = UnstructuredGrid::default();
        write_vtu(&dir.path("e.vtu"), &empty).unwrap();
        assert_eq!(read_vtu(&dir.path("e.vtu")).unwrap(), empty);
    }

    #[test]
    fn add_data_checks_lengths_and_names() {
        let mut g = UnstructuredGrid::from_mesh(&tri6_mesh());
        let e = g.add_point_data("u", 2, vec![0.0; 17]).unwrap_err();
        assert!(matches!(e, VtkError::LengthMismatch { expected: 18, got: 17, .. }), "{e}");
        assert!(g.add_cell_data("c", 0, vec![]).is_err());
        g.add_cell_data("c", 1, vec![1.0, 2.0]).unwrap();
        assert!(g.add_cell_data("c", 1, vec![1.0, 2.0]).is_err());
        assert!(g.point_data.is_empty());
    }

    #[test]
    fn non_finite_values_are_refused_and_nothing_is_written() {
        let dir = TestDir::new("nan");
        let mut g = with_data(UnstructuredGrid::from_mesh(&tri6_mesh()));
        g.point_data[0].values[5] = f64::NAN;
        let path = dir.path("bad.vtu");
        let e = write_vtu(&path, &g).unwrap_err();
        assert!(matches!(&e, VtkError::NonFinite { array, index: 5, .. } if array == "velocity"), "{e}");
        assert!(e.to_string().contains("'velocity'"));
        g.point_data[0].values[5] = 0.0;
        g.points[3][1] = f64::INFINITY;
        let e = write_vtu(&path, &g).unwrap_err();
        assert!(matches!(&e, VtkError::NonFinite { array, index: 10, .. } if array == "Points"), "{e}");
        assert!(dir.listing().is_empty());
    }

    #[test]
    fn atomic_write_leaves_no_tmp_file_and_replaces() {
        let dir = TestDir::new("atomic");
        let path = dir.path("a.vtu");
        let grid = UnstructuredGrid::from_mesh(&tri6_mesh());
        write_vtu(&path, &grid).unwrap();
        let grid2 = with_data(grid);
        write_vtu(&path, &grid2).unwrap();
        assert_eq!(dir.listing(), vec!["a.vtu".to_string()]);
        assert_eq!(read_vtu(&path).unwrap(), grid2);
        // A failing write (destination is a directory) leaves neither a tmp file nor damage.
        fs::create_dir(dir.path("d.vtu")).unwrap();
        assert!(write_vtu(&dir.path("d.vtu"), &grid2).is_err());
        assert_eq!(dir.listing(), vec!["a.vtu".to_string(), "d.vtu".to_string()]);
    }

    #[test]
    fn pvd_series_three_steps_two_parts() {
        let dir = TestDir::new("series");
        let fluid = with_data(UnstructuredGrid::from_mesh(&tri6_mesh()));
        let solid = with_data(UnstructuredGrid::from_mesh(&hex27_mesh()));
        let mut series = PvdSeries::new(&dir.path("out"), "run");
        let times = [0.0, 0.1, 2.5e-20];
        for &t in &times {
            series.add(t, "fluid", &fluid).unwrap();
            let p = series.add(t, "solid", &solid).unwrap();
            assert!(p.exists());
        }
        let pvd = series.pvd_path();
        assert_eq!(pvd, dir.path("out").join("run.pvd"));
        let entries = read_pvd(&pvd).unwrap();
        assert_eq!(entries, series.entries());
        assert_eq!(entries.len(), 6);
        for (k, e) in entries.iter().enumerate() {
            let (step, part) = (k / 2, k % 2);
            let name = ["fluid", "solid"][part];
            assert_eq!(e.time, times[step]);
            assert_eq!(e.part, part);
            assert_eq!(e.name, name);
            assert_eq!(e.file, format!("run_{name}_{step:06}.vtu"));
            let g = read_vtu(&e.resolve(&pvd)).unwrap();
            assert_eq!(&g, if part == 0 { &fluid } else { &solid });
        }
        let files: Vec<_> = fs::read_dir(dir.path("out")).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(files.len(), 7);
        assert!(!files.iter().any(|f| f.to_string_lossy().ends_with(".tmp")));
        assert!(series.add(f64::NAN, "fluid", &fluid).is_err());
        assert!(series.add(1.0, "../x", &fluid).is_err());
        assert_eq!(read_pvd(&pvd).unwrap().len(), 6);
    }

    #[test]
    fn pvd_round_trip_with_escaping() {
        let dir = TestDir::new("pvd");
        let entries = vec![
            PvdEntry { time: 1e-300, part: 0, name: "a\"<&>'".into(), file: "x y.vtu".into() },
            PvdEntry { time: -123456.789, part: 3, name: "b".into(), file: "sub/b.vtu".into() },
            PvdEntry { time: 1e20, part: 1, name: "".into(), file: "c.vtu".into() },
        ];
        let path = dir.path("c.pvd");
        write_pvd(&path, &entries).unwrap();
        assert_eq!(read_pvd(&path).unwrap(), entries);
        assert_eq!(dir.listing(), vec!["c.pvd".to_string()]);
        let mut bad = entries.clone();
        bad[1].time = f64::INFINITY;
        assert!(matches!(write_pvd(&path, &bad), Err(VtkError::NonFinite { .. })));
    }

    #[test]
    fn reads_ascii_arrays() {
        let dir = TestDir::new("ascii");
        let text = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
  <UnstructuredGrid>
    <Piece NumberOfPoints="3" NumberOfCells="1">
      <PointData>
        <DataArray type="Float32" Name="T" format="ascii">1 2.5 -3e2</DataArray>
      </PointData>
      <Points>
        <DataArray type="Float64" NumberOfComponents="3" format="ascii">
          0 0 0  1 0 0
          0 1 0
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">3</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">5</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>"#;
        let path = dir.path("a.vtu");
        fs::write(&path, text).unwrap();
        let g = read_vtu(&path).unwrap();
        assert_eq!(g.points, vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        assert_eq!(g.cell_types, vec![VtkCellType::Triangle]);
        assert_eq!(g.point_array("T").unwrap().values, vec![1.0, 2.5, -300.0]);
    }

    /// Writes `text` to a file and returns the reader's error message.
    fn read_error(dir: &TestDir, name: &str, text: &str) -> String {
        let path = dir.path(name);
        fs::write(&path, text).unwrap();
        let e = read_vtu(&path).unwrap_err();
        assert!(matches!(e, VtkError::Read { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains(name), "error does not name the file: {msg}");
        msg
    }

    #[test]
    fn reader_errors_are_errors_not_panics() {
        let dir = TestDir::new("errors");
        let grid = with_data(UnstructuredGrid::from_mesh(&hex27_mesh()));
        let good = dir.path("good.vtu");
        write_vtu(&good, &grid).unwrap();
        let text = fs::read_to_string(&good).unwrap();
        // Truncated at many places.
        for cut in (0..text.len()).step_by(97) {
            let _ = read_error(&dir, "trunc.vtu", &text[..cut]);
        }
        let msg = read_error(&dir, "trunc.vtu", &text[..text.len() / 2]);
        assert!(msg.contains("truncated"), "{msg}");
        // Missing Points.
        let start = text.find("<Points>").unwrap();
        let end = text.find("</Points>").unwrap() + "</Points>".len();
        let no_points = format!("{}{}", &text[..start], &text[end..]);
        assert!(read_error(&dir, "nopts.vtu", &no_points).contains("missing <Points>"));
        // Unknown cell type (UInt8 29 -> 99 via ascii replacement of the types array).
        let ts = text.find(r#"Name="types""#).unwrap();
        let ts = text[..ts].rfind("<DataArray").unwrap();
        let te = ts + text[ts..].find("</DataArray>").unwrap() + "</DataArray>".len();
        let unknown = format!(r#"{}<DataArray type="UInt8" Name="types" format="ascii">29 99</DataArray>{}"#, &text[..ts], &text[te..]);
        assert!(read_error(&dir, "type.vtu", &unknown).contains("unknown VTK cell type 99"));
        // Bad base64.
        let bad64 = text.replacen(r#"format="binary">"#, r#"format="binary">!!"#, 1);
        assert!(read_error(&dir, "b64.vtu", &bad64).contains("bad base64"));
        // Length mismatch.
        let np = grid.num_points();
        let wrong = text.replace(&format!(r#"NumberOfPoints="{np}""#), &format!(r#"NumberOfPoints="{}""#, np + 1));
        assert!(read_error(&dir, "len.vtu", &wrong).contains("expected"));
        // Wrong file type, compressed, not XML at all.
        assert!(read_error(&dir, "pvd.vtu", &text.replace("UnstructuredGrid", "PolyData")).contains("PolyData"));
        let z = text.replace("header_type=", r#"compressor="vtkZLibDataCompressor" header_type="#);
        assert!(read_error(&dir, "z.vtu", &z).contains("compressed"));
        let _ = read_error(&dir, "junk.vtu", "\u{0}\u{1}garbage");
        // Missing file and bad pvd.
        assert!(matches!(read_vtu(&dir.path("none.vtu")), Err(VtkError::Io { .. })));
        fs::write(dir.path("x.pvd"), "<VTKFile type=\"Collection\"><Collection><DataSet timestep=\"a\" file=\"f\"/>").unwrap();
        assert!(read_pvd(&dir.path("x.pvd")).unwrap_err().to_string().contains("x.pvd"));
    }
}
