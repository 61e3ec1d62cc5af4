//! Gmsh MSH 4.1 import (ASCII or binary, parsed by the `mshio` crate).
//!
//! [`read_msh`] / [`parse_msh`] turn a Gmsh mesh into a [`Mesh<2>`] or [`Mesh<3>`]:
//!
//! - **Dimension.** The mesh dimension `D` is the highest dimension of any element in the file
//!   (points ignored). Elements of dimension `D` are the cells; all must be of one type:
//!   3/6-node triangles (Gmsh types 2/9), 4/9-node quadrangles (3/10), 4/10-node tetrahedra
//!   (4/11), 8/27-node hexahedra (5/12). A 2D mesh must lie in the plane `z = 0` (up to `1e-12`
//!   relative to its size); `z` is dropped.
//! - **Nodes.** Gmsh node tags may be sparse; only nodes used by cells are kept, numbered
//!   `0, 1, ...` in order of first use by the cells. Two distinct kept nodes closer than `1e-12`
//!   times the bounding-box diagonal (in each coordinate) are an error (duplicate nodes), so is
//!   a kept node with a NaN or infinite coordinate, and a node tag given twice in a block.
//! - **Node order.** Cells are converted from Gmsh's node order to VTK's (the order of
//!   [`crate::element`]) by matching the reference coordinates of the nodes: the Gmsh tables
//!   below are copied from the Gmsh manual ("Node ordering") and Gmsh's `MTetrahedron` /
//!   `MHexahedron` edge and face lists; for every VTK node the Gmsh node at the same reference
//!   position is taken. (Triangle6 and quadrangle9 orders coincide with VTK; tetrahedron10 swaps
//!   nodes 8 and 9; the hexahedron27 orders differ in edge and face order.)
//! - **Orientation.** A 2D cell with negative signed area (a surface meshed with its normal along
//!   `-z`) is reoriented by the reflection `(xi, eta) -> (eta, xi)` of its reference cell (for a
//!   triangle: vertices 1 and 2 swap, mid-edge nodes of edges (0,1) and (2,0) swap). A 3D cell
//!   with negative volume is an error ([`GmshError::InvertedCell`]): Gmsh always writes positive
//!   volume cells, so a negative one means a corrupt file or a wrong node order, which silent
//!   reorientation would hide. A cell whose vertex measure is below `1e-12 h^D` (`h` the extent
//!   of the cell) is degenerate. Curved (quadratic) and tensor-product cells must moreover have
//!   `det J > 0` at all their geometry nodes.
//! - **Regions.** A cell's region tag is the first physical tag of its geometric entity (the
//!   `$Entities` section). If any entity of dimension `D` has a physical tag, every cell must
//!   have one ([`GmshError::MissingPhysicalGroup`]: region tags select materials, so an untagged
//!   cell is an error rather than a silent tag 0); if none has, all cells get region tag 0 and
//!   there are no region names. Region names come from `$PhysicalNames` of dimension `D`; a
//!   physical tag used by cells without a name is named by its number (e.g. `"7"`).
//! - **Boundaries.** Every element of dimension `D - 1` (2-/3-node lines in 2D; 3-/6-node
//!   triangles and 4-/9-node quadrangles in 3D) whose entity has a physical tag becomes a
//!   [`BoundaryFacet`] with that tag: it is matched to `(cell, local facet)` by its sorted vertex
//!   set. An element of dimension `D - 1` that matches no cell facet, tagged or not, is an error
//!   (a file mixing 2D and 3D cells fails here: its triangles are no faces of its tetrahedra). A
//!   facet shared by two cells (an interface) is tagged once, on the first cell that has it. A
//!   facet tagged twice with different tags is an error. Elements of dimension `D - 1` without a
//!   physical tag give no boundary facet; elements of lower dimension are ignored. Boundary
//!   names come from `$PhysicalNames` of dimension `D - 1` (unnamed tags that are used are named
//!   by their number).
//!
//! Limitations (of `mshio` 0.4): only format 4.1 is read; parametric node blocks are refused;
//! when all node tags of the file are contiguous, `mshio` drops them and node `i` of the file is
//! taken to have tag `min_tag + i` (the order Gmsh writes). `$PhysicalNames` is not parsed by
//! `mshio` and is read here from the text (also in binary files, where Gmsh writes it as text).
//! Errors name the file and, where it applies, the Gmsh element or node tag, or the line (byte
//! offset in binary files) where parsing failed; a file without `$Nodes` or `$Elements`, or with
//! a section that is not closed, says so.

use crate::element::ReferenceCell;
use crate::mesh::{geometry_element, geometry_nodes, BoundaryFacet, GeometryOrder, Mesh};
use crate::values::det_inv;
use mshio::error::MshParserErrorKind;
use mshio::{ElementType, MshFile};
use std::collections::HashMap;
use std::path::Path;
use thiserror::Error;

/// A mesh of either dimension, as read from a file.
#[derive(Clone, Debug)]
pub enum AnyMesh {
    D2(Mesh<2>),
    D3(Mesh<3>),
}

impl AnyMesh {
    /// Spatial dimension (2 or 3).
    pub fn dim(&self) -> usize {
        match self {
            AnyMesh::D2(_) => 2,
            AnyMesh::D3(_) => 3,
        }
    }
    /// The 2D mesh, if it is one.
    pub fn into_2d(self) -> Option<Mesh<2>> {
        match self {
            AnyMesh::D2(m) => Some(m),
            AnyMesh::D3(_) => None,
        }
    }
    /// The 3D mesh, if it is one.
    pub fn into_3d(self) -> Option<Mesh<3>> {
        match self {
            AnyMesh::D3(m) => Some(m),
            AnyMesh::D2(_) => None,
        }
    }
    /// The mesh as a `Mesh<D>`, for code generic over the dimension `D`; `None` when it has the
    /// other dimension.
    pub fn into_dim<const D: usize>(self) -> Option<Mesh<D>> {
        match self {
            AnyMesh::D2(m) if D == 2 => Some(m.in_dim()),
            AnyMesh::D3(m) if D == 3 => Some(m.in_dim()),
            _ => None,
        }
    }
}

impl<const E: usize> Mesh<E> {
    /// The same mesh with its points as `D`-vectors (`D = E`).
    fn in_dim<const D: usize>(self) -> Mesh<D> {
        let points = self.points.iter().map(|p| std::array::from_fn(|d| p[d])).collect();
        Mesh {
            points,
            cell_type: self.cell_type,
            order: self.order,
            cell_nodes: self.cell_nodes,
            cell_tags: self.cell_tags,
            region_names: self.region_names,
            boundary: self.boundary,
            boundary_names: self.boundary_names,
        }
    }
}

/// Errors of the Gmsh import. Every message starts with the file name.
#[derive(Debug, Error)]
pub enum GmshError {
    #[error("{file}: cannot read the file: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: not a readable Gmsh MSH 4.1 file: {message}")]
    Parse { file: String, message: String },
    #[error("{file}: MSH format version {version} is not supported (only 4.1, ASCII or binary)")]
    UnsupportedVersion { file: String, version: String },
    #[error("{file}: element {} has Gmsh element type {}, which is not supported here ({detail})", opt(.element_tag), opt(.type_number))]
    UnsupportedElement { file: String, element_tag: Option<u64>, type_number: Option<i64>, detail: String },
    #[error("{file}: element {element_tag} refers to node {node_tag}, which is not in $Nodes")]
    MissingNode { file: String, element_tag: u64, node_tag: u64 },
    #[error("{file}: element {element_tag} is a {found}, but the first cell is a {first} (one cell type per mesh)")]
    MixedCellTypes { file: String, element_tag: u64, first: String, found: String },
    #[error("{file}: nodes {node_a} and {node_b} coincide at {coords:?} (duplicate nodes; only the bodies of a solid mesh, in separate physical groups, may touch)")]
    DuplicateNodes { file: String, node_a: u64, node_b: u64, coords: [f64; 3] },
    #[error("{file}: element {element_tag} is inverted (signed measure or det J {measure:.3e})")]
    InvertedCell { file: String, element_tag: u64, measure: f64 },
    #[error("{file}: element {element_tag} is degenerate: its vertices span no area or volume (signed measure {measure:.3e})")]
    DegenerateCell { file: String, element_tag: u64, measure: f64 },
    #[error("{file}: element {element_tag} (entity {entity_tag}) belongs to no physical group, but other cells do")]
    MissingPhysicalGroup { file: String, element_tag: u64, entity_tag: i32 },
    #[error(
        "{file}: element {element_tag} ({kind}) is not a facet of any {dim}D cell: the cells are the elements \
         of the highest dimension ({dim}D), every {}D element must be a side of one (a file mixing 2D and 3D \
         cells is refused)",
        .dim - 1
    )]
    BoundaryNotOnFacet { file: String, element_tag: u64, kind: String, dim: usize },
    #[error("{file}: the file has no {section} section")]
    MissingSection { file: String, section: &'static str },
    #[error("{file}: node {node_tag} has a non-finite coordinate {coords:?}")]
    NonFiniteNode { file: String, node_tag: u64, coords: [f64; 3] },
    #[error("{file}: node {node_tag} has z = {z:e}: a 2D mesh must lie in the plane z = 0")]
    NotPlanar { file: String, node_tag: u64, z: f64 },
    #[error("{file}: no 2D or 3D elements (note: when physical groups are defined, Gmsh saves only elements in physical groups)")]
    NoCells { file: String },
    #[error("{file}: {message}")]
    Inconsistent { file: String, message: String },
}

fn opt<T: std::fmt::Display>(x: &Option<T>) -> String {
    x.as_ref().map_or_else(|| "(unknown)".to_string(), |v| v.to_string())
}

/// Reads a Gmsh MSH 4.1 file (see the module documentation).
pub fn read_msh(path: &Path) -> Result<AnyMesh, GmshError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| GmshError::Io { file: file.clone(), source })?;
    parse_msh(&bytes, &file)
}

