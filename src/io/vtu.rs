//! ParaView output: VTK XML UnstructuredGrid (`.vtu`) files, their parallel index (`.pvtu`, one
//! piece per MPI rank) and `.pvd` time collections.
//!
//! Files are VTK XML, version 0.1, little endian, with the arrays in one of three encodings
//! ([`Encoding`]): `binary` (the default: each array base64-encoded after a UInt64 byte count,
//! `header_type="UInt64"`; about a third of the ASCII size and faster to write and read),
//! `compressed` (VTK's `vtkZLibDataCompressor`: each array cut into 32 KiB blocks compressed with
//! zlib, base64 of the header [blocks, block size, last block size, compressed sizes…] followed by
//! base64 of the blocks) or `ascii` (floating point values printed with Rust's shortest
//! round-trip representation in exponent form, `{:e}`). All read back bit-identical. Floating point values are `Float64`,
//! connectivity and offsets `Int64`, cell types `UInt8`. All files are written through
//! [`write_atomic_with`], so an interrupted run never leaves a half-written file.
//!
//! [`read_vtu`] is a small hand-written reader for exactly this subset of the format (one
//! piece, ascii or binary arrays); it is meant for tests and post-processing of deasim's own
//! output.

use std::collections::BTreeMap;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::atomic::write_atomic_with;

/// Cell shapes deasim writes. The node order of the mesh is already VTK's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellType {
    /// 8-node hexahedron, `VTK_HEXAHEDRON` = 12.
    Hex8,
    /// 4-node tetrahedron, `VTK_TETRA` = 10.
    Tet4,
    /// 10-node tetrahedron, `VTK_QUADRATIC_TETRA` = 24 (mid-edge nodes of 0–1, 1–2, 2–0, 0–3,
    /// 1–3, 2–3).
    Tet10,
    /// 4-node quadrilateral, `VTK_QUAD` = 9.
    Quad4,
    /// 8-node quadrilateral, `VTK_QUADRATIC_QUAD` = 23 (corners, then the mid-side nodes).
    Quad8,
    /// 9-node quadrilateral, `VTK_BIQUADRATIC_QUAD` = 28 (Quad8's nodes and the centre).
    Quad9,
    /// 3-node triangle, `VTK_TRIANGLE` = 5.
    Tri3,
    /// 6-node triangle, `VTK_QUADRATIC_TRIANGLE` = 22 (corners, then the mid-edge nodes).
    Tri6,
    /// 6-node wedge, `VTK_WEDGE` = 13 (the revolved view of a triangle).
    Wedge6,
}

impl From<crate::mesh::ElementKind> for CellType {
    fn from(kind: crate::mesh::ElementKind) -> Self {
        use crate::mesh::{ElementKind as E, MeridianKind as M};
        match kind {
            E::Hex8 => CellType::Hex8,
            E::Tet4 => CellType::Tet4,
            E::Tet10 => CellType::Tet10,
            E::Meridian(M::Quad4) => CellType::Quad4,
            E::Meridian(M::Quad8) => CellType::Quad8,
            E::Meridian(M::Quad9) => CellType::Quad9,
            E::Meridian(M::Tri3) => CellType::Tri3,
            E::Meridian(M::Tri6) => CellType::Tri6,
        }
    }
}

impl CellType {
    /// The VTK cell type id.
    pub fn vtk_id(self) -> u8 {
        match self {
            CellType::Hex8 => 12,
            CellType::Tet4 => 10,
            CellType::Tet10 => 24,
            CellType::Quad4 => 9,
            CellType::Quad8 => 23,
            CellType::Quad9 => 28,
            CellType::Tri3 => 5,
            CellType::Tri6 => 22,
            CellType::Wedge6 => 13,
        }
    }

    /// Number of nodes of one cell.
    pub fn nodes_per_cell(self) -> usize {
        match self {
            CellType::Hex8 => 8,
            CellType::Tet4 => 4,
            CellType::Tet10 => 10,
            CellType::Quad4 => 4,
            CellType::Quad8 => 8,
            CellType::Quad9 => 9,
            CellType::Tri3 => 3,
            CellType::Tri6 => 6,
            CellType::Wedge6 => 6,
        }
    }
}

/// A named array attached to points or cells: `values.len() == components × count`, stored
/// tuple by tuple (all components of entity 0, then entity 1, ...).
#[derive(Debug, Clone, Copy)]
pub struct DataArray<'a> {
    pub name: &'a str,
    pub components: usize,
    pub values: &'a [f64],
}

/// One unstructured-grid piece with a single cell type.
#[derive(Debug, Clone)]
pub struct VtuPiece<'a> {
    /// Node coordinates in m.
    pub points: &'a [[f64; 3]],
    pub cell_type: CellType,
    /// Node indices, `nodes_per_cell × cells`, flattened cell by cell.
    pub connectivity: &'a [usize],
    pub point_data: Vec<DataArray<'a>>,
    pub cell_data: Vec<DataArray<'a>>,
}

/// What [`read_vtu`] returns. Data arrays map name → (components, values).
#[derive(Debug, Clone, PartialEq)]
pub struct VtuData {
    pub points: Vec<[f64; 3]>,
    pub connectivity: Vec<usize>,
    pub offsets: Vec<usize>,
    pub types: Vec<u8>,
    pub point_data: BTreeMap<String, (usize, Vec<f64>)>,
    pub cell_data: BTreeMap<String, (usize, Vec<f64>)>,
}

/// Errors of the VTU/PVD writer and reader. Every message starts with the file path.
#[derive(Debug, thiserror::Error)]
pub enum VtuError {
    #[error("{}: I/O error: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error(
        "{}: data array '{name}' has {len} values, expected {expected} \
         ({components} components × {count} {entity})",
        .path.display()
    )]
    LengthMismatch {
        path: PathBuf,
        name: String,
        len: usize,
        expected: usize,
        components: usize,
        count: usize,
        entity: &'static str,
    },
    #[error(
        "{}: data array '{name}' has a non-finite value ({value}) at index {index}; \
         ParaView cannot read it",
        .path.display()
    )]
    NonFinite {
        path: PathBuf,
        name: String,
        index: usize,
        value: f64,
    },
    #[error("{}: invalid data array '{name}': {reason}", .path.display())]
    InvalidArray {
        path: PathBuf,
        name: String,
        reason: String,
    },
    #[error("{}: invalid mesh: {reason}", .path.display())]
    InvalidMesh { path: PathBuf, reason: String },
    #[error("{}: invalid collection entry {index}: {reason}", .path.display())]
    InvalidPvdEntry {
        path: PathBuf,
        index: usize,
        reason: String,
    },
    #[error("{}: malformed VTU file: {reason}", .path.display())]
    Parse { path: PathBuf, reason: String },
}

// ---------------------------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------------------------

/// Writes `piece` as a VTK XML UnstructuredGrid file (atomically).
///
/// Everything is validated before the file is touched: connectivity length and node indices,
/// array lengths (`values.len() == components × count`), array names (non-empty, unique within
/// point data and within cell data) and finiteness of every value (NaN/∞ are rejected with the
/// array name and the flat index, because ParaView cannot parse them).
pub fn write_vtu(path: &Path, piece: &VtuPiece) -> Result<(), VtuError> {
    write_vtu_as(path, piece, Encoding::Binary)
}

/// How the arrays of a `.vtu` file are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Encoding {
    /// Base64 of the little-endian values after a UInt64 byte count (VTK's `binary` format).
    #[default]
    Binary,
    /// Values as text, one tuple per line.
    Ascii,
    /// zlib-compressed blocks (VTK's `compressor="vtkZLibDataCompressor"`).
    Compressed,
}

/// Uncompressed size of the blocks of a compressed array (bytes), as VTK writes them.
const BLOCK: usize = 32 * 1024;

