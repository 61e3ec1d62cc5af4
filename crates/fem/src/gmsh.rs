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
//!   times the bounding-box diagonal (in each coordinate) are an error (duplicate nodes).
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
//!   set. An element that matches no cell facet is an error. A facet shared by two cells (an
//!   interface) is tagged once, on the first cell that has it. A facet tagged twice with
//!   different tags is an error. Elements of dimension `D - 1` without a physical tag, and
//!   elements of lower dimension, are ignored. Boundary names come from `$PhysicalNames` of
//!   dimension `D - 1` (unnamed tags that are used are named by their number).
//!
//! Limitations (of `mshio` 0.4): only format 4.1 is read; parametric node blocks are refused;
//! when all node tags of the file are contiguous, `mshio` drops them and node `i` of the file is
//! taken to have tag `min_tag + i` (the order Gmsh writes). `$PhysicalNames` is not parsed by
//! `mshio` and is read here from the text (also in binary files, where Gmsh writes it as text).
//! Errors name the file and, where it applies, the Gmsh element or node tag.

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
    #[error("{file}: element {element_tag} is a {found}, but the mesh's cells are {first}s (one cell type per mesh)")]
    MixedCellTypes { file: String, element_tag: u64, first: String, found: String },
    #[error("{file}: nodes {node_a} and {node_b} coincide at {coords:?} (duplicate nodes)")]
    DuplicateNodes { file: String, node_a: u64, node_b: u64, coords: [f64; 3] },
    #[error("{file}: element {element_tag} is inverted (signed measure or det J {measure:.3e})")]
    InvertedCell { file: String, element_tag: u64, measure: f64 },
    #[error("{file}: element {element_tag} is degenerate (signed measure {measure:.3e})")]
    DegenerateCell { file: String, element_tag: u64, measure: f64 },
    #[error("{file}: element {element_tag} (entity {entity_tag}) belongs to no physical group, but other cells do")]
    MissingPhysicalGroup { file: String, element_tag: u64, entity_tag: i32 },
    #[error("{file}: boundary element {element_tag} is not a facet of any cell")]
    BoundaryNotOnFacet { file: String, element_tag: u64 },
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
    match version.parse::<f64>() {
        Ok(v) if v == 4.1 => {}
        Ok(_) => return Err(GmshError::UnsupportedVersion { file: file.to_string(), version }),
        Err(_) => return Err(parse_err(&format!("invalid format version '{version}' in $MeshFormat"))),
    }
    let binary = match token(1).as_deref() {
        Some("0") => false,
        Some("1") => true,
        other => return Err(parse_err(&format!("invalid file type {other:?} in $MeshFormat (0 or 1)"))),
    };
    match token(2).as_deref().map(str::parse::<usize>) {
        Some(Ok(1 | 2 | 4 | 8 | 16)) => Ok(binary),
        _ => Err(parse_err(&format!("invalid data size {:?} in $MeshFormat", token(2)))),
    }
}