/// Parses the bytes of a Gmsh MSH 4.1 file; `source_name` names it in error messages.
pub fn parse_msh(bytes: &[u8], source_name: &str) -> Result<AnyMesh, GmshError> {
    let file = source_name.to_string();
    let binary = check_header(bytes, &file)?;
    let msh = run_mshio(bytes, &file, binary)?;
    if msh.data.elements.is_none() {
        return Err(GmshError::MissingSection { file, section: "$Elements" });
    }
    if msh.data.nodes.is_none() {
        return Err(GmshError::MissingSection { file, section: "$Nodes" });
    }
    let names = physical_names(bytes, &file)?;
    let nodes = node_table(&msh, &file)?;
    let groups = entity_groups(&msh);
    let elements = collect_elements(&msh);
    let dim = elements.iter().map(|e| type_dim(e.ty)).max().unwrap_or(0);
    let input = Input { file, nodes, groups, names, elements };
    match dim {
        2 => Ok(AnyMesh::D2(build::<2>(&input)?)),
        3 => Ok(AnyMesh::D3(build::<3>(&input)?)),
        _ => Err(GmshError::NoCells { file: input.file }),
    }
}

/// Everything read from the file, in the form the mesh builder needs.
struct Input {
    file: String,
    /// Node tag -> coordinates.
    nodes: HashMap<u64, [f64; 3]>,
    /// (entity dimension, entity tag) -> physical tags.
    groups: HashMap<(usize, i32), Vec<i32>>,
    /// (dimension, physical tag) -> name.
    names: HashMap<(usize, i32), String>,
    elements: Vec<RawElement>,
}

/// One element of the `$Elements` section.
struct RawElement {
    tag: u64,
    ty: ElementType,
    entity_dim: usize,
    entity_tag: i32,
    nodes: Vec<u64>,
}

// ---------------------------------------------------------------------------------------------
// Reading the file
// ---------------------------------------------------------------------------------------------

/// Checks the `$MeshFormat` header before `mshio` sees the file (`mshio` panics on some bad
/// headers): version 4.1, file type 0 (ASCII) or 1 (binary), and a `size_t` size `mshio` can
/// read. Returns whether the file is binary.
fn check_header(bytes: &[u8], file: &str) -> Result<bool, GmshError> {
    let parse_err = |message: &str| GmshError::Parse { file: file.to_string(), message: message.to_string() };
    let start = bytes.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(bytes.len());
    let rest = &bytes[start..];
    const TAG: &[u8] = b"$MeshFormat";
    if !rest.starts_with(TAG) {
        return Err(parse_err("the file does not start with $MeshFormat (not a Gmsh MSH file)"));
    }
    let line: Vec<&[u8]> = rest[TAG.len()..]
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .map(|p| {
            let body = &rest[TAG.len() + p..];
            let end = body.iter().position(|&b| b == b'\n').unwrap_or(body.len());
            body[..end].split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty()).collect()
        })
        .unwrap_or_default();
    let token = |i: usize| line.get(i).map(|t| String::from_utf8_lossy(t).into_owned());
    let version = token(0).ok_or_else(|| parse_err("$MeshFormat has no version line"))?;
    let number = version.parse::<f64>().map_err(|_| parse_err(&format!("invalid format version '{version}' in $MeshFormat")))?;
    if number != 4.1 {
        return Err(GmshError::UnsupportedVersion { file: file.to_string(), version });
    }
    let binary = match token(1).as_deref() {
        Some("0") => false,
        Some("1") => true,
        other => return Err(parse_err(&format!("invalid file type '{}' in $MeshFormat (0 = ASCII, 1 = binary)", other.unwrap_or("")))),
    };
    match token(2).as_deref().map(str::parse::<usize>) {
        Some(Ok(1 | 2 | 4 | 8 | 16)) => Ok(binary),
        _ => Err(parse_err(&format!("invalid data size '{}' in $MeshFormat", token(2).unwrap_or_default()))),
    }
}

/// Runs `mshio`, turning its errors (and, defensively, its panics) into [`GmshError`]s.
fn run_mshio(bytes: &[u8], file: &str, binary: bool) -> Result<MshFile<u64, i32, f64>, GmshError> {
    let result = std::panic::catch_unwind(|| mshio::parse_msh_bytes(bytes).map_err(|e| mshio_error(bytes, &e, file, binary)));
    match result {
        Ok(r) => r,
        Err(_) => Err(GmshError::Parse { file: file.to_string(), message: "the MSH parser failed".into() }),
    }
}

/// Converts an `mshio` error: an unknown element type becomes [`GmshError::UnsupportedElement`];
/// anything else a [`GmshError::Parse`] with the error, its context and its line.
fn mshio_error(bytes: &[u8], err: &mshio::MshParserError<&[u8]>, file: &str, binary: bool) -> GmshError {
    let trace = err.filtered_backtrace();
    let offset = |slice: &[u8]| bytes.len().saturating_sub(slice.len());
    if let Some((at, _)) = trace.iter().find(|(_, k)| *k == MshParserErrorKind::UnknownElement) {
        // In ASCII files the failing position is "type count first-element-tag ...".
        let tokens: Vec<String> = if binary {
            Vec::new()
        } else {
            let window = &at[..at.len().min(256)];
            String::from_utf8_lossy(window).split_ascii_whitespace().take(3).map(String::from).collect()
        };
        let from_context = trace.iter().find_map(|(_, k)| k.context()?.strip_prefix("value ")?.trim().parse().ok());
        let type_number = tokens.first().and_then(|t| t.parse().ok()).or(from_context);
        let element_tag = tokens.get(2).and_then(|t| t.parse().ok());
        return GmshError::UnsupportedElement { file: file.to_string(), element_tag, type_number, detail: "unknown element type number".into() };
    }
    let message = match trace.first() {
        None => match section_problem(bytes).or_else(|| if binary { None } else { bad_number(bytes) }) {
            Some(problem) => problem,
            None if !contains(bytes, b"$EndElements") => "the file ends before $EndElements (truncated?)".to_string(),
            None => "malformed file (the parser gave no details)".to_string(),
        },
        Some((at, kind)) => {
            let off = offset(at);
            let place = if binary { format!("byte {off}") } else { format!("line {}", bytes[..off].iter().filter(|&&b| b == b'\n').count() + 1) };
            // Contexts from the outermost in; the innermost entry is the error itself.
            let chain: Vec<String> = trace.iter().rev().filter_map(|(_, k)| k.context().map(String::from)).collect();
            let what = if kind.context().is_some() { String::new() } else { format!(": {kind}") };
            format!("parse error in {} ({place}){what}", chain.join(" > "))
        }
    };
    GmshError::Parse { file: file.to_string(), message }
}

/// The first problem in the nesting of the `$Section` ... `$EndSection` lines, if any (a
/// diagnosis for when `mshio` gives no details).
fn section_problem(bytes: &[u8]) -> Option<String> {
    let mut open: Option<(String, usize)> = None;
    for (i, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let line = line.trim();
        let Some(name) = line.strip_prefix('$') else {
            continue;
        };
        if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric()) {
            continue;
        }
        match (name.strip_prefix("End"), &open) {
            (Some(end), Some((section, _))) if end == section => open = None,
            (Some(_), _) => {
                let inside = open.as_ref().map(|(s, l)| format!(" (inside ${s} of line {l})")).unwrap_or_default();
                return Some(format!("${name} at line {} closes no section{inside}", i + 1));
            }
            (None, Some((section, l))) => {
                return Some(format!("${section} (line {l}) has no $End{section}: ${name} starts at line {}", i + 1));
            }
            (None, None) => open = Some((name.to_string(), i + 1)),
        }
    }
    open.map(|(section, l)| format!("${section} (line {l}) has no $End{section} (truncated?)"))
}

/// The first token of the `$Entities`, `$Nodes` or `$Elements` section of an ASCII file that is
/// not a number (a diagnosis for when `mshio` gives no details).
fn bad_number(bytes: &[u8]) -> Option<String> {
    let mut numeric = false;
    for (i, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let line = line.trim();
        if let Some(name) = line.strip_prefix('$') {
            numeric = matches!(name, "Entities" | "Nodes" | "Elements");
            continue;
        }
        if numeric {
            if let Some(t) = line.split_ascii_whitespace().find(|t| t.parse::<f64>().is_err()) {
                return Some(format!("line {}: `{t}` is not a number", i + 1));
            }
        }
    }
    None
}

