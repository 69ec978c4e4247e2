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

/// A field array given as (name, components, values): see [`DataArray`].
pub type Field<'a> = (&'a str, usize, &'a [f64]);

impl<'a> VtuPiece<'a> {
    /// The field file of the cells `connectivity` (of `cell_type`) on `points`: the nodal arrays
    /// `point_data` and the cell arrays `cell_data`, in the order given. What the field, mode
    /// and revolved files write goes through here.
    pub fn fields(
        points: &'a [[f64; 3]],
        cell_type: CellType,
        connectivity: &'a [usize],
        point_data: &[Field<'a>],
        cell_data: &[Field<'a>],
    ) -> Self {
        let arrays = |fields: &[Field<'a>]| {
            fields
                .iter()
                .map(|&(name, components, values)| DataArray {
                    name,
                    components,
                    values,
                })
                .collect()
        };
        VtuPiece {
            points,
            cell_type,
            connectivity,
            point_data: arrays(point_data),
            cell_data: arrays(cell_data),
        }
    }
}

/// Errors of the VTU/PVD writer. Every message starts with the file path.
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

/// The encoding of the field files of `output.vtu_format`.
impl From<crate::job::plan::FieldFormat> for Encoding {
    fn from(format: crate::job::plan::FieldFormat) -> Self {
        use crate::job::plan::FieldFormat;
        match format {
            FieldFormat::Ascii => Encoding::Ascii,
            FieldFormat::Binary => Encoding::Binary,
            FieldFormat::Compressed => Encoding::Compressed,
        }
    }
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