/// Runs `mshio`, turning its errors (and, defensively, its panics) into [`GmshError`]s.
fn run_mshio(bytes: &[u8], file: &str, binary: bool) -> Result<MshFile<u64, i32, f64>, GmshError> {
    let result = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(bytes).map_err(|e| mshio_error(bytes, &e, file, binary))
    });
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
        return GmshError::UnsupportedElement {
            file: file.to_string(),
            element_tag,
            type_number,
            detail: "unknown element type number".into(),
        };
    }
    let message = match trace.first() {
        None => "unknown parse error".to_string(),
        Some((at, kind)) => {
            let off = offset(at);
            let line = bytes[..off.min(bytes.len())].iter().filter(|&&b| b == b'\n').count() + 1;
            let contexts: Vec<String> =
                trace[1..].iter().rev().map(|(_, k)| k.context().map_or_else(|| k.to_string(), String::from)).collect();
            let place = if binary { format!("byte {off}") } else { format!("line {line}") };
            if contexts.is_empty() {
                format!("{kind} (at {place})")
            } else {
                format!("{kind} (in {}; at {place})", contexts.join(" > "))
            }
        }
    };
    GmshError::Parse { file: file.to_string(), message }
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
    let len = find(&bytes[body_start..], b"$EndPhysicalNames")
        .ok_or_else(|| err("$PhysicalNames has no $EndPhysicalNames".into()))?;
    let text = String::from_utf8_lossy(&bytes[body_start..body_start + len]);
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let count: usize = lines
        .next()
        .and_then(|l| l.parse().ok())
        .ok_or_else(|| err("$PhysicalNames does not start with the number of names".into()))?;
    let mut read = 0;
    for line in lines {
        let bad = || err(format!("invalid line in $PhysicalNames: '{line}'"));
        let mut parts = line.splitn(3, char::is_whitespace);
        let dim: usize = parts.next().and_then(|t| t.parse().ok()).ok_or_else(bad)?;
        let tag: i32 = parts.next().and_then(|t| t.trim().parse().ok()).ok_or_else(bad)?;
        let name = parts.next().ok_or_else(bad)?.trim().trim_matches('"').to_string();
        names.insert((dim, tag), name);
        read += 1;
    }
    if read != count {
        return Err(err(format!("$PhysicalNames announces {count} names but has {read}")));
    }
    Ok(names)
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
            Some(map) => map.iter().map(|(&t, &i)| (t, i)).collect(),
            None => (0..block.nodes.len()).map(|i| (next + i as u64, i)).collect(),
        };
        for (tag, i) in entries {
            let x = coords(i).ok_or_else(|| GmshError::Inconsistent {
                file: file.to_string(),
                message: format!("node {tag} has no coordinates"),
            })?;
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
const GMSH_TRI6: [[f64; 3]; 6] =
    [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.5, 0.0]];
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
    let cells = collect_cells(input, D)?;
    let points = planar_points::<D>(&cells.points, &cells.point_tags, &input.file)?;
    check_duplicates(&points, &cells.point_tags, &input.file)?;
    let mut mesh = Mesh {
        points,
        cell_type: cells.cell_type,
        order: cells.order,
        cell_nodes: cells.nodes,
        cell_tags: Vec::new(),
        region_names: Vec::new(),
        boundary: Vec::new(),
        boundary_names: Vec::new(),
    };
    orient_cells(&mut mesh, &cells.element_tags, &input.file)?;
    check_jacobians(&mesh, &cells.element_tags, &input.file)?;
    assign_regions(&mut mesh, input, &cells)?;
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
            return Err(GmshError::MixedCellTypes {
                file: file.clone(),
                element_tag: e.tag,
                first: type_name(first.ty),
                found: type_name(e.ty),
            });
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
    let x = input.nodes.get(&tag).ok_or_else(|| GmshError::MissingNode {
        file: input.file.clone(),
        element_tag,
        node_tag: tag,
    })?;
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
        if let Some((i, p)) = points.iter().enumerate().find(|(_, p)| !(p[2].abs() <= tol)) {
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
/// than `h` in each coordinate is found in expected linear time.
fn check_duplicates<const D: usize>(points: &[[f64; D]], tags: &[u64], file: &str) -> Result<(), GmshError> {
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
                if j > i && (0..D).all(|d| (points[j][d] - p[d]).abs() <= h) {
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
    let reflect = reflection_permutation(mesh.cell_type, mesh.order).ok_or_else(|| GmshError::Inconsistent {
        file: file.to_string(),
        message: "internal error: no reflection permutation".into(),
    })?;
    let npc = mesh.nodes_per_cell();
    for c in 0..mesh.num_cells() {
        let measure = mesh.signed_vertex_measure(c);
        let h = cell_extent(mesh, c);
        if !(measure.abs() > 1e-12 * h.powi(D as i32)) {
            return Err(GmshError::DegenerateCell { file: file.to_string(), element_tag: element_tags[c], measure });
        }
        if measure < 0.0 {
            if D == 3 {
                return Err(GmshError::InvertedCell { file: file.to_string(), element_tag: element_tags[c], measure });
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
    for c in 0..mesh.num_cells() {
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
            if !(det > 0.0) {
                return Err(GmshError::InvertedCell { file: file.to_string(), element_tag: element_tags[c], measure: det });
            }
        }
    }
    Ok(())
}

/// A physical tag as a mesh tag (physical tags are positive).
fn physical_tag(tag: i32, file: &str) -> Result<u32, GmshError> {
    u32::try_from(tag).ok().filter(|&t| t > 0).ok_or_else(|| GmshError::Inconsistent {
        file: file.to_string(),
        message: format!("invalid physical tag {tag}"),
    })
}

/// Names of the physical tags `used` of dimension `dim`: all named groups of that dimension, and
/// used tags without a name under their number; sorted by tag.
fn group_names(input: &Input, dim: usize, used: &[u32]) -> Vec<(String, u32)> {
    let mut out: Vec<(String, u32)> = input
        .names
        .iter()
        .filter(|((d, t), _)| *d == dim && *t > 0)
        .map(|((_, t), name)| (name.clone(), *t as u32))
        .collect();
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
                return Err(GmshError::MissingPhysicalGroup {
                    file: input.file.clone(),
                    element_tag: cells.element_tags[c],
                    entity_tag: entity,
                })
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
        let Some(&phys) = input.groups.get(&(e.entity_dim, e.entity_tag)).and_then(|t| t.first()) else {
            continue;
        };
        let tag = physical_tag(phys, file)?;
        let not_on_facet = || GmshError::BoundaryNotOnFacet { file: file.clone(), element_tag: e.tag };
        let mut verts = Vec::with_capacity(nv);
        for &node in e.nodes.iter().take(nv) {
            if !input.nodes.contains_key(&node) {
                return Err(GmshError::MissingNode { file: file.clone(), element_tag: e.tag, node_tag: node });
            }
            verts.push(*compact.get(&node).ok_or_else(not_on_facet)?);
        }
        let &(cell, facet) = facets.get(&facet_key(verts.into_iter())).ok_or_else(not_on_facet)?;
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
//TESTS
}