/// The `$PhysicalNames` section: `(dimension, physical tag) -> name`. `mshio` skips this section,
/// so it is read here from the text (Gmsh writes it as text in binary files too).
fn physical_names(bytes: &[u8], file: &str) -> Result<HashMap<(usize, i32), String>, GmshError> {
    let mut names = HashMap::new();
    let Some(start) = find(bytes, b"\n$PhysicalNames") else {
        return Ok(names);
    };
    let body_start = start + b"\n$PhysicalNames".len();
    let err = |message: String| GmshError::Parse { file: file.to_string(), message };
    let len = find(&bytes[body_start..], b"$EndPhysicalNames").ok_or_else(|| err("$PhysicalNames has no $EndPhysicalNames".into()))?;
    let text = String::from_utf8_lossy(&bytes[body_start..body_start + len]);
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let count: usize =
        lines.next().and_then(|l| l.parse().ok()).ok_or_else(|| err("$PhysicalNames does not start with the number of names".into()))?;
    let mut read = 0;
    for line in lines {
        let bad = || err(format!("invalid line in $PhysicalNames: '{line}'"));
        // `dim tag "name"`; the name is everything between the first and the last quote.
        let (numbers, quoted) = line.split_once('"').ok_or_else(bad)?;
        let name = quoted.rsplit_once('"').map_or(quoted, |(n, _)| n).to_string();
        let mut parts = numbers.split_whitespace();
        let dim: usize = parts.next().and_then(|t| t.parse().ok()).ok_or_else(bad)?;
        let tag: i32 = parts.next().and_then(|t| t.parse().ok()).ok_or_else(bad)?;
        if parts.next().is_some() {
            return Err(bad());
        }
        names.insert((dim, tag), name);
        read += 1;
    }
    if read != count {
        return Err(err(format!("$PhysicalNames announces {count} names but has {read}")));
    }
    Ok(names)
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    find(haystack, needle).is_some()
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// Node tag -> coordinates. `mshio` keeps the tags only when they are sparse; otherwise the
/// nodes are numbered from the minimum tag on, in file order.
fn node_table(msh: &MshFile<u64, i32, f64>, file: &str) -> Result<HashMap<u64, [f64; 3]>, GmshError> {
    let mut table = HashMap::new();
    let Some(nodes) = &msh.data.nodes else {
        return Ok(table);
    };
    let mut next = nodes.min_node_tag;
    for block in &nodes.node_blocks {
        let coords = |i: usize| block.nodes.get(i).map(|n| [n.x, n.y, n.z]);
        let entries: Vec<(u64, usize)> = match &block.node_tags {
            Some(map) => {
                if map.len() != block.nodes.len() {
                    return Err(GmshError::Inconsistent {
                        file: file.to_string(),
                        message: format!(
                            "a node block of $Nodes has {} nodes but {} distinct node tags (a node tag is given twice)",
                            block.nodes.len(),
                            map.len()
                        ),
                    });
                }
                let mut e: Vec<(u64, usize)> = map.iter().map(|(&t, &i)| (t, i)).collect();
                e.sort_unstable();
                e
            }
            None => (0..block.nodes.len()).map(|i| (next + i as u64, i)).collect(),
        };
        for (tag, i) in entries {
            let x = coords(i).ok_or_else(|| GmshError::Inconsistent { file: file.to_string(), message: format!("node {tag} has no coordinates") })?;
            if table.insert(tag, x).is_some() {
                return Err(GmshError::Inconsistent { file: file.to_string(), message: format!("node tag {tag} is defined twice") });
            }
        }
        next += block.nodes.len() as u64;
    }
    Ok(table)
}

/// `(entity dimension, entity tag) -> physical tags` from the `$Entities` section.
fn entity_groups(msh: &MshFile<u64, i32, f64>) -> HashMap<(usize, i32), Vec<i32>> {
    let mut groups = HashMap::new();
    if let Some(e) = &msh.data.entities {
        groups.extend(e.points.iter().map(|p| ((0, p.tag), p.physical_tags.clone())));
        groups.extend(e.curves.iter().map(|c| ((1, c.tag), c.physical_tags.clone())));
        groups.extend(e.surfaces.iter().map(|s| ((2, s.tag), s.physical_tags.clone())));
        groups.extend(e.volumes.iter().map(|v| ((3, v.tag), v.physical_tags.clone())));
    }
    groups
}

fn collect_elements(msh: &MshFile<u64, i32, f64>) -> Vec<RawElement> {
    let Some(elements) = &msh.data.elements else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for block in &elements.element_blocks {
        for e in &block.elements {
            out.push(RawElement {
                tag: e.element_tag,
                ty: block.element_type,
                entity_dim: block.entity_dim.max(0) as usize,
                entity_tag: block.entity_tag,
                nodes: e.nodes.clone(),
            });
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Element types and node orders
// ---------------------------------------------------------------------------------------------

/// Topological dimension of a Gmsh element type (from its family: point, line, triangle, ...).
fn type_dim(ty: ElementType) -> usize {
    let name = format!("{ty:?}");
    if name.starts_with("Pnt") {
        0
    } else if name.starts_with("Lin") {
        1
    } else if name.starts_with("Tri") || name.starts_with("Qua") || name.starts_with("Polyg") {
        2
    } else {
        3
    }
}

/// The cell type and geometric order of a supported cell type.
fn cell_kind(ty: ElementType) -> Option<(ReferenceCell, GeometryOrder)> {
    use ElementType::*;
    use GeometryOrder::*;
    use ReferenceCell::*;
    Some(match ty {
        Tri3 => (Triangle, Linear),
        Tri6 => (Triangle, Quadratic),
        Qua4 => (Quadrilateral, Linear),
        Qua9 => (Quadrilateral, Quadratic),
        Tet4 => (Tetrahedron, Linear),
        Tet10 => (Tetrahedron, Quadratic),
        Hex8 => (Hexahedron, Linear),
        Hex27 => (Hexahedron, Quadratic),
        _ => return None,
    })
}

/// Number of vertices of a supported boundary element type of a `dim`-dimensional mesh.
fn facet_vertices(ty: ElementType, dim: usize) -> Option<usize> {
    use ElementType::*;
    match (dim, ty) {
        (2, Lin2 | Lin3) => Some(2),
        (3, Tri3 | Tri6) => Some(3),
        (3, Qua4 | Qua9) => Some(4),
        _ => None,
    }
}

fn type_name(ty: ElementType) -> String {
    format!("{ty:?} (Gmsh type {})", ty as i32)
}

const SUPPORTED: &str = "supported cells: Tri3, Tri6, Qua4, Qua9, Tet4, Tet10, Hex8, Hex27; \
                         boundary elements: Lin2, Lin3 (2D), Tri3, Tri6, Qua4, Qua9 (3D)";

/// Gmsh reference coordinates of the 6-node triangle (manual, "Node ordering"); the 3-node
/// triangle is its first 3 rows.
const GMSH_TRI6: [[f64; 3]; 6] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.5, 0.0]];
/// Gmsh reference coordinates of the 9-node quadrangle on `[-1, 1]^2`: vertices, edges
/// (0,1), (1,2), (2,3), (3,0), centre.
const GMSH_QUA9: [[f64; 3]; 9] = [
    [-1.0, -1.0, 0.0],
    [1.0, -1.0, 0.0],
    [1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 0.0, 0.0],
];
/// Gmsh reference coordinates of the 10-node tetrahedron: vertices, then the edges of Gmsh's
/// `MTetrahedron`: (0,1), (1,2), (2,0), (3,0), (3,2), (3,1).
const GMSH_TET10: [[f64; 3]; 10] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.5, 0.0, 0.0],
    [0.5, 0.5, 0.0],
    [0.0, 0.5, 0.0],
    [0.0, 0.0, 0.5],
    [0.0, 0.5, 0.5],
    [0.5, 0.0, 0.5],
];
/// Gmsh reference coordinates of the 27-node hexahedron on `[-1, 1]^3`: vertices; edges of
/// Gmsh's `MHexahedron` (0,1), (0,3), (0,4), (1,2), (1,5), (2,3), (2,6), (3,7), (4,5), (4,7),
/// (5,6), (6,7); faces (0,3,2,1), (0,1,5,4), (0,4,7,3), (1,2,6,5), (2,3,7,6), (4,5,6,7); centre.
const GMSH_HEX27: [[f64; 3]; 27] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
    [0.0, -1.0, -1.0],
    [-1.0, 0.0, -1.0],
    [-1.0, -1.0, 0.0],
    [1.0, 0.0, -1.0],
    [1.0, -1.0, 0.0],
    [0.0, 1.0, -1.0],
    [1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0],
    [0.0, -1.0, 1.0],
    [-1.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [0.0, 1.0, 1.0],
    [0.0, 0.0, -1.0],
    [0.0, -1.0, 0.0],
    [-1.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, 0.0],
];

/// Gmsh's reference node coordinates of a cell type, mapped to this crate's reference cells
/// (tensor cells from `[-1, 1]^d` to `[0, 1]^d`; simplices are the same).
fn gmsh_reference(cell: ReferenceCell, order: GeometryOrder) -> Vec<[f64; 3]> {
    let n = geometry_nodes(cell, order);
    let to_unit = |p: &[f64; 3], dim: usize| -> [f64; 3] { std::array::from_fn(|d| if d < dim { 0.5 * (p[d] + 1.0) } else { 0.0 }) };
    match cell {
        ReferenceCell::Triangle => GMSH_TRI6[..n].to_vec(),
        ReferenceCell::Tetrahedron => GMSH_TET10[..n].to_vec(),
        ReferenceCell::Quadrilateral => GMSH_QUA9[..n].iter().map(|p| to_unit(p, 2)).collect(),
        ReferenceCell::Hexahedron => GMSH_HEX27[..n].iter().map(|p| to_unit(p, 3)).collect(),
        ReferenceCell::Segment => Vec::new(),
    }
}

/// This crate's (VTK-ordered) reference node coordinates, padded to 3 components.
fn our_reference(cell: ReferenceCell, order: GeometryOrder) -> Vec<[f64; 3]> {
    match cell.dim() {
        2 => geometry_element::<2>(cell, order).nodes().iter().map(|p| [p[0], p[1], 0.0]).collect(),
        3 => geometry_element::<3>(cell, order).nodes().to_vec(),
        _ => Vec::new(),
    }
}

/// For each point of `to`, the index of the point of `from` at the same place; `None` unless
/// this is a bijection.
fn match_points(from: &[[f64; 3]], to: &[[f64; 3]]) -> Option<Vec<usize>> {
    if from.len() != to.len() {
        return None;
    }
    let same = |a: &[f64; 3], b: &[f64; 3]| (0..3).all(|d| (a[d] - b[d]).abs() < 1e-12);
    let perm: Vec<usize> = to.iter().map(|t| from.iter().position(|f| same(f, t))).collect::<Option<_>>()?;
    let mut seen = vec![false; perm.len()];
    for &p in &perm {
        if std::mem::replace(&mut seen[p], true) {
            return None;
        }
    }
    Some(perm)
}

/// `perm[k]`: the Gmsh node that is node `k` in VTK order (`ours[k] = gmsh[perm[k]]`).
pub fn gmsh_to_vtk_permutation(cell: ReferenceCell, order: GeometryOrder) -> Option<Vec<usize>> {
    match_points(&gmsh_reference(cell, order), &our_reference(cell, order))
}