/// [`write_vtu`] with the arrays in `encoding`.
pub fn write_vtu_as(path: &Path, piece: &VtuPiece, encoding: Encoding) -> Result<(), VtuError> {
    validate_piece(path, piece)?;
    write_atomic_with(path, |w| write_piece(w, piece, encoding)).map_err(|source| VtuError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// One binary DataArray body on one line: base64 of the byte count (UInt64) and the bytes, or
/// with `compress` VTK's zlib blocks: base64 of the header [number of blocks, block size, size of
/// the last block, compressed size of each block] (UInt64) and base64 of the compressed blocks.
fn write_binary(w: &mut dyn Write, bytes: &[u8], compress: bool) -> io::Result<()> {
    use base64::Engine as _;
    if compress {
        let engine = &base64::engine::general_purpose::STANDARD;
        let blocks: Vec<&[u8]> = bytes.chunks(BLOCK).collect();
        let mut header: Vec<u64> = vec![
            blocks.len() as u64,
            BLOCK as u64,
            blocks.last().map_or(0, |b| b.len()) as u64,
        ];
        let mut data = Vec::new();
        for b in &blocks {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(b)?;
            let c = z.finish()?;
            header.push(c.len() as u64);
            data.extend_from_slice(&c);
        }
        let head: Vec<u8> = header.iter().flat_map(|v| v.to_le_bytes()).collect();
        return writeln!(
            w,
            "          {}{}",
            engine.encode(head),
            engine.encode(data)
        );
    }
    let mut raw = Vec::with_capacity(8 + bytes.len());
    raw.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
    raw.extend_from_slice(bytes);
    writeln!(
        w,
        "          {}",
        base64::engine::general_purpose::STANDARD.encode(raw)
    )
}

/// Writes a ParaView collection file listing `(time, file)` entries, where `file` is relative
/// to the directory of the `.pvd` file. Times are in s and must be finite.
pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> Result<(), VtuError> {
    for (index, (time, file)) in entries.iter().enumerate() {
        let reason = if !time.is_finite() {
            Some(format!("time {time} is not finite"))
        } else if file.is_empty() {
            Some("empty file name".to_string())
        } else {
            None
        };
        if let Some(reason) = reason {
            return Err(VtuError::InvalidPvdEntry {
                path: path.to_path_buf(),
                index,
                reason,
            });
        }
    }
    write_atomic_with(path, |w| {
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        writeln!(
            w,
            "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">"
        )?;
        writeln!(w, "  <Collection>")?;
        for (time, file) in entries {
            writeln!(
                w,
                "    <DataSet timestep=\"{}\" group=\"\" part=\"0\" file=\"{}\"/>",
                format_time(*time),
                xml_escape(file)
            )?;
        }
        writeln!(w, "  </Collection>")?;
        writeln!(w, "</VTKFile>")
    })
    .map_err(|source| VtuError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes a parallel unstructured-grid index (`.pvtu`, VTK's `PUnstructuredGrid`) over the
/// `.vtu` files `pieces` (names relative to the index's directory), which all hold the
/// `Float64` point arrays `point_data` and cell arrays `cell_data` (name, components). ParaView
/// reads the pieces as one data set.
pub fn write_pvtu(
    path: &Path,
    pieces: &[String],
    point_data: &[(&str, usize)],
    cell_data: &[(&str, usize)],
) -> Result<(), VtuError> {
    if let Some(index) = pieces.iter().position(|p| p.is_empty()) {
        return Err(VtuError::InvalidPvdEntry {
            path: path.to_path_buf(),
            index,
            reason: "empty piece file name".into(),
        });
    }
    let arrays = |w: &mut dyn Write, tag: &str, list: &[(&str, usize)]| -> io::Result<()> {
        writeln!(w, "    <{tag}>")?;
        for (name, components) in list {
            writeln!(
                w,
                "      <PDataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{components}\"/>",
                xml_escape(name)
            )?;
        }
        writeln!(w, "    </{tag}>")
    };
    write_atomic_with(path, |w| {
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        writeln!(
            w,
            "<VTKFile type=\"PUnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\" header_type=\"UInt64\">"
        )?;
        writeln!(w, "  <PUnstructuredGrid GhostLevel=\"0\">")?;
        arrays(w, "PPointData", point_data)?;
        arrays(w, "PCellData", cell_data)?;
        writeln!(w, "    <PPoints>")?;
        writeln!(
            w,
            "      <PDataArray type=\"Float64\" NumberOfComponents=\"3\"/>"
        )?;
        writeln!(w, "    </PPoints>")?;
        for p in pieces {
            writeln!(w, "    <Piece Source=\"{}\"/>", xml_escape(p))?;
        }
        writeln!(w, "  </PUnstructuredGrid>")?;
        writeln!(w, "</VTKFile>")
    })
    .map_err(|source| VtuError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Shortest round-trip representation; plain decimal for ordinary magnitudes, exponent form
/// otherwise (Rust's `Display` never uses an exponent, which is unreadable for 1e-9).
fn format_time(t: f64) -> String {
    let a = t.abs();
    if a == 0.0 || (1e-4..1e15).contains(&a) {
        format!("{t}")
    } else {
        format!("{t:e}")
    }
}

fn validate_piece(path: &Path, piece: &VtuPiece) -> Result<(), VtuError> {
    let n_points = piece.points.len();
    let npc = piece.cell_type.nodes_per_cell();
    let mesh_err = |reason: String| VtuError::InvalidMesh {
        path: path.to_path_buf(),
        reason,
    };
    if !piece.connectivity.len().is_multiple_of(npc) {
        return Err(mesh_err(format!(
            "connectivity has {} entries, not a multiple of {} nodes per {:?} cell",
            piece.connectivity.len(),
            npc,
            piece.cell_type
        )));
    }
    let n_cells = piece.connectivity.len() / npc;
    if let Some((i, &node)) = piece
        .connectivity
        .iter()
        .enumerate()
        .find(|(_, &node)| node >= n_points)
    {
        return Err(mesh_err(format!(
            "connectivity entry {i} (cell {}) refers to node {node}, but there are only \
             {n_points} points",
            i / npc
        )));
    }
    if let Some(index) = piece.points.iter().flatten().position(|v| !v.is_finite()) {
        return Err(VtuError::NonFinite {
            path: path.to_path_buf(),
            name: "Points".to_string(),
            index,
            value: piece.points[index / 3][index % 3],
        });
    }
    validate_arrays(path, &piece.point_data, n_points, "points")?;
    validate_arrays(path, &piece.cell_data, n_cells, "cells")?;
    Ok(())
}

fn validate_arrays(
    path: &Path,
    arrays: &[DataArray],
    count: usize,
    entity: &'static str,
) -> Result<(), VtuError> {
    for (k, a) in arrays.iter().enumerate() {
        let invalid = |reason: String| VtuError::InvalidArray {
            path: path.to_path_buf(),
            name: a.name.to_string(),
            reason,
        };
        if a.name.is_empty() {
            return Err(invalid(format!(
                "empty name (array {k} of the {entity} data)"
            )));
        }
        if arrays[..k].iter().any(|b| b.name == a.name) {
            return Err(invalid(format!("duplicate name in the {entity} data")));
        }
        if a.components == 0 {
            return Err(invalid("zero components".to_string()));
        }
        let expected = a.components.checked_mul(count);
        if expected != Some(a.values.len()) {
            return Err(VtuError::LengthMismatch {
                path: path.to_path_buf(),
                name: a.name.to_string(),
                len: a.values.len(),
                expected: expected.unwrap_or(usize::MAX),
                components: a.components,
                count,
                entity,
            });
        }
        if let Some(index) = a.values.iter().position(|v| !v.is_finite()) {
            return Err(VtuError::NonFinite {
                path: path.to_path_buf(),
                name: a.name.to_string(),
                index,
                value: a.values[index],
            });
        }
    }
    Ok(())
}

fn write_piece(w: &mut dyn Write, piece: &VtuPiece, encoding: Encoding) -> io::Result<()> {
    let npc = piece.cell_type.nodes_per_cell();
    let n_cells = piece.connectivity.len() / npc;
    let binary = encoding != Encoding::Ascii;
    writeln!(w, "<?xml version=\"1.0\"?>")?;
    writeln!(
        w,
        "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\"{}>",
        match encoding {
            Encoding::Binary => " header_type=\"UInt64\"",
            Encoding::Compressed => " header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\"",
            Encoding::Ascii => "",
        }
    )?;
    writeln!(w, "  <UnstructuredGrid>")?;
    writeln!(
        w,
        "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
        piece.points.len(),
        n_cells
    )?;

    writeln!(w, "      <PointData>")?;
    for a in &piece.point_data {
        write_f64_array(w, Some(a.name), a.components, a.values, encoding)?;
    }
    writeln!(w, "      </PointData>")?;
    writeln!(w, "      <CellData>")?;
    for a in &piece.cell_data {
        write_f64_array(w, Some(a.name), a.components, a.values, encoding)?;
    }
    writeln!(w, "      </CellData>")?;

    writeln!(w, "      <Points>")?;
    write_f64_array(w, None, 3, piece.points.as_flattened(), encoding)?;
    writeln!(w, "      </Points>")?;

    writeln!(w, "      <Cells>")?;
    if binary {
        let ints = |v: &mut dyn Iterator<Item = usize>| -> Vec<u8> {
            v.flat_map(|x| (x as i64).to_le_bytes()).collect()
        };
        writeln!(
            w,
            "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"binary\">"
        )?;
        let z = encoding == Encoding::Compressed;
        write_binary(w, &ints(&mut piece.connectivity.iter().copied()), z)?;
        writeln!(w, "        </DataArray>")?;
        writeln!(
            w,
            "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"binary\">"
        )?;
        write_binary(w, &ints(&mut (1..=n_cells).map(|c| c * npc)), z)?;
        writeln!(w, "        </DataArray>")?;
        writeln!(
            w,
            "        <DataArray type=\"UInt8\" Name=\"types\" format=\"binary\">"
        )?;
        write_binary(w, &vec![piece.cell_type.vtk_id(); n_cells], z)?;
        writeln!(w, "        </DataArray>")?;
        writeln!(w, "      </Cells>")?;
        writeln!(w, "    </Piece>")?;
        writeln!(w, "  </UnstructuredGrid>")?;
        return writeln!(w, "</VTKFile>");
    }
    writeln!(
        w,
        "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">"
    )?;
    for cell in piece.connectivity.chunks(npc) {
        write_row(w, cell)?;
    }
    writeln!(w, "        </DataArray>")?;
    writeln!(
        w,
        "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">"
    )?;
    let mut first = 1;
    while first <= n_cells {
        let last = (first + 7).min(n_cells);
        let row: Vec<usize> = (first..=last).map(|c| c * npc).collect();
        write_row(w, &row)?;
        first = last + 1;
    }
    writeln!(w, "        </DataArray>")?;
    writeln!(
        w,
        "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">"
    )?;
    let row = [piece.cell_type.vtk_id(); 16];
    let mut remaining = n_cells;
    while remaining > 0 {
        let k = remaining.min(row.len());
        write_row(w, &row[..k])?;
        remaining -= k;
    }
    writeln!(w, "        </DataArray>")?;
    writeln!(w, "      </Cells>")?;

    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </UnstructuredGrid>")?;
    writeln!(w, "</VTKFile>")
}

/// One `Float64` DataArray: binary, or one tuple per line (scalars six per line).
fn write_f64_array(
    w: &mut dyn Write,
    name: Option<&str>,
    components: usize,
    values: &[f64],
    encoding: Encoding,
) -> io::Result<()> {
    write!(w, "        <DataArray type=\"Float64\"")?;
    if let Some(name) = name {
        write!(w, " Name=\"{}\"", xml_escape(name))?;
    }
    if encoding != Encoding::Ascii {
        writeln!(w, " NumberOfComponents=\"{components}\" format=\"binary\">")?;
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        write_binary(w, &bytes, encoding == Encoding::Compressed)?;
        return writeln!(w, "        </DataArray>");
    }
    writeln!(w, " NumberOfComponents=\"{components}\" format=\"ascii\">")?;
    let per_line = if components == 1 { 6 } else { components };
    for row in values.chunks(per_line) {
        write!(w, "         ")?;
        for v in row {
            // `{:e}` is Rust's shortest round-trip representation, e.g. `-2.5e-7`.
            write!(w, " {v:e}")?;
        }
        writeln!(w)?;
    }
    writeln!(w, "        </DataArray>")
}

fn write_row<T: std::fmt::Display>(w: &mut dyn Write, items: &[T]) -> io::Result<()> {
    write!(w, "         ")?;
    for item in items {
        write!(w, " {item}")?;
    }
    writeln!(w)
}

fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            _ => out.push(c),
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Reader
// ---------------------------------------------------------------------------------------------

/// Reads a `.vtu` file of the kind [`write_vtu`] writes (one piece, ascii arrays).
///
/// Malformed or truncated input gives [`VtuError::Parse`]; the reader never panics.
pub fn read_vtu(path: &Path) -> Result<VtuData, VtuError> {
    let text = std::fs::read_to_string(path).map_err(|source| VtuError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_vtu(&text).map_err(|reason| VtuError::Parse {
        path: path.to_path_buf(),
        reason,
    })
}

/// Reads a `.pvtu` index as [`write_pvtu`] writes it and every piece it lists (with
/// [`read_vtu`], paths relative to the index's directory), in the index's order.
pub fn read_pvtu(path: &Path) -> Result<Vec<VtuData>, VtuError> {
    let parse = |reason: String| VtuError::Parse {
        path: path.to_path_buf(),
        reason,
    };
    let text = std::fs::read_to_string(path).map_err(|source| VtuError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut sc = Scanner::new(&text);
    let mut sources = Vec::new();
    let mut root = false;
    while let Some(tok) = sc.next_token().map_err(parse)? {
        if let Token::Start { name, attrs, .. } = tok {
            match name {
                "VTKFile" => {
                    let kind = attrs.iter().find(|(n, _)| *n == "type").map(|(_, v)| v);
                    if kind.map(String::as_str) != Some("PUnstructuredGrid") {
                        return Err(parse(format!(
                            "VTKFile type is {kind:?}, expected \"PUnstructuredGrid\""
                        )));
                    }
                    root = true;
                }
                "Piece" => match attrs.into_iter().find(|(n, _)| *n == "Source") {
                    Some((_, source)) => sources.push(source),
                    None => return Err(parse(sc.err("a Piece without a Source"))),
                },
                _ => {}
            }
        }
    }
    if !root || sources.is_empty() {
        return Err(parse("no PUnstructuredGrid with pieces".into()));
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    sources.iter().map(|s| read_vtu(&dir.join(s))).collect()
}

/// A start tag, end tag or text run of the XML stream.
#[derive(Debug)]
enum Token<'t> {
    Start {
        name: &'t str,
        attrs: Vec<(&'t str, String)>,
        self_closing: bool,
    },
    End {
        name: &'t str,
    },
    Text(&'t str),
}

/// Minimal XML tokenizer: elements, attributes, text; skips the prolog, comments, `<!...>`
/// declarations and processing instructions. No CDATA, no namespaces.
struct Scanner<'t> {
    text: &'t str,
    pos: usize,
}

impl<'t> Scanner<'t> {
    fn new(text: &'t str) -> Self {
        Scanner { text, pos: 0 }
    }

    fn line(&self) -> usize {
        self.text[..self.pos.min(self.text.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count()
            + 1
    }

    fn err(&self, what: &str) -> String {
        format!("line {}: {what}", self.line())
    }

    fn next_token(&mut self) -> Result<Option<Token<'t>>, String> {
        loop {
            let rest = &self.text[self.pos..];
            if rest.is_empty() {
                return Ok(None);
            }
            if !rest.starts_with('<') {
                let end = rest.find('<').unwrap_or(rest.len());
                self.pos += end;
                return Ok(Some(Token::Text(&rest[..end])));
            }
            if rest.starts_with("<?") {
                self.skip_past("?>", "unterminated processing instruction")?;
                continue;
            }
            if rest.starts_with("<!--") {
                self.skip_past("-->", "unterminated comment")?;
                continue;
            }
            if rest.starts_with("<!") {
                self.skip_past(">", "unterminated declaration")?;
                continue;
            }
            let close = rest
                .find('>')
                .ok_or_else(|| self.err("unterminated tag (file truncated?)"))?;
            let inner = &rest[1..close];
            self.pos += close + 1;
            if let Some(name) = inner.strip_prefix('/') {
                let name = name.trim();
                if name.is_empty() || !name.chars().all(is_name_char) {
                    return Err(self.err(&format!("invalid end tag '</{name}>'")));
                }
                return Ok(Some(Token::End { name }));
            }
            let (inner, self_closing) = match inner.strip_suffix('/') {
                Some(s) => (s, true),
                None => (inner, false),
            };
            let name_end = inner
                .find(|c: char| !is_name_char(c))
                .unwrap_or(inner.len());
            let name = &inner[..name_end];
            if name.is_empty() {
                return Err(self.err("tag without a name"));
            }
            let attrs = parse_attributes(&inner[name_end..]).map_err(|e| self.err(&e))?;
            return Ok(Some(Token::Start {
                name,
                attrs,
                self_closing,
            }));
        }
    }

    fn skip_past(&mut self, marker: &str, what: &str) -> Result<(), String> {
        match self.text[self.pos..].find(marker) {
            Some(i) => {
                self.pos += i + marker.len();
                Ok(())
            }
            None => Err(self.err(what)),
        }
    }
}

fn is_name_char(c: char) -> bool {
    c.is_alphanumeric() || matches!(c, '_' | '-' | '.' | ':')
}

fn parse_attributes(mut s: &str) -> Result<Vec<(&str, String)>, String> {
    let mut attrs = Vec::new();
    loop {
        s = s.trim_start();
        if s.is_empty() {
            return Ok(attrs);
        }
        let name_end = s.find(|c: char| !is_name_char(c)).unwrap_or(s.len());
        if name_end == 0 {
            return Err(format!("unexpected character in tag near '{}'", preview(s)));
        }
        let name = &s[..name_end];
        s = s[name_end..].trim_start();
        s = s
            .strip_prefix('=')
            .ok_or_else(|| format!("attribute '{name}' without a value"))?
            .trim_start();
        let quote = match s.chars().next() {
            Some(q @ ('"' | '\'')) => q,
            _ => return Err(format!("attribute '{name}' value is not quoted")),
        };
        s = &s[1..];
        let end = s
            .find(quote)
            .ok_or_else(|| format!("attribute '{name}' value is not terminated"))?;
        let value = xml_unescape(&s[..end])?;
        if attrs.iter().any(|(n, _)| *n == name) {
            return Err(format!("duplicate attribute '{name}'"));
        }
        attrs.push((name, value));
        s = &s[end + 1..];
    }
}

fn preview(s: &str) -> String {
    s.chars().take(20).collect()
}

fn xml_unescape(s: &str) -> Result<String, String> {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(amp) = rest.find('&') {
        out.push_str(&rest[..amp]);
        rest = &rest[amp + 1..];
        let semi = rest
            .find(';')
            .ok_or_else(|| "unterminated character reference".to_string())?;
        let entity = &rest[..semi];
        let c = match entity {
            "amp" => '&',
            "lt" => '<',
            "gt" => '>',
            "quot" => '"',
            "apos" => '\'',
            _ => {
                let code = if let Some(hex) = entity
                    .strip_prefix("#x")
                    .or_else(|| entity.strip_prefix("#X"))
                {
                    u32::from_str_radix(hex, 16).ok()
                } else if let Some(dec) = entity.strip_prefix('#') {
                    dec.parse::<u32>().ok()
                } else {
                    None
                };
                code.and_then(char::from_u32)
                    .ok_or_else(|| format!("unknown character reference '&{entity};'"))?
            }
        };
        out.push(c);
        rest = &rest[semi + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

fn attr<'a>(attrs: &'a [(&str, String)], name: &str) -> Option<&'a str> {
    attrs
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, v)| v.as_str())
}

/// A DataArray as read: attributes and raw text.
struct RawArray {
    name: Option<String>,
    ty: String,
    components: usize,
    text: String,
    line: usize,
    /// `format="binary"`, with the byte count's width in bytes (4 or 8, from `header_type`).
    binary: Option<usize>,
    /// The file's arrays are zlib blocks (`compressor="vtkZLibDataCompressor"`).
    compressed: bool,
}

impl RawArray {
    /// The bytes of a compressed array: the header's blocks inflated and joined. The sizes must
    /// agree with one another and with the decompressed data (no allocation beyond what the
    /// header's block size allows per block).
    fn inflate(&self, header: usize, compact: &str) -> Result<Vec<u8>, String> {
        use base64::Engine as _;
        let engine = &base64::engine::general_purpose::STANDARD;
        let bad = |what: &str| format!("line {}: array '{}': {what}", self.line, self.label());
        let b64_len = |bytes: usize| bytes.div_ceil(3) * 4;
        let word = |b: &[u8], i: usize| -> u64 {
            let mut v = [0u8; 8];
            v[..header].copy_from_slice(&b[i * header..(i + 1) * header]);
            u64::from_le_bytes(v)
        };
        let first = compact
            .get(..b64_len(3 * header))
            .ok_or_else(|| bad("truncated compression header"))?;
        let head = engine
            .decode(first)
            .map_err(|e| bad(&format!("bad base64: {e}")))?;
        let blocks = word(&head, 0) as usize;
        let (block, last) = (word(&head, 1) as usize, word(&head, 2) as usize);
        if blocks > compact.len() || block > 1 << 30 || last > block {
            return Err(bad("inconsistent compression header"));
        }
        let head_len = b64_len((3 + blocks) * header);
        let head = engine
            .decode(
                compact
                    .get(..head_len)
                    .ok_or_else(|| bad("truncated compression header"))?,
            )
            .map_err(|e| bad(&format!("bad base64: {e}")))?;
        let data = engine
            .decode(&compact[head_len..])
            .map_err(|e| bad(&format!("bad base64: {e}")))?;
        let mut out = Vec::new();
        let mut at = 0usize;
        for k in 0..blocks {
            let size = word(&head, 3 + k) as usize;
            let chunk = data
                .get(at..at.saturating_add(size))
                .ok_or_else(|| bad("truncated compressed data"))?;
            at += size;
            let expected = if k + 1 == blocks && last != 0 {
                last
            } else {
                block
            };
            let mut inflated = Vec::with_capacity(expected.min(BLOCK.max(1) * 64));
            use std::io::Read as _;
            flate2::read::ZlibDecoder::new(chunk)
                .take(expected as u64 + 1)
                .read_to_end(&mut inflated)
                .map_err(|e| bad(&format!("bad zlib data: {e}")))?;
            if inflated.len() != expected {
                return Err(bad("a compressed block has the wrong size"));
            }
            out.extend_from_slice(&inflated);
        }
        if at != data.len() {
            return Err(bad("compressed data longer than its header says"));
        }
        Ok(out)
    }

    /// The values of a binary array (Float64, Int64 or UInt8) as f64.
    fn binary_values(&self, header: usize) -> Result<Vec<f64>, String> {
        use base64::Engine as _;
        let compact: String = self.text.split_ascii_whitespace().collect();
        let short = || {
            format!(
                "line {}: array '{}': truncated binary data",
                self.line,
                self.label()
            )
        };
        let inflated;
        let bytes;
        let data = if self.compressed {
            inflated = self.inflate(header, &compact)?;
            &inflated[..]
        } else {
            bytes = base64::engine::general_purpose::STANDARD
                .decode(compact.as_bytes())
                .map_err(|e| {
                    format!(
                        "line {}: array '{}': bad base64: {e}",
                        self.line,
                        self.label()
                    )
                })?;
            if bytes.len() < header {
                return Err(short());
            }
            let mut count = [0u8; 8];
            count[..header].copy_from_slice(&bytes[..header]);
            let count = u64::from_le_bytes(count) as usize;
            bytes
                .get(header..header.saturating_add(count))
                .ok_or_else(short)?
        };
        let count = data.len();
        let width = match self.ty.as_str() {
            "Float64" | "Int64" => 8,
            "UInt8" => 1,
            other => {
                return Err(format!(
                    "line {}: unsupported binary DataArray type '{other}'",
                    self.line
                ))
            }
        };
        if !count.is_multiple_of(width) {
            return Err(short());
        }
        Ok(data
            .chunks(width)
            .map(|c| match self.ty.as_str() {
                "Float64" => f64::from_le_bytes(c.try_into().unwrap_or([0; 8])),
                "Int64" => i64::from_le_bytes(c.try_into().unwrap_or([0; 8])) as f64,
                _ => c[0] as f64,
            })
            .collect())
    }

    fn f64_values(&self) -> Result<Vec<f64>, String> {
        if let Some(header) = self.binary {
            return self.binary_values(header);
        }
        if !matches!(
            self.ty.as_str(),
            "Float64"
                | "Float32"
                | "Int8"
                | "Int16"
                | "Int32"
                | "Int64"
                | "UInt8"
                | "UInt16"
                | "UInt32"
                | "UInt64"
        ) {
            return Err(format!(
                "line {}: unsupported DataArray type '{}'",
                self.line, self.ty
            ));
        }
        self.text
            .split_ascii_whitespace()
            .map(|tok| {
                tok.parse::<f64>().map_err(|_| {
                    format!(
                        "line {}: array '{}': invalid number '{}'",
                        self.line,
                        self.label(),
                        preview(tok)
                    )
                })
            })
            .collect()
    }

    fn usize_values(&self) -> Result<Vec<usize>, String> {
        if let Some(header) = self.binary {
            return self
                .binary_values(header)?
                .into_iter()
                .map(|v| {
                    if v >= 0.0 && v.fract() == 0.0 {
                        Ok(v as usize)
                    } else {
                        Err(format!(
                            "line {}: array '{}': invalid non-negative integer {v}",
                            self.line,
                            self.label()
                        ))
                    }
                })
                .collect();
        }
        self.text
            .split_ascii_whitespace()
            .map(|tok| {
                tok.parse::<usize>().map_err(|_| {
                    format!(
                        "line {}: array '{}': invalid non-negative integer '{}'",
                        self.line,
                        self.label(),
                        preview(tok)
                    )
                })
            })
            .collect()
    }

    fn label(&self) -> &str {
        self.name.as_deref().unwrap_or("(unnamed)")
    }
}

#[derive(Default)]
struct PieceRaw {
    n_points: usize,
    n_cells: usize,
    point_data: Vec<RawArray>,
    cell_data: Vec<RawArray>,
    points: Option<RawArray>,
    cells: Vec<RawArray>,
}

fn parse_count(attrs: &[(&str, String)], name: &str, line: usize) -> Result<usize, String> {
    let v = attr(attrs, name).ok_or_else(|| format!("line {line}: Piece without {name}"))?;
    v.trim()
        .parse::<usize>()
        .map_err(|_| format!("line {line}: invalid {name} '{}'", preview(v)))
}

fn parse_vtu(text: &str) -> Result<VtuData, String> {
    let mut sc = Scanner::new(text);
    // width of the byte count before each binary array (VTKFile `header_type`)
    let mut header_bytes = 4;
    let mut compressed = false;
    let mut stack: Vec<&str> = Vec::new();
    let mut seen_root = false;
    let mut root_closed = false;
    let mut piece: Option<PieceRaw> = None;
    let mut current: Option<RawArray> = None;

    while let Some(tok) = sc.next_token()? {
        match tok {
            Token::Text(t) => {
                if let Some(arr) = current.as_mut() {
                    arr.text.push_str(t);
                } else if !t.trim().is_empty() {
                    return Err(sc.err(&format!("unexpected text '{}'", preview(t.trim()))));
                }
            }
            Token::Start {
                name,
                attrs,
                self_closing,
            } => {
                let line = sc.line();
                if root_closed {
                    return Err(sc.err("content after the root element"));
                }
                if current.is_some() {
                    return Err(sc.err("element inside a DataArray"));
                }
                let parent = stack.last().copied();
                match (parent, name) {
                    (None, "VTKFile") => {
                        if seen_root {
                            return Err(sc.err("second VTKFile element"));
                        }
                        seen_root = true;
                        if attr(&attrs, "type") != Some("UnstructuredGrid") {
                            return Err(sc.err("VTKFile type is not UnstructuredGrid"));
                        }
                        if let Some(bo) = attr(&attrs, "byte_order") {
                            if bo != "LittleEndian" {
                                return Err(sc.err(&format!("unsupported byte_order '{bo}'")));
                            }
                        }
                        compressed = match attr(&attrs, "compressor") {
                            None => false,
                            Some("vtkZLibDataCompressor") => true,
                            Some(other) => {
                                return Err(
                                    sc.err(&format!("unsupported compressor '{}'", preview(other)))
                                )
                            }
                        };
                        header_bytes = match attr(&attrs, "header_type").unwrap_or("UInt32") {
                            "UInt32" => 4,
                            "UInt64" => 8,
                            other => {
                                return Err(sc.err(&format!("unsupported header_type '{other}'")))
                            }
                        };
                    }
                    (None, other) => {
                        return Err(sc.err(&format!("root element is '{other}', not VTKFile")))
                    }
                    (Some("VTKFile"), "UnstructuredGrid") => {}
                    (Some("UnstructuredGrid"), "Piece") => {
                        if piece.is_some() {
                            return Err(sc.err("more than one Piece is not supported"));
                        }
                        piece = Some(PieceRaw {
                            n_points: parse_count(&attrs, "NumberOfPoints", line)?,
                            n_cells: parse_count(&attrs, "NumberOfCells", line)?,
                            ..PieceRaw::default()
                        });
                    }
                    (Some("Piece"), "PointData" | "CellData" | "Points" | "Cells") => {}
                    (Some("PointData" | "CellData" | "Points" | "Cells"), "DataArray") => {
                        let components = match attr(&attrs, "NumberOfComponents") {
                            None => 1,
                            Some(v) => v
                                .trim()
                                .parse::<usize>()
                                .ok()
                                .filter(|&c| c > 0)
                                .ok_or_else(|| {
                                    sc.err(&format!("invalid NumberOfComponents '{}'", preview(v)))
                                })?,
                        };
                        let ty = attr(&attrs, "type")
                            .ok_or_else(|| sc.err("DataArray without type"))?
                            .to_string();
                        let binary = match attr(&attrs, "format").unwrap_or("ascii") {
                            "ascii" => None,
                            "binary" => Some(header_bytes),
                            other => {
                                return Err(
                                    sc.err(&format!("unsupported DataArray format '{other}'"))
                                )
                            }
                        };
                        let arr = RawArray {
                            name: attr(&attrs, "Name").map(str::to_string),
                            ty,
                            components,
                            text: String::new(),
                            line,
                            binary,
                            compressed,
                        };
                        if self_closing {
                            store_array(&mut piece, parent, arr, line)?;
                        } else {
                            current = Some(arr);
                        }
                    }
                    (p, other) => {
                        return Err(sc.err(&format!(
                            "unexpected element '{other}' inside '{}'",
                            p.unwrap_or("")
                        )))
                    }
                }
                if !self_closing {
                    stack.push(name);
                } else if name == "VTKFile" {
                    root_closed = true;
                }
            }
            Token::End { name } => {
                let line = sc.line();
                match stack.pop() {
                    Some(open) if open == name => {}
                    Some(open) => {
                        return Err(sc.err(&format!(
                            "end tag '</{name}>' does not match open element '{open}'"
                        )))
                    }
                    None => return Err(sc.err(&format!("unexpected end tag '</{name}>'"))),
                }
                if name == "DataArray" {
                    if let Some(arr) = current.take() {
                        store_array(&mut piece, stack.last().copied(), arr, line)?;
                    }
                }
                if stack.is_empty() {
                    root_closed = true;
                }
            }
        }
    }
    if !root_closed {
        return Err(match stack.last() {
            Some(open) => format!("unexpected end of file inside '{open}' (file truncated?)"),
            None => "no VTKFile element".to_string(),
        });
    }
    let piece = piece.ok_or_else(|| "no Piece element".to_string())?;
    assemble(piece)
}

fn store_array(
    piece: &mut Option<PieceRaw>,
    parent: Option<&str>,
    arr: RawArray,
    line: usize,
) -> Result<(), String> {
    let piece = piece
        .as_mut()
        .ok_or_else(|| format!("line {line}: DataArray outside a Piece"))?;
    match parent {
        Some("PointData") => piece.point_data.push(arr),
        Some("CellData") => piece.cell_data.push(arr),
        Some("Points") => {
            if piece.points.is_some() {
                return Err(format!("line {line}: more than one Points array"));
            }
            piece.points = Some(arr);
        }
        Some("Cells") => piece.cells.push(arr),
        _ => return Err(format!("line {line}: DataArray in an unexpected place")),
    }
    Ok(())
}

fn assemble(piece: PieceRaw) -> Result<VtuData, String> {
    let PieceRaw {
        n_points,
        n_cells,
        point_data,
        cell_data,
        points,
        cells,
    } = piece;

    let points_arr = points.ok_or_else(|| "no Points array".to_string())?;
    if points_arr.components != 3 {
        return Err(format!(
            "Points array has {} components, expected 3",
            points_arr.components
        ));
    }
    let flat = points_arr.f64_values()?;
    check_len("Points", flat.len(), 3, n_points)?;
    let points: Vec<[f64; 3]> = flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();

    let find_cells = |name: &str| {
        cells
            .iter()
            .find(|a| a.name.as_deref() == Some(name))
            .ok_or_else(|| format!("Cells has no '{name}' array"))
    };
    let connectivity = find_cells("connectivity")?.usize_values()?;
    let offsets = find_cells("offsets")?.usize_values()?;
    let types_raw = find_cells("types")?.usize_values()?;
    check_len("offsets", offsets.len(), 1, n_cells)?;
    check_len("types", types_raw.len(), 1, n_cells)?;
    let types = types_raw
        .iter()
        .map(|&t| u8::try_from(t).map_err(|_| format!("cell type {t} does not fit in UInt8")))
        .collect::<Result<Vec<u8>, String>>()?;
    let mut prev = 0;
    for (i, &o) in offsets.iter().enumerate() {
        if o < prev {
            return Err(format!("offsets decrease at cell {i}"));
        }
        prev = o;
    }
    if prev != connectivity.len() {
        return Err(format!(
            "last offset is {prev} but connectivity has {} entries",
            connectivity.len()
        ));
    }
    if let Some(&bad) = connectivity.iter().find(|&&n| n >= n_points) {
        return Err(format!(
            "connectivity refers to node {bad}, but there are only {n_points} points"
        ));
    }

    let collect = |arrays: Vec<RawArray>, count: usize, what: &str| {
        let mut map = BTreeMap::new();
        for (k, a) in arrays.into_iter().enumerate() {
            let name = a
                .name
                .clone()
                .ok_or_else(|| format!("{what} array {k} has no Name"))?;
            let values = a.f64_values()?;
            check_len(&name, values.len(), a.components, count)?;
            if map.insert(name.clone(), (a.components, values)).is_some() {
                return Err(format!("duplicate {what} array '{name}'"));
            }
        }
        Ok::<_, String>(map)
    };
    let point_data = collect(point_data, n_points, "point data")?;
    let cell_data = collect(cell_data, n_cells, "cell data")?;

    Ok(VtuData {
        points,
        connectivity,
        offsets,
        types,
        point_data,
        cell_data,
    })
}

fn check_len(name: &str, len: usize, components: usize, count: usize) -> Result<(), String> {
    match components.checked_mul(count) {
        Some(expected) if expected == len => Ok(()),
        _ => Err(format!(
            "array '{name}' has {len} values, expected {components} × {count}"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;
    use std::sync::atomic::{AtomicU64, Ordering};

    static COUNTER: AtomicU64 = AtomicU64::new(0);

    fn scratch_dir(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "deasim-vtu-{}-{}-{}",
            tag,
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("create scratch dir");
        dir
    }

    /// Two unit hexes side by side along x (12 nodes), VTK node order.
    fn two_hex_mesh() -> (Vec<[f64; 3]>, Vec<usize>) {
        let mut points = Vec::new();
        for k in 0..2 {
            for j in 0..2 {
                for i in 0..3 {
                    points.push([i as f64 * 1e-3, j as f64 * 1e-3, k as f64 * 2.5e-4]);
                }
            }
        }
        let id = |i: usize, j: usize, k: usize| i + 3 * j + 6 * k;
        let mut conn = Vec::new();
        for e in 0..2 {
            conn.extend_from_slice(&[
                id(e, 0, 0),
                id(e + 1, 0, 0),
                id(e + 1, 1, 0),
                id(e, 1, 0),
                id(e, 0, 1),
                id(e + 1, 0, 1),
                id(e + 1, 1, 1),
                id(e, 1, 1),
            ]);
        }
        (points, conn)
    }

    /// A `.pvtu` index over two one-cell pieces: the reader finds both pieces, in order, with
    /// their arrays; an index of another type or without pieces is refused.
    #[test]
    fn pvtu_index_lists_its_pieces() {
        let dir = scratch_dir("pvtu");
        let (points, conn) = two_hex_mesh();
        for (r, cell) in conn.chunks(8).enumerate() {
            let phi: Vec<f64> = (0..points.len()).map(|n| (n + r) as f64).collect();
            let j = [1.0 + r as f64];
            let piece = VtuPiece {
                points: &points,
                cell_type: CellType::Hex8,
                connectivity: cell,
                point_data: vec![DataArray {
                    name: "potential",
                    components: 1,
                    values: &phi,
                }],
                cell_data: vec![DataArray {
                    name: "J",
                    components: 1,
                    values: &j,
                }],
            };
            write_vtu(&dir.join(format!("p{r}.vtu")), &piece).unwrap();
        }
        let index = dir.join("all.pvtu");
        let names = vec!["p0.vtu".to_string(), "p1.vtu".to_string()];
        write_pvtu(&index, &names, &[("potential", 1)], &[("J", 1)]).unwrap();
        let text = fs::read_to_string(&index).unwrap();
        assert!(text.contains("PUnstructuredGrid") && text.contains("Name=\"J\""));
        let pieces = read_pvtu(&index).unwrap();
        assert_eq!(pieces.len(), 2);
        for (r, p) in pieces.iter().enumerate() {
            assert_eq!(p.cell_data["J"].1, vec![1.0 + r as f64]);
            assert_eq!(p.point_data["potential"].1[0], r as f64);
        }
        assert!(write_pvtu(&index, &[String::new()], &[], &[]).is_err());
        fs::write(
            dir.join("bad.pvtu"),
            "<VTKFile type=\"UnstructuredGrid\"></VTKFile>",
        )
        .unwrap();
        let e = read_pvtu(&dir.join("bad.pvtu")).unwrap_err().to_string();
        assert!(
            e.contains("bad.pvtu") && e.contains("PUnstructuredGrid"),
            "{e}"
        );
        let _ = fs::remove_dir_all(&dir);
    }

    /// Values that stress round-tripping: irrational-ish, tiny, huge, negative zero.
    fn awkward(n: usize, seed: f64) -> Vec<f64> {
        (0..n)
            .map(|i| match i % 5 {
                0 => (seed + i as f64).sqrt() * std::f64::consts::PI,
                1 => -1.0 / (3.0 + i as f64) * 1e-9,
                2 => 1.234_567_890_123_456_7e300 * seed,
                3 => -0.0,
                _ => f64::MIN_POSITIVE * (i as f64 + seed),
            })
            .collect()
    }

    fn assert_bits_eq(a: &[f64], b: &[f64]) {
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(b) {
            assert_eq!(x.to_bits(), y.to_bits(), "{x:e} vs {y:e}");
        }
    }

    #[test]
    fn hex_mesh_round_trip_is_exact() {
        let dir = scratch_dir("hex");
        let path = dir.join("hex.vtu");
        let (points, conn) = two_hex_mesh();
        let disp = awkward(3 * points.len(), 1.0);
        let phi = awkward(points.len(), 2.0);
        let stress = awkward(9 * 2, 3.0);
        let id = [0.0, 1.0];
        let piece = VtuPiece {
            points: &points,
            cell_type: CellType::Hex8,
            connectivity: &conn,
            point_data: vec![
                DataArray {
                    name: "displacement",
                    components: 3,
                    values: &disp,
                },
                DataArray {
                    name: "potential <Φ> & \"quotes\"",
                    components: 1,
                    values: &phi,
                },
            ],
            cell_data: vec![
                DataArray {
                    name: "cauchy_stress",
                    components: 9,
                    values: &stress,
                },
                DataArray {
                    name: "element_id",
                    components: 1,
                    values: &id,
                },
            ],
        };
        write_vtu(&path, &piece).expect("write");
        let data = read_vtu(&path).expect("read");
        assert_eq!(data.points.len(), points.len());
        assert_bits_eq(data.points.as_flattened(), points.as_flattened());
        assert_eq!(data.connectivity, conn);
        assert_eq!(data.offsets, vec![8, 16]);
        assert_eq!(data.types, vec![12, 12]);
        assert_eq!(data.point_data.len(), 2);
        let (c, v) = &data.point_data["displacement"];
        assert_eq!(*c, 3);
        assert_bits_eq(v, &disp);
        let (c, v) = &data.point_data["potential <Φ> & \"quotes\""];
        assert_eq!(*c, 1);
        assert_bits_eq(v, &phi);
        let (c, v) = &data.cell_data["cauchy_stress"];
        assert_eq!(*c, 9);
        assert_bits_eq(v, &stress);
        assert_bits_eq(&data.cell_data["element_id"].1, &id);

        let text = fs::read_to_string(&path).expect("read text");
        assert!(text.contains(
            "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\" \
             header_type=\"UInt64\">"
        ));
        assert!(text.contains("format=\"binary\""));
        assert!(text.contains("<Piece NumberOfPoints=\"12\" NumberOfCells=\"2\">"));
        assert!(text.contains("Name=\"potential &lt;Φ&gt; &amp; &quot;quotes&quot;\""));
        // the same piece as ASCII reads back to the same bits
        let ascii = dir.join("hex-ascii.vtu");
        write_vtu_as(&ascii, &piece, Encoding::Ascii).expect("write ascii");
        let a = read_vtu(&ascii).expect("read ascii");
        assert_bits_eq(a.points.as_flattened(), data.points.as_flattened());
        assert_eq!(
            (a.connectivity, a.offsets, a.types),
            (data.connectivity, data.offsets, data.types)
        );
        for (name, (c, v)) in &data
            .point_data
            .iter()
            .chain(&data.cell_data)
            .collect::<BTreeMap<_, _>>()
        {
            let other = a
                .point_data
                .get(*name)
                .or(a.cell_data.get(*name))
                .expect("array");
            assert_eq!(other.0, *c);
            assert_bits_eq(&other.1, v);
        }
        let text = fs::read_to_string(&ascii).expect("read text");
        assert!(text.contains(
            "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">"
        ));
        assert!(!text.contains("nan") && !text.contains("inf"));
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    /// zlib blocks: arrays shorter than, exactly one and several blocks long read back bit for
    /// bit; a field of few distinct values compresses; the header of a one-block array is as VTK writes it.
    #[test]
    fn compressed_arrays_round_trip_and_compress() {
        use base64::Engine as _;
        let dir = scratch_dir("zlib");
        let (points, conn) = two_hex_mesh();
        // 4096 values of 8 bytes are exactly one 32 KiB block
        for n in [0usize, 5, BLOCK / 8, BLOCK / 8 + 1, 3 * BLOCK / 8 + 7] {
            // few distinct values, as in a uniform region (noise-like mantissas barely compress)
            let smooth: Vec<f64> = (0..n).map(|i| (i % 64) as f64 * 0.25).collect();
            let piece = VtuPiece {
                points: &points,
                cell_type: CellType::Hex8,
                connectivity: &conn,
                point_data: vec![],
                cell_data: vec![DataArray {
                    name: "field",
                    components: n.max(1) / 2,
                    values: &smooth,
                }],
            };
            if n % 2 == 1 || n == 0 {
                continue; // the array must have two cells' worth of tuples
            }
            let z = dir.join(format!("z{n}.vtu"));
            let b = dir.join(format!("b{n}.vtu"));
            write_vtu_as(&z, &piece, Encoding::Compressed).expect("write compressed");
            write_vtu_as(&b, &piece, Encoding::Binary).expect("write binary");
            let (dz, db) = (read_vtu(&z).expect("read z"), read_vtu(&b).expect("read b"));
            assert_bits_eq(&dz.cell_data["field"].1, &smooth);
            assert_bits_eq(dz.points.as_flattened(), db.points.as_flattened());
            assert_eq!(dz.connectivity, db.connectivity);
            let text = fs::read_to_string(&z).unwrap();
            assert!(text.contains("compressor=\"vtkZLibDataCompressor\""));
            if n >= BLOCK / 8 {
                let (sz, sb) = (
                    fs::metadata(&z).unwrap().len(),
                    fs::metadata(&b).unwrap().len(),
                );
                assert!(sz * 2 < sb, "{n}: {sz} vs {sb}");
            }
        }
        // the header of the one-block "types" array of two hex8 cells: [1, 32768, 2, c]
        let piece = VtuPiece {
            points: &points,
            cell_type: CellType::Hex8,
            connectivity: &conn,
            point_data: vec![],
            cell_data: vec![],
        };
        let z = dir.join("types.vtu");
        write_vtu_as(&z, &piece, Encoding::Compressed).unwrap();
        let text = fs::read_to_string(&z).unwrap();
        let line = text
            .lines()
            .skip_while(|l| !l.contains("Name=\"types\""))
            .nth(1)
            .unwrap()
            .trim();
        let head = base64::engine::general_purpose::STANDARD
            .decode(&line[..44])
            .unwrap();
        let word = |i: usize| u64::from_le_bytes(head[8 * i..8 * i + 8].try_into().unwrap());
        assert_eq!((word(0), word(1), word(2)), (1, BLOCK as u64, 2));
        let data = base64::engine::general_purpose::STANDARD
            .decode(&line[44..])
            .unwrap();
        assert_eq!(data.len() as u64, word(3));
        let mut out = Vec::new();
        use std::io::Read as _;
        flate2::read::ZlibDecoder::new(&data[..])
            .read_to_end(&mut out)
            .unwrap();
        assert_eq!(out, vec![12u8, 12]);
        // every truncation and a header that lies are errors, not panics
        let full = fs::read(&z).unwrap();
        let cut = dir.join("cut.vtu");
        for k in (0..full.trim_ascii_end().len()).step_by(7) {
            fs::write(&cut, &full[..k]).unwrap();
            assert!(read_vtu(&cut).is_err(), "truncation at {k} accepted");
        }
        let lying = text.replacen(
            &line[..44],
            "AQAAAAAAAAAAgAAAAAAAAAMAAAAAAAAACgAAAAAAAAA=",
            1,
        );
        fs::write(&cut, lying).unwrap();
        assert!(read_vtu(&cut).is_err());
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn tet_mesh_round_trip_is_exact() {
        let dir = scratch_dir("tet");
        let path = dir.join("tet.vtu");
        let points = vec![
            [0.0, 0.0, 0.0],
            [1e-3, 0.0, 0.0],
            [0.0, 1e-3, 0.0],
            [0.0, 0.0, 1e-3],
            [1e-3, 1e-3, 1e-3],
        ];
        let conn = vec![0, 1, 2, 3, 1, 2, 3, 4];
        let u = awkward(15, 4.0);
        let e_field = awkward(6, 5.0);
        let piece = VtuPiece {
            points: &points,
            cell_type: CellType::Tet4,
            connectivity: &conn,
            point_data: vec![DataArray {
                name: "u",
                components: 3,
                values: &u,
            }],
            cell_data: vec![DataArray {
                name: "E",
                components: 3,
                values: &e_field,
            }],
        };
        write_vtu(&path, &piece).expect("write");
        let data = read_vtu(&path).expect("read");
        assert_bits_eq(data.points.as_flattened(), points.as_flattened());
        assert_eq!(data.connectivity, conn);
        assert_eq!(data.offsets, vec![4, 8]);
        assert_eq!(data.types, vec![10, 10]);
        assert_eq!(data.point_data["u"].0, 3);
        assert_bits_eq(&data.point_data["u"].1, &u);
        assert_eq!(data.cell_data["E"].0, 3);
        assert_bits_eq(&data.cell_data["E"].1, &e_field);
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn tet10_is_vtk_quadratic_tetra() {
        let dir = scratch_dir("tet10");
        let path = dir.join("tet10.vtu");
        let c = [
            [0.0, 0.0, 0.0],
            [1e-3, 0.0, 0.0],
            [0.0, 1e-3, 0.0],
            [0.0, 0.0, 1e-3],
        ];
        let mut points = c.to_vec();
        for [i, j] in crate::fem::TET10_EDGES {
            points.push([0, 1, 2].map(|k| 0.5 * (c[i][k] + c[j][k])));
        }
        let conn: Vec<usize> = (0..10).collect();
        let piece = VtuPiece {
            points: &points,
            cell_type: CellType::Tet10,
            connectivity: &conn,
            point_data: vec![],
            cell_data: vec![],
        };
        write_vtu(&path, &piece).expect("write");
        let data = read_vtu(&path).expect("read");
        assert_eq!(data.types, vec![24]);
        assert_eq!(data.offsets, vec![10]);
        assert_eq!(data.connectivity, conn);
        assert_bits_eq(data.points.as_flattened(), points.as_flattened());
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn empty_mesh_round_trips() {
        let dir = scratch_dir("empty");
        let path = dir.join("empty.vtu");
        let piece = VtuPiece {
            points: &[],
            cell_type: CellType::Tet4,
            connectivity: &[],
            point_data: vec![],
            cell_data: vec![],
        };
        for encoding in [Encoding::Binary, Encoding::Compressed, Encoding::Ascii] {
            write_vtu_as(&path, &piece, encoding).expect("write");
            let data = read_vtu(&path).expect("read");
            assert!(data.points.is_empty() && data.connectivity.is_empty());
            assert!(data.offsets.is_empty() && data.types.is_empty());
        }
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn length_mismatch_is_an_error_naming_the_array() {
        let dir = scratch_dir("len");
        let path = dir.join("bad.vtu");
        let (points, conn) = two_hex_mesh();
        let short = vec![0.0; 3 * points.len() - 1];
        let piece = VtuPiece {
            points: &points,
            cell_type: CellType::Hex8,
            connectivity: &conn,
            point_data: vec![DataArray {
                name: "displacement",
                components: 3,
                values: &short,
            }],
            cell_data: vec![],
        };
        let err = write_vtu(&path, &piece).expect_err("must fail");
        assert!(matches!(err, VtuError::LengthMismatch { .. }), "{err:?}");
        let msg = err.to_string();
        assert!(msg.contains("displacement"), "{msg}");
        assert!(msg.contains("bad.vtu"), "{msg}");
        assert!(!path.exists());

        let cell_vals = vec![1.0; 3];
        let piece = VtuPiece {
            point_data: vec![],
            cell_data: vec![DataArray {
                name: "energy",
                components: 1,
                values: &cell_vals,
            }],
            ..piece
        };
        let msg = write_vtu(&path, &piece).expect_err("must fail").to_string();
        assert!(msg.contains("energy") && msg.contains("cells"), "{msg}");
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn non_finite_values_are_errors_naming_array_and_index() {
        let dir = scratch_dir("nan");
        let path = dir.join("nan.vtu");
        let (points, conn) = two_hex_mesh();
        let mut phi = vec![1.0; points.len()];
        phi[7] = f64::NAN;
        let piece = VtuPiece {
            points: &points,
            cell_type: CellType::Hex8,
            connectivity: &conn,
            point_data: vec![DataArray {
                name: "potential",
                components: 1,
                values: &phi,
            }],
            cell_data: vec![],
        };
        match write_vtu(&path, &piece) {
            Err(VtuError::NonFinite { name, index, .. }) => {
                assert_eq!(name, "potential");
                assert_eq!(index, 7);
            }
            other => panic!("expected NonFinite, got {other:?}"),
        }
        assert!(!path.exists());

        let mut bad_points = points.clone();
        bad_points[2][1] = f64::INFINITY;
        let piece = VtuPiece {
            points: &bad_points,
            point_data: vec![],
            ..piece
        };
        match write_vtu(&path, &piece) {
            Err(VtuError::NonFinite { name, index, .. }) => {
                assert_eq!(name, "Points");
                assert_eq!(index, 7);
            }
            other => panic!("expected NonFinite, got {other:?}"),
        }
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn invalid_mesh_and_names_are_errors() {
        let dir = scratch_dir("mesh");
        let path = dir.join("m.vtu");
        let (points, conn) = two_hex_mesh();
        let base = VtuPiece {
            points: &points,
            cell_type: CellType::Hex8,
            connectivity: &conn[..12],
            point_data: vec![],
            cell_data: vec![],
        };
        assert!(matches!(
            write_vtu(&path, &base),
            Err(VtuError::InvalidMesh { .. })
        ));
        let mut bad_conn = conn.clone();
        bad_conn[3] = 12;
        let piece = VtuPiece {
            connectivity: &bad_conn,
            ..base.clone()
        };
        assert!(matches!(
            write_vtu(&path, &piece),
            Err(VtuError::InvalidMesh { .. })
        ));
        let vals = vec![0.0; 12];
        let arr = DataArray {
            name: "a",
            components: 1,
            values: &vals,
        };
        let piece = VtuPiece {
            connectivity: &conn,
            point_data: vec![arr, arr],
            ..base.clone()
        };
        assert!(matches!(
            write_vtu(&path, &piece),
            Err(VtuError::InvalidArray { .. })
        ));
        let piece = VtuPiece {
            connectivity: &conn,
            point_data: vec![DataArray { name: "", ..arr }],
            ..base.clone()
        };
        assert!(matches!(
            write_vtu(&path, &piece),
            Err(VtuError::InvalidArray { .. })
        ));
        let piece = VtuPiece {
            connectivity: &conn,
            point_data: vec![DataArray {
                components: 0,
                ..arr
            }],
            ..base
        };
        assert!(matches!(
            write_vtu(&path, &piece),
            Err(VtuError::InvalidArray { .. })
        ));
        assert!(!path.exists());
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn pvd_content() {
        let dir = scratch_dir("pvd");
        let path = dir.join("run.pvd");
        let entries = vec![
            (0.0, "run_0000.vtu".to_string()),
            (0.25, "run_0001.vtu".to_string()),
            (1e-9, "steps/run_0002.vtu".to_string()),
            (2.0, "a&b.vtu".to_string()),
        ];
        write_pvd(&path, &entries).expect("write");
        let text = fs::read_to_string(&path).expect("read");
        assert!(text.starts_with("<?xml version=\"1.0\"?>\n"));
        assert!(text.contains("<VTKFile type=\"Collection\" version=\"0.1\""));
        assert!(text.contains("<Collection>") && text.contains("</Collection>"));
        assert!(text.trim_end().ends_with("</VTKFile>"));
        let lines: Vec<&str> = text
            .lines()
            .map(str::trim)
            .filter(|l| l.starts_with("<DataSet"))
            .collect();
        assert_eq!(
            lines,
            vec![
                "<DataSet timestep=\"0\" group=\"\" part=\"0\" file=\"run_0000.vtu\"/>",
                "<DataSet timestep=\"0.25\" group=\"\" part=\"0\" file=\"run_0001.vtu\"/>",
                "<DataSet timestep=\"1e-9\" group=\"\" part=\"0\" file=\"steps/run_0002.vtu\"/>",
                "<DataSet timestep=\"2\" group=\"\" part=\"0\" file=\"a&amp;b.vtu\"/>",
            ]
        );
        let err = write_pvd(&path, &[(f64::NAN, "x.vtu".to_string())]).expect_err("nan time");
        assert!(matches!(err, VtuError::InvalidPvdEntry { index: 0, .. }));
        // The previous file is untouched by the failed write.
        assert_eq!(fs::read_to_string(&path).expect("read"), text);
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn reader_rejects_every_truncation() {
        let dir = scratch_dir("trunc");
        let path = dir.join("full.vtu");
        let points = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let conn = vec![0, 1, 2, 3];
        let phi = vec![0.5, 1.5, 2.5, 3.5];
        let piece = VtuPiece {
            points: &points,
            cell_type: CellType::Tet4,
            connectivity: &conn,
            point_data: vec![DataArray {
                name: "phi",
                components: 1,
                values: &phi,
            }],
            cell_data: vec![],
        };
        write_vtu(&path, &piece).expect("write");
        let full = fs::read(&path).expect("read");
        let body_len = full.trim_ascii_end().len();
        let cut_path = dir.join("cut.vtu");
        for cut in 0..body_len {
            fs::write(&cut_path, &full[..cut]).expect("write cut");
            let res = read_vtu(&cut_path);
            assert!(
                matches!(res, Err(VtuError::Parse { .. }) | Err(VtuError::Io { .. })),
                "truncation at {cut} accepted: {res:?}"
            );
        }
        fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn reader_rejects_malformed_input() {
        let dir = scratch_dir("malformed");
        let path = dir.join("bad.vtu");
        let good_head = "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\"><UnstructuredGrid>\
                         <Piece NumberOfPoints=\"1\" NumberOfCells=\"0\">";
        let good_tail = "<Cells><DataArray type=\"Int64\" Name=\"connectivity\"></DataArray>\
                         <DataArray type=\"Int64\" Name=\"offsets\"></DataArray>\
                         <DataArray type=\"UInt8\" Name=\"types\"></DataArray></Cells>\
                         </Piece></UnstructuredGrid></VTKFile>";
        let ok = format!(
            "{good_head}<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\">\
             1 2 3</DataArray></Points>{good_tail}"
        );
        fs::write(&path, &ok).expect("write");
        let data = read_vtu(&path).expect("minimal file is valid");
        assert_eq!(data.points, vec![[1.0, 2.0, 3.0]]);

        let cases = [
            String::new(),
            "garbage".to_string(),
            "<".to_string(),
            "<VTKFile type=\"PolyData\"></VTKFile>".to_string(),
            ok.replace("1 2 3", "1 2"),
            ok.replace("1 2 3", "1 2 x"),
            ok.replace("1 2 3", "1 2 3 4"),
            ok.replace("</Points>", "</Cells>"),
            ok.replace("NumberOfPoints=\"1\"", "NumberOfPoints=\"-1\""),
            ok.replace("NumberOfPoints=\"1\"", "NumberOfPoints=1"),
            ok.replace(
                "NumberOfComponents=\"3\"",
                "NumberOfComponents=\"3\" format=\"binary\"",
            ),
            ok.replace("NumberOfComponents=\"3\"", "NumberOfComponents=\"0\""),
            ok.replace("Name=\"types\"", "Name=\"typo\""),
            ok.replace("<Points>", "<Points><Foo/>"),
            format!("{ok}<VTKFile/>"),
            ok.replace("Name=\"connectivity\"", "Name=\"&bogus;\""),
            ok.replace("NumberOfCells=\"0\"", "NumberOfCells=\"1\""),
        ];
        for (i, case) in cases.iter().enumerate() {
            fs::write(&path, case).expect("write");
            let res = read_vtu(&path);
            assert!(
                matches!(res, Err(VtuError::Parse { .. })),
                "case {i} accepted: {res:?}"
            );
            let msg = res.expect_err("checked").to_string();
            assert!(msg.contains("bad.vtu"), "{msg}");
        }

        let missing = dir.join("missing.vtu");
        assert!(matches!(read_vtu(&missing), Err(VtuError::Io { .. })));
        fs::remove_dir_all(&dir).expect("cleanup");
    }
}