/// `perm[k]`: the node of a cell that becomes node `k` of its mirror image under the reference
/// reflection `(xi_0, xi_1) -> (xi_1, xi_0)`, which reverses the orientation.
pub fn reflection_permutation(cell: ReferenceCell, order: GeometryOrder) -> Option<Vec<usize>> {
    let ours = our_reference(cell, order);
    let swapped: Vec<[f64; 3]> = ours.iter().map(|p| [p[1], p[0], p[2]]).collect();
    match_points(&ours, &swapped)
}

// ---------------------------------------------------------------------------------------------
// Building the mesh
// ---------------------------------------------------------------------------------------------

/// Builds the `D`-dimensional mesh from the file's contents.
fn build<const D: usize>(input: &Input) -> Result<Mesh<D>, GmshError> {
    let mut cells = collect_cells(input, D)?;
    let points = planar_points::<D>(&cells.points, &cells.point_tags, &input.file)?;
    let mut mesh = Mesh {
        points,
        cell_type: cells.cell_type,
        order: cells.order,
        cell_nodes: std::mem::take(&mut cells.nodes),
        cell_tags: vec![0; cells.element_tags.len()],
        region_names: Vec::new(),
        boundary: Vec::new(),
        boundary_names: Vec::new(),
    };
    assign_regions(&mut mesh, input, &cells)?;
    check_duplicates(&mesh, &cells.point_tags, &input.file)?;
    orient_cells(&mut mesh, &cells.element_tags, &input.file)?;
    check_jacobians(&mesh, &cells.element_tags, &input.file)?;
    assign_boundary(&mut mesh, input, &cells.compact)?;
    mesh.check().map_err(|e| GmshError::Inconsistent { file: input.file.clone(), message: e.to_string() })?;
    Ok(mesh)
}

/// The cells of a mesh in VTK node order, with compacted nodes.
struct Cells {
    cell_type: ReferenceCell,
    order: GeometryOrder,
    nodes: Vec<usize>,
    element_tags: Vec<u64>,
    entity_tags: Vec<i32>,
    /// Coordinates and Gmsh tag of each kept node.
    points: Vec<[f64; 3]>,
    point_tags: Vec<u64>,
    /// Gmsh node tag -> kept node.
    compact: HashMap<u64, usize>,
}

/// Collects the elements of dimension `dim` as cells: one supported type, nodes converted to VTK
/// order, node tags compacted in order of first use.
fn collect_cells(input: &Input, dim: usize) -> Result<Cells, GmshError> {
    let file = &input.file;
    let mut volume = input.elements.iter().filter(|e| type_dim(e.ty) == dim).peekable();
    let first = *volume.peek().ok_or_else(|| GmshError::NoCells { file: file.clone() })?;
    let unsupported = |e: &RawElement| GmshError::UnsupportedElement {
        file: file.clone(),
        element_tag: Some(e.tag),
        type_number: Some(e.ty as i64),
        detail: format!("{}; {SUPPORTED}", type_name(e.ty)),
    };
    let (cell_type, order) = cell_kind(first.ty).ok_or_else(|| unsupported(first))?;
    let internal = |what: &str| GmshError::Inconsistent { file: file.clone(), message: format!("internal error: {what}") };
    let perm = gmsh_to_vtk_permutation(cell_type, order).ok_or_else(|| internal("no Gmsh node permutation"))?;
    let mut cells = Cells {
        cell_type,
        order,
        nodes: Vec::new(),
        element_tags: Vec::new(),
        entity_tags: Vec::new(),
        points: Vec::new(),
        point_tags: Vec::new(),
        compact: HashMap::new(),
    };
    for e in volume {
        if e.ty != first.ty {
            if cell_kind(e.ty).is_none() {
                return Err(unsupported(e));
            }
            return Err(GmshError::MixedCellTypes { file: file.clone(), element_tag: e.tag, first: type_name(first.ty), found: type_name(e.ty) });
        }
        if e.nodes.len() != perm.len() {
            return Err(internal("element with a wrong number of nodes"));
        }
        for &k in &perm {
            let id = keep_node(&mut cells, input, e.tag, e.nodes[k])?;
            cells.nodes.push(id);
        }
        cells.element_tags.push(e.tag);
        cells.entity_tags.push(e.entity_tag);
    }
    Ok(cells)
}

/// The kept-node number of Gmsh node `tag`, keeping it if it is new.
fn keep_node(cells: &mut Cells, input: &Input, element_tag: u64, tag: u64) -> Result<usize, GmshError> {
    if let Some(&id) = cells.compact.get(&tag) {
        return Ok(id);
    }
    let x = input.nodes.get(&tag).ok_or_else(|| GmshError::MissingNode { file: input.file.clone(), element_tag, node_tag: tag })?;
    if !x.iter().all(|c| c.is_finite()) {
        return Err(GmshError::NonFiniteNode { file: input.file.clone(), node_tag: tag, coords: *x });
    }
    let id = cells.points.len();
    cells.points.push(*x);
    cells.point_tags.push(tag);
    cells.compact.insert(tag, id);
    Ok(id)
}

/// The points in `D` dimensions; for `D = 2` every `|z|` must be below `1e-12` times the size of
/// the mesh.
fn planar_points<const D: usize>(points: &[[f64; 3]], tags: &[u64], file: &str) -> Result<Vec<[f64; D]>, GmshError> {
    if D == 2 {
        let tol = 1e-12 * bounding_diagonal(points).max(f64::MIN_POSITIVE);
        if let Some((i, p)) = points.iter().enumerate().find(|(_, p)| p[2].abs().is_nan() || p[2].abs() > tol) {
            return Err(GmshError::NotPlanar { file: file.to_string(), node_tag: tags[i], z: p[2] });
        }
    }
    Ok(points.iter().map(|p| std::array::from_fn(|d| p[d])).collect())
}

fn bounding_diagonal<const N: usize>(points: &[[f64; N]]) -> f64 {
    let mut lo = [f64::INFINITY; N];
    let mut hi = [f64::NEG_INFINITY; N];
    for p in points {
        for d in 0..N {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (0..N).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt()
}

/// Duplicate-node check: points are binned in a grid of spacing `h = 1e-12 * diagonal`, and each
/// point is compared with the points in its own and the neighbouring bins, so every pair closer
/// than `h` in each coordinate is found in expected linear time. In a mesh of quadrilaterals or
/// hexahedra (a solid's) two nodes may coincide where they belong to cells of different
/// regions only (two bodies touching, as in a contact problem: separate physical groups);
/// within one region, or in a simplex (fluid) mesh, coincident nodes are a mesh that was not
/// merged, a crack no one asked for.
fn check_duplicates<const D: usize>(mesh: &Mesh<D>, tags: &[u64], file: &str) -> Result<(), GmshError> {
    let points = &mesh.points;
    let mut regions: Vec<Vec<u32>> = vec![Vec::new(); points.len()];
    for c in 0..mesh.num_cells() {
        for &p in mesh.cell(c) {
            if !regions[p].contains(&mesh.cell_tags[c]) {
                regions[p].push(mesh.cell_tags[c]);
            }
        }
    }
    // Only solid meshes (quadrilaterals, hexahedra) hold bodies that touch; a fluid mesh's
    // regions must be merged.
    let solid = matches!(mesh.cell_type, ReferenceCell::Quadrilateral | ReferenceCell::Hexahedron);
    let apart = |i: usize, j: usize| solid && !regions[i].is_empty() && !regions[j].is_empty() && regions[i].iter().all(|r| !regions[j].contains(r));
    if points.len() < 2 {
        return Ok(());
    }
    let diag = bounding_diagonal(points);
    if !diag.is_finite() {
        return Err(GmshError::Inconsistent { file: file.to_string(), message: "node coordinates are not finite".into() });
    }
    let h = 1e-12 * diag.max(f64::MIN_POSITIVE);
    let lo: [f64; D] = std::array::from_fn(|d| points.iter().map(|p| p[d]).fold(f64::INFINITY, f64::min));
    let bin = |p: &[f64; D]| -> [i64; D] { std::array::from_fn(|d| ((p[d] - lo[d]) / h).floor() as i64) };
    let mut bins: HashMap<[i64; D], Vec<usize>> = HashMap::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        bins.entry(bin(p)).or_default().push(i);
    }
    for (i, p) in points.iter().enumerate() {
        let b = bin(p);
        for code in 0..3usize.pow(D as u32) {
            let mut c = code;
            let nb: [i64; D] = std::array::from_fn(|d| {
                let o = (c % 3) as i64 - 1;
                c /= 3;
                b[d] + o
            });
            for &j in bins.get(&nb).map(Vec::as_slice).unwrap_or(&[]) {
                if j > i && (0..D).all(|d| (points[j][d] - p[d]).abs() <= h) && !apart(i, j) {
                    let coords = std::array::from_fn(|d| if d < D { p[d] } else { 0.0 });
                    return Err(GmshError::DuplicateNodes { file: file.to_string(), node_a: tags[i], node_b: tags[j], coords });
                }
            }
        }
    }
    Ok(())
}

/// Orientation and degeneracy of each cell (see the module documentation).
fn orient_cells<const D: usize>(mesh: &mut Mesh<D>, element_tags: &[u64], file: &str) -> Result<(), GmshError> {
    let reflect = reflection_permutation(mesh.cell_type, mesh.order)
        .ok_or_else(|| GmshError::Inconsistent { file: file.to_string(), message: "internal error: no reflection permutation".into() })?;
    let npc = mesh.nodes_per_cell();
    for (c, &element_tag) in element_tags.iter().enumerate() {
        let measure = mesh.signed_vertex_measure(c);
        let h = cell_extent(mesh, c);
        if measure.is_nan() || measure.abs() <= 1e-12 * h.powi(D as i32) {
            return Err(GmshError::DegenerateCell { file: file.to_string(), element_tag, measure });
        }
        if measure < 0.0 {
            if D == 3 {
                return Err(GmshError::InvertedCell { file: file.to_string(), element_tag, measure });
            }
            let old: Vec<usize> = mesh.cell(c).to_vec();
            for (k, &r) in reflect.iter().enumerate() {
                mesh.cell_nodes[c * npc + k] = old[r];
            }
        }
    }
    Ok(())
}

/// Largest coordinate extent of the vertices of cell `c`.
fn cell_extent<const D: usize>(mesh: &Mesh<D>, c: usize) -> f64 {
    let v = mesh.cell_vertices(c);
    (0..D)
        .map(|d| {
            let xs = v.iter().map(|&i| mesh.points[i][d]);
            xs.clone().fold(f64::NEG_INFINITY, f64::max) - xs.fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

/// For curved and tensor-product cells: `det J > 0` at every geometry node.
fn check_jacobians<const D: usize>(mesh: &Mesh<D>, element_tags: &[u64], file: &str) -> Result<(), GmshError> {
    let simplex = matches!(mesh.cell_type, ReferenceCell::Triangle | ReferenceCell::Tetrahedron);
    if simplex && mesh.order == GeometryOrder::Linear {
        return Ok(());
    }
    let geo = mesh.geometry_element();
    let tab = geo.tabulate(geo.nodes());
    let n = tab.num_dofs;
    let mut coords = Vec::with_capacity(n);
    for (c, &element_tag) in element_tags.iter().enumerate() {
        mesh.cell_coords_into(c, &mut coords);
        for q in 0..tab.num_points {
            let mut jac = [[0.0; D]; D];
            for (k, x) in coords.iter().enumerate() {
                let g = tab.grads[q * n + k];
                for a in 0..D {
                    for b in 0..D {
                        jac[a][b] += x[a] * g[b];
                    }
                }
            }
            let (det, _) = det_inv(&jac);
            if det.is_nan() || det <= 0.0 {
                return Err(GmshError::InvertedCell { file: file.to_string(), element_tag, measure: det });
            }
        }
    }
    Ok(())
}

/// A physical tag as a mesh tag (physical tags are positive).
fn physical_tag(tag: i32, file: &str) -> Result<u32, GmshError> {
    u32::try_from(tag)
        .ok()
        .filter(|&t| t > 0)
        .ok_or_else(|| GmshError::Inconsistent { file: file.to_string(), message: format!("invalid physical tag {tag}") })
}

/// Names of the physical tags `used` of dimension `dim`: all named groups of that dimension, and
/// used tags without a name under their number; sorted by tag.
fn group_names(input: &Input, dim: usize, used: &[u32]) -> Vec<(String, u32)> {
    let mut out: Vec<(String, u32)> =
        input.names.iter().filter(|((d, t), _)| *d == dim && *t > 0).map(|((_, t), name)| (name.clone(), *t as u32)).collect();
    for &t in used {
        if !out.iter().any(|(_, u)| *u == t) {
            out.push((t.to_string(), t));
        }
    }
    out.sort_by_key(|(_, t)| *t);
    out
}

/// Region tags of the cells from their entities' physical groups.
fn assign_regions<const D: usize>(mesh: &mut Mesh<D>, input: &Input, cells: &Cells) -> Result<(), GmshError> {
    let groups_exist = input.groups.iter().any(|((d, _), tags)| *d == D && !tags.is_empty());
    let mut used = Vec::new();
    mesh.cell_tags = Vec::with_capacity(cells.entity_tags.len());
    for (c, &entity) in cells.entity_tags.iter().enumerate() {
        let tag = match input.groups.get(&(D, entity)).and_then(|t| t.first()) {
            Some(&t) => physical_tag(t, &input.file)?,
            None if groups_exist => {
                return Err(GmshError::MissingPhysicalGroup { file: input.file.clone(), element_tag: cells.element_tags[c], entity_tag: entity })
            }
            None => 0,
        };
        if tag != 0 && !used.contains(&tag) {
            used.push(tag);
        }
        mesh.cell_tags.push(tag);
    }
    mesh.region_names = if groups_exist { group_names(input, D, &used) } else { Vec::new() };
    Ok(())
}

/// Sorted vertex set of a facet, padded with `usize::MAX`.
fn facet_key(verts: impl Iterator<Item = usize>) -> [usize; 4] {
    let mut key = [usize::MAX; 4];
    for (slot, v) in key.iter_mut().zip(verts) {
        *slot = v;
    }
    key.sort_unstable();
    key
}

/// Boundary facets from the tagged elements of dimension `D - 1`.
fn assign_boundary<const D: usize>(mesh: &mut Mesh<D>, input: &Input, compact: &HashMap<u64, usize>) -> Result<(), GmshError> {
    let file = &input.file;
    let ct = mesh.cell_type;
    let mut facets: HashMap<[usize; 4], (usize, usize)> = HashMap::with_capacity(mesh.num_cells() * ct.num_facets());
    for c in 0..mesh.num_cells() {
        let v = mesh.cell_vertices(c);
        for f in 0..ct.num_facets() {
            facets.entry(facet_key(ct.facet(f).iter().map(|&i| v[i]))).or_insert((c, f));
        }
    }
    let mut tagged: HashMap<(usize, usize), (u32, u64)> = HashMap::new();
    let mut used = Vec::new();
    for e in input.elements.iter().filter(|e| type_dim(e.ty) + 1 == D) {
        let nv = facet_vertices(e.ty, D).ok_or_else(|| GmshError::UnsupportedElement {
            file: file.clone(),
            element_tag: Some(e.tag),
            type_number: Some(e.ty as i64),
            detail: format!("{} as a boundary element of a {D}D mesh; {SUPPORTED}", type_name(e.ty)),
        })?;
        let not_on_facet = || GmshError::BoundaryNotOnFacet { file: file.clone(), element_tag: e.tag, kind: type_name(e.ty), dim: D };
        let mut verts = Vec::with_capacity(nv);
        for &node in e.nodes.iter().take(nv) {
            if !input.nodes.contains_key(&node) {
                return Err(GmshError::MissingNode { file: file.clone(), element_tag: e.tag, node_tag: node });
            }
            verts.push(*compact.get(&node).ok_or_else(not_on_facet)?);
        }
        // Every element of dimension D - 1 must be a facet (an untagged one too: otherwise it is
        // a lower-dimensional part of a mixed-dimension mesh, silently dropped).
        let &(cell, facet) = facets.get(&facet_key(verts.into_iter())).ok_or_else(not_on_facet)?;
        let Some(&phys) = input.groups.get(&(e.entity_dim, e.entity_tag)).and_then(|t| t.first()) else {
            continue;
        };
        let tag = physical_tag(phys, file)?;
        match tagged.get(&(cell, facet)) {
            Some(&(t, _)) if t == tag => continue,
            Some(&(t, other)) => {
                return Err(GmshError::Inconsistent {
                    file: file.clone(),
                    message: format!("boundary elements {other} and {} tag the same facet with {t} and {tag}", e.tag),
                })
            }
            None => {}
        }
        tagged.insert((cell, facet), (tag, e.tag));
        mesh.boundary.push(BoundaryFacet { cell, facet, tag });
        if !used.contains(&tag) {
            used.push(tag);
        }
    }
    mesh.boundary_names = group_names(input, D - 1, &used);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::{HEX_EDGES, HEX_FACETS, TET_EDGES, TET_FACETS};
    use crate::mesh::Topology;
    use crate::quadrature;
    use crate::values::{CellValues, FacetValues};
    use std::collections::HashSet;

    /// An element block: entity dimension, entity tag, element type, elements `(tag, nodes)`.
    type Block = (usize, i32, i32, Vec<(u64, Vec<u64>)>);

    /// A small MSH 4.1 ASCII file: physical names, entities (without bounding boxes), one node
    /// block, element blocks `(entity dim, entity tag, element type, [(tag, nodes)])`.
    #[derive(Default, Clone)]
    struct Msh {
        format: &'static str,
        names: Vec<(usize, i32, &'static str)>,
        entities: Vec<(usize, i32, Vec<i32>)>,
        nodes: Vec<(u64, [f64; 3])>,
        blocks: Vec<Block>,
    }

    impl Msh {
        fn text(&self) -> String {
            let format = if self.format.is_empty() { "4.1 0 8" } else { self.format };
            let mut s = format!("$MeshFormat\n{format}\n$EndMeshFormat\n");
            if !self.names.is_empty() {
                s += &format!("$PhysicalNames\n{}\n", self.names.len());
                for (d, t, n) in &self.names {
                    s += &format!("{d} {t} \"{n}\"\n");
                }
                s += "$EndPhysicalNames\n";
            }
            if !self.entities.is_empty() {
                let count = |d: usize| self.entities.iter().filter(|e| e.0 == d).count();
                s += &format!("$Entities\n{} {} {} {}\n", count(0), count(1), count(2), count(3));
                for d in 0..4 {
                    for (_, tag, phys) in self.entities.iter().filter(|e| e.0 == d) {
                        let ph: String = phys.iter().map(|p| format!(" {p}")).collect();
                        if d == 0 {
                            s += &format!("{tag} 0 0 0 {}{ph}\n", phys.len());
                        } else {
                            s += &format!("{tag} 0 0 0 0 0 0 {}{ph} 0\n", phys.len());
                        }
                    }
                }
                s += "$EndEntities\n";
            }
            let n = self.nodes.len();
            let min = self.nodes.iter().map(|x| x.0).min().unwrap_or(1);
            let max = self.nodes.iter().map(|x| x.0).max().unwrap_or(1);
            let dim = self.blocks.iter().map(|b| b.0).max().unwrap_or(0);
            s += &format!("$Nodes\n1 {n} {min} {max}\n{dim} 1 0 {n}\n");
            for (t, _) in &self.nodes {
                s += &format!("{t}\n");
            }
            for (_, x) in &self.nodes {
                s += &format!("{} {} {}\n", x[0], x[1], x[2]);
            }
            s += "$EndNodes\n";
            let all: Vec<u64> = self.blocks.iter().flat_map(|b| b.3.iter().map(|e| e.0)).collect();
            let (emin, emax) = (all.iter().min().unwrap_or(&1), all.iter().max().unwrap_or(&1));
            s += &format!("$Elements\n{} {} {emin} {emax}\n", self.blocks.len(), all.len());
            for (d, ent, ty, elems) in &self.blocks {
                s += &format!("{d} {ent} {ty} {}\n", elems.len());
                for (t, nodes) in elems {
                    let ns: Vec<String> = nodes.iter().map(|x| x.to_string()).collect();
                    s += &format!("{t} {}\n", ns.join(" "));
                }
            }
            s += "$EndElements\n";
            s
        }
    }

    fn parse(m: &Msh, name: &str) -> Result<AnyMesh, GmshError> {
        parse_msh(m.text().as_bytes(), name)
    }

    fn parse_2d(m: &Msh) -> Mesh<2> {
        parse(m, "test.msh").unwrap().into_2d().unwrap()
    }

    fn parse_3d(m: &Msh) -> Mesh<3> {
        parse(m, "test.msh").unwrap().into_3d().unwrap()
    }

    /// The unit square as two triangles (the second written clockwise), sparse node tags, a
    /// tagged bottom edge ("bottom", tag 3), a tagged right edge (unnamed tag 4), an untagged left
    /// edge.
    fn square() -> Msh {
        Msh {
            names: vec![(2, 7, "plate"), (1, 3, "bottom")],
            entities: vec![(2, 1, vec![7]), (1, 1, vec![3]), (1, 2, vec![4]), (1, 3, vec![])],
            nodes: vec![(10, [0.0, 0.0, 0.0]), (20, [1.0, 0.0, 0.0]), (30, [1.0, 1.0, 0.0]), (40, [0.0, 1.0, 0.0])],
            blocks: vec![
                (1, 1, 1, vec![(1, vec![10, 20])]),
                (1, 2, 1, vec![(2, vec![30, 20])]),
                (1, 3, 1, vec![(3, vec![40, 10])]),
                (2, 1, 2, vec![(4, vec![10, 20, 30]), (5, vec![10, 40, 30])]),
            ],
            ..Default::default()
        }
    }

    fn facet_coords<const D: usize>(m: &Mesh<D>, b: &BoundaryFacet) -> Vec<[f64; D]> {
        let v = m.cell_vertices(b.cell);
        let mut pts: Vec<[f64; D]> = m.cell_type.facet(b.facet).iter().map(|&i| m.points[v[i]]).collect();
        pts.sort_by(|a, b| a.partial_cmp(b).unwrap());
        pts
    }

    #[test]
    fn two_triangle_square_tags_and_orientation() {
        let m = parse_2d(&square());
        m.check().unwrap();
        assert_eq!((m.cell_type, m.order), (ReferenceCell::Triangle, GeometryOrder::Linear));
        assert_eq!(m.num_cells(), 2);
        assert_eq!(m.points.len(), 4);
        assert_eq!(m.cell_tags, vec![7, 7]);
        assert_eq!(m.region_names, vec![("plate".to_string(), 7)]);
        assert_eq!(m.boundary_names, vec![("bottom".to_string(), 3), ("4".to_string(), 4)]);
        assert_eq!(m.boundary.len(), 2);
        let bottom = m.boundary_facets("bottom").unwrap();
        assert_eq!(facet_coords(&m, &bottom[0]), vec![[0.0, 0.0], [1.0, 0.0]]);
        let right = m.boundary_facets("4").unwrap();
        assert_eq!(facet_coords(&m, &right[0]), vec![[1.0, 0.0], [1.0, 1.0]]);
        // The clockwise triangle was reoriented.
        assert!(m.signed_vertex_measure(1) > 0.0);
        assert_eq!(Topology::build(&m).exterior_facets().len(), 4);
    }

    #[test]
    fn physical_names_are_read_from_the_text() {
        let text = b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\r\n$PhysicalNames\r\n2\r\n1   3 \"no slip wall\"\r\n2 7 \"a\"\r\n$EndPhysicalNames\n";
        let names = physical_names(text, "n.msh").unwrap();
        assert_eq!(names[&(1, 3)], "no slip wall");
        assert_eq!(names[&(2, 7)], "a");
        let bad = b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n1 3 \"x\"\n$EndPhysicalNames\n";
        assert!(matches!(physical_names(bad, "n.msh"), Err(GmshError::Parse { .. })));
        let bad = b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n1 x \"x\"\n$EndPhysicalNames\n";
        assert!(matches!(physical_names(bad, "n.msh"), Err(GmshError::Parse { .. })));
    }

    #[test]
    fn dense_node_tags_and_no_physical_groups() {
        let mut s = square();
        s.entities.clear();
        s.names.clear();
        s.nodes = vec![(1, [0.0, 0.0, 0.0]), (2, [1.0, 0.0, 0.0]), (3, [1.0, 1.0, 0.0]), (4, [0.0, 1.0, 0.0])];
        s.blocks = vec![(2, 1, 2, vec![(4, vec![1, 2, 3]), (5, vec![1, 3, 4])]), (1, 1, 1, vec![(1, vec![1, 2])])];
        let m = parse_2d(&s);
        assert_eq!(m.cell_tags, vec![0, 0]);
        assert!(m.region_names.is_empty());
        assert!(m.boundary.is_empty(), "untagged lines are not boundary facets");
        assert_eq!(m.points[m.cell(0)[2]], [1.0, 1.0]);
    }

    #[test]
    fn quad9_mesh_is_read_in_vtk_order() {
        // One 9-node quadrangle on [0,2]x[0,1]; Gmsh and VTK orders coincide.
        let p = |x: f64, y: f64| [x, y, 0.0];
        let coords = [p(0., 0.), p(2., 0.), p(2., 1.), p(0., 1.), p(1., 0.), p(2., 0.5), p(1., 1.), p(0., 0.5), p(1., 0.5)];
        let m = parse_2d(&Msh {
            nodes: coords.iter().enumerate().map(|(i, x)| (i as u64 + 1, *x)).collect(),
            blocks: vec![(2, 1, 10, vec![(1, (1..=9).collect())])],
            ..Default::default()
        });
        assert_eq!((m.cell_type, m.order), (ReferenceCell::Quadrilateral, GeometryOrder::Quadratic));
        for (k, x) in coords.iter().enumerate() {
            assert_eq!(m.points[m.cell(0)[k]], [x[0], x[1]]);
        }
    }

    const GMSH_TET_EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [2, 0], [3, 0], [3, 2], [3, 1]];
    const GMSH_HEX_EDGES: [[usize; 2]; 12] = [[0, 1], [0, 3], [0, 4], [1, 2], [1, 5], [2, 3], [2, 6], [3, 7], [4, 5], [4, 7], [5, 6], [6, 7]];
    const GMSH_HEX_FACES: [[usize; 4]; 6] = [[0, 3, 2, 1], [0, 1, 5, 4], [0, 4, 7, 3], [1, 2, 6, 5], [2, 3, 7, 6], [4, 5, 6, 7]];

    fn mean(points: &[[f64; 3]]) -> [f64; 3] {
        std::array::from_fn(|d| points.iter().map(|p| p[d]).sum::<f64>() / points.len() as f64)
    }

    fn near(a: [f64; 3], b: [f64; 3]) -> bool {
        (0..3).all(|d| (a[d] - b[d]).abs() < 1e-14)
    }

    /// A 10-node tetrahedron written in Gmsh's node order (mid-edge nodes per Gmsh's
    /// `MTetrahedron` edge list), with a tagged 6-node boundary triangle on the face opposite
    /// vertex 0.
    fn tet10() -> Msh {
        let v = [[0.1, 0.0, 0.0], [1.0, 0.2, 0.0], [0.0, 1.0, 0.3], [0.2, 0.1, 1.0]];
        let mut nodes: Vec<[f64; 3]> = v.to_vec();
        nodes.extend(GMSH_TET_EDGES.iter().map(|e| mean(&[v[e[0]], v[e[1]]])));
        Msh {
            names: vec![(2, 5, "slanted")],
            entities: vec![(3, 1, vec![]), (2, 1, vec![5])],
            nodes: nodes.iter().enumerate().map(|(i, x)| (i as u64 + 1, *x)).collect(),
            // Boundary triangle (v3, v1, v2): edges (3,1) = Gmsh node 10, (1,2) = 6, (2,3) = 9.
            blocks: vec![(2, 1, 9, vec![(2, vec![4, 2, 3, 10, 6, 9])]), (3, 1, 11, vec![(1, (1..=10).collect())])],
            ..Default::default()
        }
    }

    #[test]
    fn tet10_mid_edge_nodes_follow_tet_edges() {
        let m = parse_3d(&tet10());
        m.check().unwrap();
        assert_eq!((m.cell_type, m.order), (ReferenceCell::Tetrahedron, GeometryOrder::Quadratic));
        let n = m.cell(0);
        let p = |k: usize| m.points[n[k]];
        for (k, e) in TET_EDGES.iter().enumerate() {
            assert!(near(p(4 + k), mean(&[p(e[0]), p(e[1])])), "mid-edge node of edge {e:?}");
        }
        assert!(m.is_affine_cell(0));
        assert_eq!(m.cell_tags, vec![0]);
        assert_eq!(m.boundary, vec![BoundaryFacet { cell: 0, facet: 0, tag: 5 }]);
        assert_eq!(TET_FACETS[0], [1, 2, 3]);
        assert_eq!(m.boundary_names, vec![("slanted".to_string(), 5)]);
    }

    /// A 27-node hexahedron (distorted trilinear box) in Gmsh's node order, sparse node tags,
    /// with a tagged 9-node quadrangle on Gmsh face (0, 3, 2, 1).
    fn hex27() -> Msh {
        let mut v = [[0.0; 3]; 8];
        for (i, p) in v.iter_mut().enumerate() {
            let (x, y, z) = ((i == 1 || i == 2 || i == 5 || i == 6) as u8, (i % 4 >= 2) as u8, (i >= 4) as u8);
            *p = [2.0 * x as f64, 3.0 * y as f64, 0.5 * z as f64];
        }
        v[6] = [2.2, 3.1, 0.6];
        v[0] = [-0.1, 0.05, 0.0];
        let mut nodes: Vec<[f64; 3]> = v.to_vec();
        nodes.extend(GMSH_HEX_EDGES.iter().map(|e| mean(&[v[e[0]], v[e[1]]])));
        nodes.extend(GMSH_HEX_FACES.iter().map(|f| mean(&f.map(|i| v[i]))));
        nodes.push(mean(&v));
        let tag = |i: usize| 100 + 7 * i as u64;
        // Gmsh quad9 on face (0,3,2,1): vertices, then its edges (0,3), (3,2), (2,1), (1,0), centre.
        let quad = vec![tag(0), tag(3), tag(2), tag(1), tag(9), tag(13), tag(11), tag(8), tag(20)];
        Msh {
            names: vec![(3, 1, "solid"), (2, 2, "bottom")],
            entities: vec![(3, 1, vec![1]), (2, 1, vec![2])],
            nodes: nodes.iter().enumerate().map(|(i, x)| (tag(i), *x)).collect(),
            blocks: vec![(3, 1, 12, vec![(1, (0..27).map(tag).collect())]), (2, 1, 10, vec![(2, quad)])],
            ..Default::default()
        }
    }

    #[test]
    fn hex27_nodes_follow_vtk_edges_and_faces() {
        let m = parse_3d(&hex27());
        m.check().unwrap();
        assert_eq!((m.cell_type, m.order), (ReferenceCell::Hexahedron, GeometryOrder::Quadratic));
        let n = m.cell(0);
        let p = |k: usize| m.points[n[k]];
        for (k, e) in HEX_EDGES.iter().enumerate() {
            assert!(near(p(8 + k), mean(&[p(e[0]), p(e[1])])), "edge node {k}");
        }
        for (f, face) in HEX_FACETS.iter().enumerate() {
            assert!(near(p(20 + f), mean(&face.map(p))), "face node {f}");
        }
        assert!(near(p(26), mean(&(0..8).map(p).collect::<Vec<_>>())));
        assert_eq!(m.cell_tags, vec![1]);
        assert_eq!(m.region_names, vec![("solid".to_string(), 1)]);
        // Gmsh face (0,3,2,1) is z-min, facet 4 of HEX_FACETS.
        assert_eq!(m.boundary, vec![BoundaryFacet { cell: 0, facet: 4, tag: 2 }]);
    }

    #[test]
    fn node_permutations_are_bijections() {
        use GeometryOrder::*;
        use ReferenceCell::*;
        for cell in [Triangle, Quadrilateral, Tetrahedron, Hexahedron] {
            for order in [Linear, Quadratic] {
                let perm = gmsh_to_vtk_permutation(cell, order).expect("Gmsh table matches ours");
                let n = geometry_nodes(cell, order);
                let set: HashSet<usize> = perm.iter().copied().collect();
                assert_eq!((perm.len(), set.len()), (n, n));
                assert!(perm[..cell.num_vertices()].iter().enumerate().all(|(i, &p)| i == p), "vertices keep their order");
                let r = reflection_permutation(cell, order).unwrap();
                assert!(r.iter().enumerate().all(|(k, &j)| r[j] == k), "a reflection is an involution");
            }
        }
        assert_eq!(gmsh_to_vtk_permutation(Tetrahedron, Quadratic).unwrap(), vec![0, 1, 2, 3, 4, 5, 6, 7, 9, 8]);
        assert_eq!(gmsh_to_vtk_permutation(Triangle, Quadratic).unwrap(), (0..6).collect::<Vec<_>>());
        assert_eq!(gmsh_to_vtk_permutation(Quadrilateral, Quadratic).unwrap(), (0..9).collect::<Vec<_>>());
        assert_eq!(reflection_permutation(Triangle, Quadratic).unwrap(), vec![0, 2, 1, 5, 4, 3]);
        // The reflection reverses the orientation of a reference triangle and quadrilateral.
        for (cell, order) in [(Triangle, Quadratic), (Quadrilateral, Quadratic)] {
            let nodes: Vec<[f64; 2]> = our_reference(cell, order).iter().map(|p| [p[0], p[1]]).collect();
            let r = reflection_permutation(cell, order).unwrap();
            let mut m = Mesh {
                points: nodes,
                cell_type: cell,
                order,
                cell_nodes: r,
                cell_tags: vec![0],
                region_names: vec![],
                boundary: vec![],
                boundary_names: vec![],
            };
            assert!(m.signed_vertex_measure(0) < 0.0);
            m.cell_nodes = (0..geometry_nodes(cell, order)).collect();
            assert!(m.signed_vertex_measure(0) > 0.0);
        }
    }

    fn meshes_dir() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../meshes")
    }

    /// Reads a DFG 2D mesh, checks it, and returns the relative error of its cylinder length.
    fn check_dfg(name: &str) -> f64 {
        let m = read_msh(&meshes_dir().join(name)).unwrap().into_2d().expect("a 2D mesh");
        m.check().unwrap();
        assert_eq!((m.cell_type, m.order), (ReferenceCell::Triangle, GeometryOrder::Quadratic));
        for b in ["inlet", "outlet", "walls", "cylinder"] {
            assert!(!m.boundary_facets(b).unwrap().is_empty(), "boundary {b}");
        }
        assert_eq!(m.region_tag("fluid").unwrap(), 1);
        assert!(m.cell_tags.iter().all(|&t| t == 1));
        // Area with the curved P2 geometry.
        let geo = m.geometry_element();
        let mut cv = CellValues::new(quadrature::triangle(4), &geo, &geo);
        let mut coords = Vec::new();
        let mut area = 0.0;
        for c in 0..m.num_cells() {
            m.cell_coords_into(c, &mut coords);
            cv.reinit(&coords).unwrap();
            area += cv.jxw.iter().sum::<f64>();
        }
        let pi = std::f64::consts::PI;
        let exact = 2.2 * 0.41 - pi * 0.05 * 0.05;
        assert!((area - exact).abs() < 1e-6 * exact, "area {area} vs {exact}");
        // Length of the cylinder.
        let seg = quadrature::segment(6);
        let pts: Vec<[f64; 2]> = seg.points.iter().map(|p| [p[0], 0.0]).collect();
        let mut fv = FacetValues::new(ReferenceCell::Triangle, &pts, &seg.weights, &geo, &geo);
        let mut length = 0.0;
        for b in m.boundary_facets("cylinder").unwrap() {
            m.cell_coords_into(b.cell, &mut coords);
            fv.reinit(&coords, b.facet).unwrap();
            length += fv.jxw.iter().sum::<f64>();
            // Outward normal of the fluid points into the cylinder, towards its centre (0.2, 0.2).
            let (x, nrm) = (fv.x[0], fv.normal[0]);
            assert!((x[0] - 0.2) * nrm[0] + (x[1] - 0.2) * nrm[1] < 0.0);
        }
        let circ = 2.0 * pi * 0.05;
        // Every exterior facet is tagged, once.
        let exterior: HashSet<(usize, usize)> = Topology::build(&m).exterior_facets().into_iter().collect();
        let tagged: HashSet<(usize, usize)> = m.boundary.iter().map(|b| (b.cell, b.facet)).collect();
        assert_eq!(tagged.len(), m.boundary.len());
        assert_eq!(exterior, tagged);
        (length - circ) / circ
    }

    /// The cylinder length converges at the 4th order of the P2 geometry: the coarse mesh has 32
    /// equal arcs of the cylinder (arc angle 0.196), whose parabolic interpolants are shorter than
    /// the circle by the relative 1.544e-6 (computed independently); the medium mesh has 64
    /// (9.7e-8). So the coarse mesh meets 2e-6, the medium one 1e-6.
    #[test]
    fn dfg2d_meshes_are_curved_p2_meshes() {
        let coarse = check_dfg("dfg2d-coarse.msh");
        let medium = check_dfg("dfg2d-medium.msh");
        assert!((coarse + 1.5436e-6).abs() < 1e-9, "coarse cylinder length error {coarse:e}");
        assert!(coarse.abs() < 2e-6 && medium.abs() < 1e-6, "{coarse:e} {medium:e}");
        assert!(coarse / medium > 14.0, "4th-order convergence: {coarse:e} / {medium:e}");
    }

    /// The error of parsing `text` as `name`, checking that its message names the file.
    fn error_of(text: &[u8], name: &str) -> GmshError {
        let e = parse_msh(text, name).expect_err("the input is malformed");
        assert!(e.to_string().contains(name), "message '{e}' does not name the file");
        e
    }

    fn single_tet(v: [[f64; 3]; 4]) -> Msh {
        Msh {
            nodes: v.iter().enumerate().map(|(i, x)| (i as u64 + 1, *x)).collect(),
            blocks: vec![(3, 1, 4, vec![(42, vec![1, 2, 3, 4])])],
            ..Default::default()
        }
    }

    #[test]
    fn unsupported_element_type_is_named() {
        // A prism (Gmsh type 6) in a 3D mesh.
        let mut m = single_tet([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        m.nodes.extend([(5, [1.0, 0.0, 1.0]), (6, [0.0, 1.0, 1.0])]);
        m.blocks = vec![(3, 1, 6, vec![(17, vec![1, 2, 3, 4, 5, 6])])];
        let e = error_of(m.text().as_bytes(), "prism.msh");
        assert!(matches!(e, GmshError::UnsupportedElement { element_tag: Some(17), type_number: Some(6), .. }), "{e}");
        // A type number Gmsh does not know.
        let mut m = square();
        m.blocks.push((2, 1, 200, vec![(77, vec![10, 20, 30])]));
        let e = error_of(m.text().as_bytes(), "unknown-type.msh");
        assert!(matches!(e, GmshError::UnsupportedElement { element_tag: Some(77), type_number: Some(200), .. }), "{e}");
        // A 20-node hexahedron (serendipity, Gmsh type 17).
        let mut m = single_tet([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        m.blocks = vec![(3, 1, 17, vec![(3, (1..=20).map(|i| (i - 1) % 4 + 1).collect())])];
        let e = error_of(m.text().as_bytes(), "hex20.msh");
        assert!(matches!(e, GmshError::UnsupportedElement { element_tag: Some(3), type_number: Some(17), .. }), "{e}");
    }

    #[test]
    fn missing_node_is_named() {
        let mut m = square();
        m.blocks[3].3[1].1 = vec![10, 99, 30];
        let e = error_of(m.text().as_bytes(), "missing.msh");
        assert!(matches!(e, GmshError::MissingNode { element_tag: 5, node_tag: 99, .. }), "{e}");
        assert!(e.to_string().contains("99"));
    }

    #[test]
    fn duplicate_nodes_are_found() {
        let mut m = square();
        m.nodes.push((50, [1.0, 1.0, 0.0]));
        m.blocks[3].3[1].1 = vec![10, 50, 40];
        let e = error_of(m.text().as_bytes(), "dup.msh");
        assert!(matches!(e, GmshError::DuplicateNodes { node_a: 30, node_b: 50, .. }), "{e}");
    }

    #[test]
    fn inverted_and_degenerate_tets_are_refused() {
        let m = single_tet([[0.0; 3], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
        let e = error_of(m.text().as_bytes(), "inverted.msh");
        assert!(matches!(e, GmshError::InvertedCell { element_tag: 42, .. }), "{e}");
        let m = single_tet([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
        let e = error_of(m.text().as_bytes(), "flat.msh");
        assert!(matches!(e, GmshError::DegenerateCell { element_tag: 42, .. }), "{e}");
        // A curved tet10 whose mid-edge node is pulled through the opposite face.
        let mut m = tet10();
        m.nodes[4].1 = [0.3, 3.0, 0.0];
        let e = error_of(m.text().as_bytes(), "tangled.msh");
        assert!(matches!(e, GmshError::InvertedCell { element_tag: 1, .. }), "{e}");
    }

    #[test]
    fn boundary_element_off_the_cells_is_refused() {
        let mut m = square();
        m.blocks[0].3[0].1 = vec![20, 40]; // the diagonal that is not an edge
        let e = error_of(m.text().as_bytes(), "off-facet.msh");
        assert!(matches!(e, GmshError::BoundaryNotOnFacet { element_tag: 1, .. }), "{e}");
    }

    #[test]
    fn truncated_garbage_and_empty_files_are_parse_errors() {
        let text = square().text();
        for cut in [text.len() / 2, text.len() - 20, 30] {
            let e = error_of(&text.as_bytes()[..cut], "truncated.msh");
            assert!(matches!(e, GmshError::Parse { .. }), "cut {cut}: {e}");
        }
        let e = error_of(b"\x00\xffthis is not a mesh\n\x13\x37", "garbage.msh");
        assert!(matches!(e, GmshError::Parse { .. }), "{e}");
        let e = error_of(b"", "empty.msh");
        assert!(matches!(e, GmshError::Parse { .. }), "{e}");
        // Garbage after a valid header.
        let e = error_of(b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2 x\n", "bad-nodes.msh");
        assert!(matches!(e, GmshError::Parse { .. }), "{e}");
        // Binary headers that mshio would choke on.
        let e = error_of(b"$MeshFormat\n4.1 1 3\n\x01\x00\x00\x00\n$EndMeshFormat\n", "size3.msh");
        assert!(matches!(e, GmshError::Parse { .. }), "{e}");
        let e = error_of(b"$MeshFormat\n4.1 1 8\n\x07\x07\x07\x07\n$EndMeshFormat\n", "endian.msh");
        assert!(matches!(e, GmshError::Parse { .. }), "{e}");
    }

    #[test]
    fn old_format_version_is_refused() {
        let m = Msh { format: "2.2 0 8", ..square() };
        let e = error_of(m.text().as_bytes(), "old.msh");
        assert!(matches!(e, GmshError::UnsupportedVersion { ref version, .. } if version == "2.2"), "{e}");
    }

    #[test]
    fn mixed_cell_types_are_refused() {
        let mut m = square();
        m.nodes.extend([(60, [2.0, 0.0, 0.0]), (70, [2.0, 1.0, 0.0])]);
        m.blocks.push((2, 1, 3, vec![(9, vec![20, 60, 70, 30])]));
        let e = error_of(m.text().as_bytes(), "mixed.msh");
        assert!(matches!(e, GmshError::MixedCellTypes { element_tag: 9, .. }), "{e}");
    }

    #[test]
    fn cell_without_physical_group_is_refused() {
        let mut m = square();
        m.entities.push((2, 2, vec![]));
        let last = m.blocks.len() - 1;
        let second = m.blocks[last].3.pop().unwrap();
        m.blocks.push((2, 2, 2, vec![second]));
        let e = error_of(m.text().as_bytes(), "ungrouped.msh");
        assert!(matches!(e, GmshError::MissingPhysicalGroup { element_tag: 5, entity_tag: 2, .. }), "{e}");
    }

    #[test]
    fn non_planar_and_lower_dimensional_meshes_are_refused() {
        let mut m = square();
        m.nodes[2].1[2] = 0.5;
        let e = error_of(m.text().as_bytes(), "bent.msh");
        assert!(matches!(e, GmshError::NotPlanar { node_tag: 30, .. }), "{e}");
        let mut m = square();
        m.blocks.truncate(3);
        let e = error_of(m.text().as_bytes(), "lines.msh");
        assert!(matches!(e, GmshError::NoCells { .. }), "{e}");
    }

    #[test]
    fn unreadable_file_is_an_io_error() {
        let path = Path::new("/nonexistent/dir/none.msh");
        let e = read_msh(path).unwrap_err();
        assert!(matches!(e, GmshError::Io { .. }));
        assert!(e.to_string().contains("none.msh"));
    }

    /// Corrupted files (bytes overwritten, deleted or duplicated at pseudo-random places) give an
    /// error or a mesh, never a panic.
    #[test]
    fn corrupted_files_never_panic() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = |n: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n as u64) as usize
        };
        const BYTES: &[u8] = b"0123456789 -.\n$eE\x00\xff";
        for original in [square().text().into_bytes(), tet10().text().into_bytes(), hex27().text().into_bytes(), binary_square()] {
            for _ in 0..300 {
                let mut b = original.clone();
                for _ in 0..1 + next(3) {
                    let at = next(b.len());
                    match next(3) {
                        0 => b[at] = BYTES[next(BYTES.len())],
                        1 => {
                            b.remove(at);
                        }
                        _ => b.insert(at, b[at]),
                    }
                }
                if let Ok(AnyMesh::D2(m)) = parse_msh(&b, "fuzz.msh") {
                    m.check().unwrap();
                } else if let Ok(AnyMesh::D3(m)) = parse_msh(&b, "fuzz.msh") {
                    m.check().unwrap();
                }
            }
        }
    }

    /// The square of [`square`] as a binary (little-endian) MSH 4.1 file.
    fn binary_square() -> Vec<u8> {
        let mut b: Vec<u8> = b"$MeshFormat\n4.1 1 8\n".to_vec();
        b.extend(1i32.to_le_bytes());
        b.extend(b"\n$EndMeshFormat\n$PhysicalNames\n2\n1 3 \"bottom\"\n2 7 \"plate\"\n$EndPhysicalNames\n$Entities\n");
        let size = |b: &mut Vec<u8>, v: u64| b.extend(v.to_le_bytes());
        let int = |b: &mut Vec<u8>, v: i32| b.extend(v.to_le_bytes());
        let dbl = |b: &mut Vec<u8>, v: f64| b.extend(v.to_le_bytes());
        for n in [0, 1, 1, 0] {
            size(&mut b, n);
        }
        // Curve 1 (physical 3) and surface 1 (physical 7).
        for phys in [3, 7] {
            int(&mut b, 1);
            for _ in 0..6 {
                dbl(&mut b, 0.0);
            }
            size(&mut b, 1);
            int(&mut b, phys);
            size(&mut b, 0);
        }
        b.extend(b"\n$EndEntities\n$Nodes\n");
        for v in [1, 4, 10, 40] {
            size(&mut b, v);
        }
        int(&mut b, 2);
        int(&mut b, 1);
        int(&mut b, 0);
        size(&mut b, 4);
        for t in [10, 20, 30, 40] {
            size(&mut b, t);
        }
        for x in [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]] {
            dbl(&mut b, x[0]);
            dbl(&mut b, x[1]);
            dbl(&mut b, 0.0);
        }
        b.extend(b"\n$EndNodes\n$Elements\n");
        for v in [2, 3, 1, 3] {
            size(&mut b, v);
        }
        let blocks: [(i32, i32, Vec<Vec<u64>>); 2] = [(1, 1, vec![vec![1, 10, 20]]), (2, 2, vec![vec![2, 10, 20, 30], vec![3, 10, 30, 40]])];
        for (dim, ty, elems) in blocks {
            int(&mut b, dim);
            int(&mut b, 1);
            int(&mut b, ty);
            size(&mut b, elems.len() as u64);
            for e in elems {
                for v in e {
                    size(&mut b, v);
                }
            }
        }
        b.extend(b"\n$EndElements\n");
        b
    }

    #[test]
    fn binary_msh_is_read() {
        let m = parse_msh(&binary_square(), "binary.msh").unwrap().into_2d().unwrap();
        m.check().unwrap();
        assert_eq!(m.num_cells(), 2);
        assert_eq!(m.cell_tags, vec![7, 7]);
        assert_eq!(m.region_names, vec![("plate".to_string(), 7)]);
        let bottom = m.boundary_facets("bottom").unwrap();
        assert_eq!(bottom.len(), 1);
        assert_eq!(facet_coords(&m, &bottom[0]), vec![[0.0, 0.0], [1.0, 0.0]]);
    }
}
