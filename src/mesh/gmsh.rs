//! Gmsh mesh import: MSH 4.1 (ASCII and binary) and MSH 2.2 (ASCII).
//!
//! 3-D meshes ([`read_msh`]): volume elements become the cells (tet4, tet10 or hex8, one kind per
//! file); physical groups by name become sets: a volume group a cell set (and the node set of its
//! cells), a surface group (triangles, six-node triangles or quadrilaterals) a face set matched to
//! the faces of the cells by their corner nodes (internal surfaces too: the face of the first
//! adjacent cell), and the node set of those faces. Points and curves are ignored. Groups without a
//! name are called `volume<tag>` and `surface<tag>`.
//!
//! Meridian meshes of axisymmetric models ([`read_msh_meridian`]): the surface elements of the
//! x–y plane (x = R ≥ 0, y = Z) become the cells (quad4, quad8, quad9, tri3 or tri6, one kind per
//! file); a physical surface becomes a cell set (and a node set), a physical curve a face set
//! matched to the cell sides (and a node set), a physical point a node set. Unnamed groups are
//! `surface<tag>`, `curve<tag>` and `point<tag>`. Nodes within 1e-12 of the mesh's extent of the
//! axis are put on it (x = 0).
//!
//! Nodes are renumbered compactly in file order; nodes no cell uses are dropped. Node orders are
//! converted to deasim's (VTK's for the 3-D kinds; the meridian kinds use Gmsh's) and inverted
//! cells reordered.
//!
//! Errors name the line (ASCII) or byte offset (binary) and what was expected; the reader never
//! panics, and its memory grows only with the bytes it has read, whatever counts the file claims.

use super::{ElementKind, FaceRef, MeridianKind, Mesh};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// Where in the file a problem is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// 1-based line of an ASCII section.
    Line(usize),
    /// Byte offset of binary data.
    Byte(usize),
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Location::Line(l) => write!(f, "line {l}: "),
            Location::Byte(b) => write!(f, "byte {b}: "),
        }
    }
}

/// A file that cannot be read as a deasim mesh.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {}{message}", .at.map(|a| a.to_string()).unwrap_or_default())]
pub struct GmshError {
    pub file: String,
    pub at: Option<Location>,
    pub message: String,
}

/// A mesh read from a Gmsh file, with what the import changed.
#[derive(Debug, Clone)]
pub struct GmshMesh {
    pub mesh: Mesh,
    /// Cells whose node order described an inverted cell and was mirrored.
    pub reoriented: usize,
    /// `4.1 ASCII`, `4.1 binary` or `2.2 ASCII`.
    pub format: String,
}

/// Reads a 3-D `.msh` file; coordinates are multiplied by `scale` (1e-3 for a file drawn in mm).
pub fn read_msh(path: &Path, scale: f64) -> Result<GmshMesh, GmshError> {
    read(path, scale, false)
}

/// Reads a 2-D `.msh` file as the meridian mesh of an axisymmetric model: its surface elements in
/// the x–y plane with x = R ≥ 0, y = Z; coordinates are multiplied by `scale`.
pub fn read_msh_meridian(path: &Path, scale: f64) -> Result<GmshMesh, GmshError> {
    read(path, scale, true)
}

fn read(path: &Path, scale: f64, meridian: bool) -> Result<GmshMesh, GmshError> {
    let name = path.display().to_string();
    let data = std::fs::read(path).map_err(|e| GmshError {
        file: name.clone(),
        at: None,
        message: format!("cannot read: {e}"),
    })?;
    parse(&data, &name, scale, meridian)
}

/// Parses the bytes of a 3-D `.msh` file; `file` names it in messages.
pub fn parse_msh(data: &[u8], file: &str, scale: f64) -> Result<GmshMesh, GmshError> {
    parse(data, file, scale, false)
}

/// Parses the bytes of a 2-D `.msh` file as a meridian mesh (see [`read_msh_meridian`]).
pub fn parse_msh_meridian(data: &[u8], file: &str, scale: f64) -> Result<GmshMesh, GmshError> {
    parse(data, file, scale, true)
}

fn parse(data: &[u8], file: &str, scale: f64, meridian: bool) -> Result<GmshMesh, GmshError> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(GmshError {
            file: file.into(),
            at: None,
            message: format!("scale must be a positive finite number; got {scale}"),
        });
    }
    let mut r = Reader {
        data,
        pos: 0,
        line: 1,
        file,
        binary: false,
        size_t: 8,
        swap: false,
        meridian,
    };
    let raw = r.read_file()?;
    if meridian {
        raw.build_meridian(file, scale)
    } else {
        raw.build(file, scale)
    }
}

/// A physical-group membership of an element: through its entity (4.1) or its own tag (2.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Group {
    Entity(i32, i32),
    Physical(i32, i32),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Version {
    V41,
    V22,
}

/// What the element types deasim reads are for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Volume(ElementKind),
    /// A face with this many corners.
    Face(usize),
    Ignored,
    Unsupported,
}

/// At most `max` bytes of `s`, cut at a character boundary (a message quotes the start of a
/// token or line, which may hold multi-byte characters).
fn clip(s: &str, max: usize) -> &str {
    if s.len() <= max {
        return s;
    }
    let mut end = max;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    &s[..end]
}

/// (dimension, nodes, name, role) of a Gmsh element type.
fn element_type(t: i32) -> Option<(i32, usize, &'static str, Role)> {
    use Role::*;
    Some(match t {
        1 => (1, 2, "2-node line", Ignored),
        2 => (2, 3, "3-node triangle", Face(3)),
        3 => (2, 4, "4-node quadrangle", Face(4)),
        4 => (3, 4, "4-node tetrahedron", Volume(ElementKind::Tet4)),
        5 => (3, 8, "8-node hexahedron", Volume(ElementKind::Hex8)),
        6 => (3, 6, "6-node prism", Unsupported),
        7 => (3, 5, "5-node pyramid", Unsupported),
        8 => (1, 3, "3-node line", Ignored),
        9 => (2, 6, "6-node triangle", Face(3)),
        10 => (2, 9, "9-node quadrangle", Unsupported),
        11 => (3, 10, "10-node tetrahedron", Volume(ElementKind::Tet10)),
        12 => (3, 27, "27-node hexahedron", Unsupported),
        13 => (3, 18, "18-node prism", Unsupported),
        14 => (3, 14, "14-node pyramid", Unsupported),
        15 => (0, 1, "point", Ignored),
        16 => (2, 8, "8-node quadrangle", Unsupported),
        17 => (3, 20, "20-node hexahedron", Unsupported),
        18 => (3, 15, "15-node prism", Unsupported),
        19 => (3, 13, "13-node pyramid", Unsupported),
        20 => (2, 9, "9-node triangle", Unsupported),
        21 => (2, 10, "10-node triangle", Unsupported),
        26 => (1, 4, "4-node line", Ignored),
        27 => (1, 5, "5-node line", Ignored),
        28 => (1, 6, "6-node line", Ignored),
        29 => (3, 20, "20-node tetrahedron", Unsupported),
        _ => return None,
    })
}

const SUPPORTED: &str =
    "deasim reads volume elements of types 4 (tet4), 11 (tet10) and 5 (hex8) and faces of types 2 \
     (triangle), 9 (6-node triangle) and 3 (quadrangle)";

const MERIDIAN_SUPPORTED: &str =
    "a meridian mesh holds surface elements of types 3 (quad4), 16 (quad8), 10 (quad9), 2 (tri3) \
     or 9 (tri6), lines of types 1 (2-node, linear cells) or 8 (3-node, quadratic cells) and points";

/// What an element of a meridian (2-D) file is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MeridianRole {
    Cell(MeridianKind),
    Side,
    Point,
    Volume,
    /// Another surface or line type.
    Unsupported,
}

/// The role of a known element type of dimension `dim` in a meridian file.
fn meridian_role(dim: i32, t: i32) -> MeridianRole {
    use MeridianRole::*;
    match t {
        3 => Cell(MeridianKind::Quad4),
        16 => Cell(MeridianKind::Quad8),
        10 => Cell(MeridianKind::Quad9),
        2 => Cell(MeridianKind::Tri3),
        9 => Cell(MeridianKind::Tri6),
        1 | 8 => Side,
        15 => Point,
        _ if dim == 3 => Volume,
        _ => Unsupported,
    }
}

struct Element {
    tag: u64,
    kind: ElementKind,
    nodes: Vec<u64>,
    group: Option<Group>,
}

struct Face {
    tag: u64,
    corners: Vec<u64>,
    group: Group,
}

/// Everything read from the file, in Gmsh's numbering.
#[derive(Default)]
struct Raw {
    version: Option<(Version, bool)>,
    names: BTreeMap<(i32, i32), String>,
    entity_groups: HashMap<(i32, i32), Vec<i32>>,
    node_tags: Vec<u64>,
    coords: Vec<[f64; 3]>,
    seen_nodes: bool,
    seen_elements: bool,
    volumes: Vec<Element>,
    faces: Vec<Face>,
    /// Surface blocks of unsupported types: (entity, type, element tag), an error if physical.
    odd_faces: Vec<(Group, i32, u64)>,
    /// Surface elements of a 3-D read (a file of only these is a 2-D mesh).
    surfaces: u64,
    /// Meridian read: the surface cells; the lines and points of groups, with all their nodes;
    /// lines of other types (an error if physical); the first volume element (tag, type).
    cells2d: Vec<Element>,
    curves: Vec<Face>,
    points: Vec<Face>,
    odd_curves: Vec<(Group, i32, u64)>,
    volume: Option<(u64, i32)>,
}

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
    file: &'a str,
    binary: bool,
    size_t: usize,
    swap: bool,
    /// Reading a meridian (2-D) mesh.
    meridian: bool,
}

type Res<T> = Result<T, GmshError>;

impl<'a> Reader<'a> {
    fn err_line(&self, msg: impl Into<String>) -> GmshError {
        GmshError {
            file: self.file.into(),
            at: Some(Location::Line(self.line)),
            message: msg.into(),
        }
    }

    fn err_byte(&self, at: usize, msg: impl Into<String>) -> GmshError {
        GmshError {
            file: self.file.into(),
            at: Some(Location::Byte(at)),
            message: msg.into(),
        }
    }

    /// The next whitespace-separated token (ASCII), counting lines.
    fn token(&mut self) -> Option<&'a [u8]> {
        while let Some(&b) = self.data.get(self.pos) {
            if b == b'\n' {
                self.line += 1;
            }
            if !b.is_ascii_whitespace() {
                break;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while self
            .data
            .get(self.pos)
            .is_some_and(|b| !b.is_ascii_whitespace())
        {
            self.pos += 1;
        }
        (self.pos > start).then(|| &self.data[start..self.pos])
    }

    /// A token that must be a number of type `T`; `what` says what it is, `section` where.
    fn num<T: std::str::FromStr>(&mut self, what: &str, section: &str) -> Res<T> {
        match self.token() {
            None => Err(self.err_line(format!(
                "unexpected end of file in ${section}: expected {what}"
            ))),
            Some(t) if t.first() == Some(&b'$') => Err(self.err_line(format!(
                "truncated ${section} section: expected {what}, found `{}`",
                String::from_utf8_lossy(t)
            ))),
            Some(t) => std::str::from_utf8(t)
                .ok()
                .and_then(|s| s.parse::<T>().ok())
                .ok_or_else(|| {
                    self.err_line(format!(
                        "expected {what} in ${section}, found `{}`",
                        String::from_utf8_lossy(&t[..t.len().min(40)])
                    ))
                }),
        }
    }

    fn coord(&mut self, what: &str, section: &str) -> Res<f64> {
        let v: f64 = self.num(what, section)?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.err_line(format!("{what} in ${section} is not finite: {v}")))
        }
    }

    /// Skips the rest of the current line (ASCII).
    fn skip_line(&mut self) {
        while let Some(&b) = self.data.get(self.pos) {
            self.pos += 1;
            if b == b'\n' {
                self.line += 1;
                return;
            }
        }
    }

    /// Expects the token `$End<section>`.
    fn end(&mut self, section: &str) -> Res<()> {
        let t = self.token();
        let want = format!("$End{section}");
        match t {
            Some(t) if t == want.as_bytes() => Ok(()),
            Some(t) => Err(self.err_line(format!(
                "expected `{want}` (the counts of ${section} do not match its contents), found `{}`",
                String::from_utf8_lossy(&t[..t.len().min(40)])
            ))),
            None => Err(self.err_line(format!("unexpected end of file: expected `{want}`"))),
        }
    }

    /// Skips an unknown section up to its end marker.
    fn skip_section(&mut self, section: &str) -> Res<()> {
        let want = format!("$End{section}");
        let rest = &self.data[self.pos..];
        match rest.windows(want.len()).position(|w| w == want.as_bytes()) {
            Some(p) => {
                self.line += rest[..p].iter().filter(|&&b| b == b'\n').count();
                self.pos += p + want.len();
                Ok(())
            }
            None => Err(self.err_line(format!("section ${section} has no end marker `{want}`"))),
        }
    }

    // ---- binary ----

    fn bytes(&mut self, n: usize, what: &str, section: &str) -> Res<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        match end {
            Some(e) => {
                let b = &self.data[self.pos..e];
                self.pos = e;
                Ok(b)
            }
            None => Err(self.err_byte(
                self.pos,
                format!("binary ${section} is truncated: expected {what}"),
            )),
        }
    }

    /// Fails early when `count` items of `each` bytes cannot fit in the rest of the file.
    fn room(&self, count: u64, each: usize, what: &str, section: &str) -> Res<()> {
        let need = (count as u128) * (each as u128);
        if need > (self.data.len() - self.pos) as u128 {
            return Err(self.err_byte(
                self.pos,
                format!(
                    "binary ${section} is truncated: {count} {what} need {need} bytes, {} remain",
                    self.data.len() - self.pos
                ),
            ));
        }
        Ok(())
    }

    fn int(&mut self, what: &str, section: &str) -> Res<i32> {
        let mut b: [u8; 4] = self.bytes(4, what, section)?.try_into().unwrap_or([0; 4]);
        if self.swap {
            b.reverse();
        }
        Ok(i32::from_le_bytes(b))
    }

    fn size(&mut self, what: &str, section: &str) -> Res<u64> {
        if self.size_t == 4 {
            Ok(self.int(what, section)? as u32 as u64)
        } else {
            let mut b: [u8; 8] = self.bytes(8, what, section)?.try_into().unwrap_or([0; 8]);
            if self.swap {
                b.reverse();
            }
            Ok(u64::from_le_bytes(b))
        }
    }

    fn double(&mut self, what: &str, section: &str) -> Res<f64> {
        let at = self.pos;
        let mut b: [u8; 8] = self.bytes(8, what, section)?.try_into().unwrap_or([0; 8]);
        if self.swap {
            b.reverse();
        }
        let v = f64::from_le_bytes(b);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.err_byte(at, format!("{what} in ${section} is not finite: {v}")))
        }
    }

    // ---- mode-independent readers for 4.1 sections ----

    fn i(&mut self, what: &str, section: &str) -> Res<i32> {
        if self.binary {
            self.int(what, section)
        } else {
            self.num(what, section)
        }
    }

    fn sz(&mut self, what: &str, section: &str) -> Res<u64> {
        if self.binary {
            self.size(what, section)
        } else {
            self.num(what, section)
        }
    }

    fn f(&mut self, what: &str, section: &str) -> Res<f64> {
        if self.binary {
            self.double(what, section)
        } else {
            self.coord(what, section)
        }
    }

    /// The element types this read accepts, for messages.
    fn supported(&self) -> &'static str {
        if self.meridian {
            MERIDIAN_SUPPORTED
        } else {
            SUPPORTED
        }
    }

    /// An error at the current position, by line or byte.
    fn here(&self, msg: impl Into<String>) -> GmshError {
        if self.binary {
            self.err_byte(self.pos, msg)
        } else {
            self.err_line(msg)
        }
    }

    // ---- sections ----

    fn read_file(&mut self) -> Res<Raw> {
        let mut raw = Raw::default();
        while let Some(t) = self.token() {
            let header = String::from_utf8_lossy(t).into_owned();
            let Some(section) = header.strip_prefix('$') else {
                return Err(self.err_line(format!(
                    "expected a section header such as `$Nodes`, found `{}`",
                    clip(&header, 40)
                )));
            };
            if raw.version.is_none() && section != "MeshFormat" && section != "Comments" {
                return Err(self.err_line(format!(
                    "expected `$MeshFormat` first, found `{header}`: not a Gmsh MSH file?"
                )));
            }
            let v = raw.version.map(|v| v.0);
            if self.binary && matches!(section, "Entities" | "Nodes" | "Elements") {
                // binary data starts right after the header line
                self.skip_line();
            }
            match section {
                "MeshFormat" => self.mesh_format(&mut raw)?,
                "PhysicalNames" => self.physical_names(&mut raw)?,
                "Entities" if v == Some(Version::V41) => self.entities(&mut raw)?,
                "Nodes" if v == Some(Version::V41) => self.nodes41(&mut raw)?,
                "Elements" if v == Some(Version::V41) => self.elements41(&mut raw)?,
                "Nodes" => self.nodes22(&mut raw)?,
                "Elements" => self.elements22(&mut raw)?,
                s if s.starts_with("End") => {
                    return Err(self.err_line(format!("`{header}` without its section")))
                }
                other => self.skip_section(other)?,
            }
        }
        if raw.version.is_none() {
            return Err(self.err_line("empty file: expected `$MeshFormat`"));
        }
        for (seen, s) in [(raw.seen_nodes, "$Nodes"), (raw.seen_elements, "$Elements")] {
            if !seen {
                return Err(GmshError {
                    file: self.file.into(),
                    at: None,
                    message: format!("no {s} section"),
                });
            }
        }
        Ok(raw)
    }

    fn mesh_format(&mut self, raw: &mut Raw) -> Res<()> {
        const S: &str = "MeshFormat";
        let v = self
            .token()
            .map(|t| String::from_utf8_lossy(t).into_owned())
            .unwrap_or_default();
        let file_type: i32 = self.num("the file type (0 ASCII, 1 binary)", S)?;
        let size: usize = self.num("the data size (8)", S)?;
        let binary = match file_type {
            0 => false,
            1 => true,
            o => return Err(self.err_line(format!("file type must be 0 or 1, found {o}"))),
        };
        let version = match v.as_str() {
            "4.1" => Version::V41,
            "2.2" | "2.1" | "2" | "2.0" if !binary => Version::V22,
            "2.2" | "2.1" | "2" | "2.0" => return Err(self.err_line(
                "binary MSH 2 is not supported: save as MSH 4.1 (binary or ASCII) or MSH 2.2 ASCII",
            )),
            other => {
                return Err(self.err_line(format!(
                    "unsupported MSH version `{other}`: deasim reads 4.1 (ASCII or binary) and 2.2 \
                     (ASCII); re-export with Gmsh (`-format msh41` or `-format msh22`)"
                )))
            }
        };
        if size != 4 && size != 8 {
            return Err(self.err_line(format!("data size must be 4 or 8, found {size}")));
        }
        self.size_t = size;
        if binary {
            self.skip_line();
            let at = self.pos;
            let b: [u8; 4] = self
                .bytes(4, "the endianness marker 1", S)?
                .try_into()
                .unwrap_or([0; 4]);
            match (i32::from_le_bytes(b), i32::from_be_bytes(b)) {
                (1, _) => self.swap = false,
                (_, 1) => self.swap = true,
                _ => return Err(self.err_byte(at, "expected the binary integer 1 (endianness)")),
            }
        }
        self.end(S)?;
        self.binary = binary;
        raw.version = Some((version, binary));
        Ok(())
    }

    fn physical_names(&mut self, raw: &mut Raw) -> Res<()> {
        const S: &str = "PhysicalNames";
        let n: u64 = self.num("the number of names", S)?;
        for _ in 0..n {
            let dim: i32 = self.num("a dimension", S)?;
            let tag: i32 = self.num("a physical tag", S)?;
            // the quoted name is the rest of the line
            let start = self.pos;
            let end = self.data[start..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(self.data.len(), |p| start + p);
            let text = String::from_utf8_lossy(&self.data[start..end]);
            let text = text.trim();
            let name = text
                .strip_prefix('"')
                .and_then(|s| s.strip_suffix('"'))
                .filter(|s| !s.is_empty())
                .ok_or_else(|| {
                    self.err_line(format!(
                        "expected a quoted physical name, found `{}`",
                        clip(text, 40)
                    ))
                })?;
            raw.names.insert((dim, tag), name.to_string());
            self.pos = end;
        }
        self.end(S)
    }

    fn entities(&mut self, raw: &mut Raw) -> Res<()> {
        const S: &str = "Entities";
        let counts = [
            self.sz("the number of points", S)?,
            self.sz("the number of curves", S)?,
            self.sz("the number of surfaces", S)?,
            self.sz("the number of volumes", S)?,
        ];
        for (dim, &count) in counts.iter().enumerate() {
            if self.binary {
                self.room(count, 4 + 3 * 8 + self.size_t, "entities", S)?;
            }
            for _ in 0..count {
                let tag = self.i("an entity tag", S)?;
                let n_box = if dim == 0 { 3 } else { 6 };
                for _ in 0..n_box {
                    self.f("a bounding-box coordinate", S)?;
                }
                let n_phys = self.sz("the number of physical tags", S)?;
                if self.binary {
                    self.room(n_phys, 4, "physical tags", S)?;
                }
                let mut tags = Vec::new();
                for _ in 0..n_phys {
                    tags.push(self.i("a physical tag", S)?);
                }
                raw.entity_groups.insert((dim as i32, tag), tags);
                if dim > 0 {
                    let n_b = self.sz("the number of bounding entities", S)?;
                    if self.binary {
                        self.room(n_b, 4, "bounding entities", S)?;
                    }
                    for _ in 0..n_b {
                        self.i("a bounding entity tag", S)?;
                    }
                }
            }
        }
        self.end(S)
    }

    /// The head of a MSH 4.1 `$Nodes` or `$Elements` section (of `what`s: `node` or `element`):
    /// the number of entity blocks, returned, then the number of `what`s and their tag range.
    fn blocks41(&mut self, what: &str, section: &str) -> Res<u64> {
        let blocks = self.sz("the number of entity blocks", section)?;
        self.sz(&format!("the number of {what}s"), section)?;
        self.sz(&format!("the smallest {what} tag"), section)?;
        self.sz(&format!("the largest {what} tag"), section)?;
        Ok(blocks)
    }

    fn nodes41(&mut self, raw: &mut Raw) -> Res<()> {
        const S: &str = "Nodes";
        raw.seen_nodes = true;
        for _ in 0..self.blocks41("node", S)? {
            let dim = self.i("an entity dimension", S)?;
            self.i("an entity tag", S)?;
            let parametric = self.i("the parametric flag (0 or 1)", S)?;
            let n = self.sz("the number of nodes in the block", S)?;
            let extra = match parametric {
                0 => 0,
                1 => dim.clamp(0, 3) as usize,
                o => return Err(self.here(format!("parametric flag must be 0 or 1, found {o}"))),
            };
            if self.binary {
                self.room(n, self.size_t + (3 + extra) * 8, "nodes", S)?;
            }
            for _ in 0..n {
                raw.node_tags.push(self.sz("a node tag", S)?);
            }
            for _ in 0..n {
                let x = [
                    self.f("an x coordinate", S)?,
                    self.f("a y coordinate", S)?,
                    self.f("a z coordinate", S)?,
                ];
                for _ in 0..extra {
                    self.f("a parametric coordinate", S)?;
                }
                raw.coords.push(x);
            }
        }
        self.end(S)
    }

    fn elements41(&mut self, raw: &mut Raw) -> Res<()> {
        const S: &str = "Elements";
        raw.seen_elements = true;
        for _ in 0..self.blocks41("element", S)? {
            let dim = self.i("an entity dimension", S)?;
            let tag = self.i("an entity tag", S)?;
            let at = (self.line, self.pos);
            let t = self.i("an element type", S)?;
            let n = self.sz("the number of elements in the block", S)?;
            let info = element_type(t);
            if let Some((d, _, name, _)) = info {
                if d != dim {
                    return Err(self.here(format!(
                        "element type {t} ({name}) in a block of dimension {dim}"
                    )));
                }
            }
            let group = Group::Entity(dim, tag);
            let (nodes, role) = match info {
                Some((_, nodes, _, role)) => (nodes, role),
                None if dim <= 1 && !self.binary => {
                    // points and curves are ignored; an ASCII element is one line
                    self.skip_line();
                    for _ in 0..n {
                        if self.pos >= self.data.len() {
                            return Err(self.here("unexpected end of file in $Elements"));
                        }
                        self.skip_line();
                    }
                    continue;
                }
                None => {
                    let msg = format!("unknown element type {t} ({})", self.supported());
                    return Err(if self.binary {
                        self.err_byte(at.1, msg)
                    } else {
                        GmshError {
                            file: self.file.into(),
                            at: Some(Location::Line(at.0)),
                            message: msg,
                        }
                    });
                }
            };
            let odd = if self.meridian {
                dim == 2 && !matches!(meridian_role(dim, t), MeridianRole::Cell(_))
            } else {
                role == Role::Unsupported && dim == 3
            };
            if odd {
                return Err(self.here(format!(
                    "element type {t} ({}) is not supported: {}",
                    info.map_or("", |i| i.2),
                    self.supported()
                )));
            }
            if self.binary {
                self.room(n, self.size_t * (1 + nodes), "elements", S)?;
            }
            for _ in 0..n {
                let etag = self.sz("an element tag", S)?;
                let mut list = Vec::with_capacity(nodes);
                for _ in 0..nodes {
                    list.push(self.sz("a node tag", S)?);
                }
                if self.meridian {
                    raw.keep_meridian(dim, t, etag, list, Some(group));
                    continue;
                }
                if dim == 2 {
                    raw.surfaces += 1;
                }
                match role {
                    Role::Volume(kind) => raw.volumes.push(Element {
                        tag: etag,
                        kind,
                        nodes: list,
                        group: Some(group),
                    }),
                    Role::Face(c) => {
                        list.truncate(c);
                        raw.faces.push(Face {
                            tag: etag,
                            corners: list,
                            group,
                        })
                    }
                    Role::Unsupported => raw.odd_faces.push((group, t, etag)),
                    Role::Ignored => {}
                }
            }
        }
        self.end(S)
    }

    fn nodes22(&mut self, raw: &mut Raw) -> Res<()> {
        const S: &str = "Nodes";
        raw.seen_nodes = true;
        let n: u64 = self.num("the number of nodes", S)?;
        for _ in 0..n {
            raw.node_tags.push(self.num("a node tag", S)?);
            raw.coords.push([
                self.coord("an x coordinate", S)?,
                self.coord("a y coordinate", S)?,
                self.coord("a z coordinate", S)?,
            ]);
        }
        self.end(S)
    }

    fn elements22(&mut self, raw: &mut Raw) -> Res<()> {
        const S: &str = "Elements";
        raw.seen_elements = true;
        let n: u64 = self.num("the number of elements", S)?;
        for _ in 0..n {
            let etag: u64 = self.num("an element tag", S)?;
            let t: i32 = self.num("an element type", S)?;
            let Some((dim, nodes, name, role)) = element_type(t) else {
                return Err(self.err_line(format!(
                    "element {etag}: unknown element type {t} ({})",
                    self.supported()
                )));
            };
            let n_tags: u64 = self.num("the number of tags", S)?;
            let mut tags = Vec::new();
            for _ in 0..n_tags {
                tags.push(self.num::<i32>("a tag", S)?);
            }
            let phys = tags.first().copied().unwrap_or(0);
            let group = Group::Physical(dim, phys);
            let mut list = Vec::with_capacity(nodes);
            for _ in 0..nodes {
                list.push(self.num::<u64>("a node tag", S)?);
            }
            if self.meridian {
                if dim == 2 && !matches!(meridian_role(dim, t), MeridianRole::Cell(_)) {
                    return Err(self.err_line(format!(
                        "element {etag}: type {t} ({name}) is not supported: {MERIDIAN_SUPPORTED}"
                    )));
                }
                raw.keep_meridian(dim, t, etag, list, (phys != 0).then_some(group));
                continue;
            }
            if dim == 2 {
                raw.surfaces += 1;
            }
            match role {
                Role::Volume(kind) => raw.volumes.push(Element {
                    tag: etag,
                    kind,
                    nodes: list,
                    group: (phys != 0).then_some(group),
                }),
                Role::Face(c) if phys != 0 => {
                    list.truncate(c);
                    raw.faces.push(Face {
                        tag: etag,
                        corners: list,
                        group,
                    });
                }
                Role::Unsupported if dim == 3 => {
                    return Err(self.err_line(format!(
                        "element {etag}: type {t} ({name}) is not supported: {SUPPORTED}"
                    )))
                }
                Role::Unsupported if phys != 0 => raw.odd_faces.push((group, t, etag)),
                _ => {}
            }
        }
        self.end(S)
    }
}

/// Sign of the Jacobian of a cell from its corners: the volume of a tetrahedron, the Jacobian at
/// the centre of a hexahedron.
fn orientation(kind: ElementKind, x: &[[f64; 3]]) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let (a, b, c) = match kind {
        ElementKind::Tet4 | ElementKind::Tet10 => {
            (sub(x[1], x[0]), sub(x[2], x[0]), sub(x[3], x[0]))
        }
        ElementKind::Hex8 => {
            // Σ ±x_a with the signs of the reference corners (−1, 1, 1, −1, −1, 1, 1, −1) etc.
            let s = [
                [-1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0, -1.0],
                [-1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0],
                [-1.0, -1.0, -1.0, -1.0, 1.0, 1.0, 1.0, 1.0],
            ];
            let d = |k: usize| {
                let mut v = [0.0; 3];
                for (p, sign) in x.iter().zip(s[k]) {
                    for i in 0..3 {
                        v[i] += sign * p[i];
                    }
                }
                v
            };
            (d(0), d(1), d(2))
        }
        ElementKind::Meridian(m) => {
            // the (R, Z) area's sign: corners 0, 1 and the last corner
            let last = if matches!(m, MeridianKind::Tri3 | MeridianKind::Tri6) {
                2
            } else {
                3
            };
            (sub(x[1], x[0]), sub(x[last], x[0]), [0.0, 0.0, 1.0])
        }
    };
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// The mirror image node order of a cell (its Jacobian changes sign).
fn mirror(kind: ElementKind) -> &'static [usize] {
    match kind {
        ElementKind::Tet4 => &[0, 2, 1, 3],
        // corners 1 ↔ 2: edges 0–1 ↔ 0–2, 1–3 ↔ 2–3
        ElementKind::Tet10 => &[0, 2, 1, 3, 6, 5, 4, 7, 9, 8],
        ElementKind::Hex8 => &[4, 5, 6, 7, 0, 1, 2, 3],
        ElementKind::Meridian(MeridianKind::Quad4) => &[0, 3, 2, 1],
        ElementKind::Meridian(MeridianKind::Quad8) => &[0, 3, 2, 1, 7, 6, 5, 4],
        ElementKind::Meridian(MeridianKind::Quad9) => &[0, 3, 2, 1, 7, 6, 5, 4, 8],
        ElementKind::Meridian(MeridianKind::Tri3) => &[0, 2, 1],
        ElementKind::Meridian(MeridianKind::Tri6) => &[0, 2, 1, 5, 4, 3],
    }
}

impl Raw {
    /// `4.1 ASCII`, `4.1 binary` or `2.2 ASCII`.
    fn format(&self) -> &'static str {
        match self.version.unwrap_or((Version::V41, false)) {
            (Version::V41, false) => "4.1 ASCII",
            (Version::V41, true) => "4.1 binary",
            (Version::V22, _) => "2.2 ASCII",
        }
    }

    /// The physical groups (dimension, tag) an element belongs to.
    fn groups_of(&self, g: Option<Group>) -> Vec<(i32, i32)> {
        match g {
            None => vec![],
            Some(Group::Physical(d, t)) => vec![(d, t)],
            Some(Group::Entity(d, t)) => self
                .entity_groups
                .get(&(d, t))
                .map(|v| v.iter().map(|&p| (d, p)).collect())
                .unwrap_or_default(),
        }
    }

    /// Keeps an element of a meridian file: cells always, lines and points of a group.
    fn keep_meridian(&mut self, dim: i32, t: i32, tag: u64, nodes: Vec<u64>, group: Option<Group>) {
        match (meridian_role(dim, t), group) {
            (MeridianRole::Cell(k), _) => self.cells2d.push(Element {
                tag,
                kind: ElementKind::Meridian(k),
                nodes,
                group,
            }),
            (MeridianRole::Side, Some(group)) => self.curves.push(Face {
                tag,
                corners: nodes,
                group,
            }),
            (MeridianRole::Point, Some(group)) => self.points.push(Face {
                tag,
                corners: nodes,
                group,
            }),
            (MeridianRole::Volume, _) => {
                self.volume.get_or_insert((tag, t));
            }
            (MeridianRole::Unsupported, Some(group)) if dim == 1 => {
                self.odd_curves.push((group, t, tag))
            }
            _ => {}
        }
    }

    /// The 3-D mesh of the file (see [`read_msh`]).
    fn build(self, file: &str, scale: f64) -> Res<GmshMesh> {
        let err = |message: String| GmshError {
            file: file.into(),
            at: None,
            message,
        };
        let first = self.volumes.first().ok_or_else(|| {
            if self.surfaces > 0 {
                err(format!(
                    "no volume elements, only surface elements ({}): a 2-D mesh, which deasim \
                     reads as the meridian plane of an axisymmetric model; a 3-D mesh needs \
                     volume elements: {SUPPORTED}",
                    self.surfaces
                ))
            } else {
                err(format!(
                    "no volume elements: {SUPPORTED}; mesh the volumes (`gmsh -3`) and, if \
                     physical groups are defined, put the volumes in one (`Physical Volume`)"
                ))
            }
        })?;
        let kind = first.kind;
        one_kind(&self.volumes, "volume", &err)?;
        for &(g, t, etag) in &self.odd_faces {
            if let Some((d, p)) = self.groups_of(Some(g)).first() {
                let name = self.names.get(&(*d, *p)).cloned().unwrap_or(format!("{p}"));
                return Err(err(format!(
                    "element {etag} of physical surface `{name}` has type {t}, not supported: \
                     {SUPPORTED}"
                )));
            }
        }
        let node_pos = self.node_positions(&err)?;
        let cells = self.unique_cells(&self.volumes, &node_pos, &err)?;
        // compact numbering in file order
        let mut new_index = vec![usize::MAX; self.coords.len()];
        for cell in &cells.nodes {
            for &p in cell {
                new_index[p] = 0;
            }
        }
        let mut nodes = Vec::new();
        for (p, slot) in new_index.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = nodes.len();
                let x = self.coords[p];
                nodes.push([scale * x[0], scale * x[1], scale * x[2]]);
            }
        }
        let (connectivity, reoriented) = oriented(kind, &cells, &new_index, &nodes, &err)?;
        // sets; named groups exist even when empty
        let mut sets = self.sets(3, &cells);
        let npc = kind.nodes_per_cell();
        let corners = kind.face_corners();
        let mut face_of: HashMap<[usize; 4], FaceRef> = HashMap::new();
        for c in 0..cells.nodes.len() {
            let cell = &connectivity[c * npc..(c + 1) * npc];
            for (f, local) in kind.faces().iter().enumerate() {
                let mut key = [usize::MAX; 4];
                for (k, &l) in local[..corners].iter().enumerate() {
                    key[k] = cell[l];
                }
                key.sort_unstable();
                face_of.entry(key).or_insert(FaceRef { cell: c, face: f });
            }
        }
        let renumbering = Renumbering {
            pos: &node_pos,
            new_index: &new_index,
            cells: "volume",
        };
        for face in &self.faces {
            let gs = self.groups_of(Some(face.group));
            let Some(&g0) = gs.first() else {
                continue;
            };
            let name = self.group_name(g0);
            let mut key = [usize::MAX; 4];
            for (k, &t) in face.corners.iter().enumerate() {
                key[k] = renumbering.node("surface", face.tag, t, &name, &err)?;
            }
            key.sort_unstable();
            let f = face_of.get(&key).ok_or_else(|| {
                err(format!(
                    "surface element {} of physical group `{name}` is not a face of a {} volume \
                     element",
                    face.tag,
                    kind.name()
                ))
            })?;
            for g in gs {
                sets.faces.entry(self.group_name(g)).or_default().push(*f);
            }
        }
        sets.distinct_names(["volume", "surface", "point"], &err)?;
        Ok(sets.mesh(kind, nodes, connectivity, reoriented, self.format()))
    }
}

impl Raw {
    /// The meridian mesh of a 2-D file (see [`read_msh_meridian`]).
    fn build_meridian(self, file: &str, scale: f64) -> Res<GmshMesh> {
        let err = |message: String| GmshError {
            file: file.into(),
            at: None,
            message,
        };
        if let Some((tag, t)) = self.volume {
            let name = element_type(t).map_or("volume element", |i| i.2);
            return Err(err(format!(
                "element {tag} is a {name}: a 3-D mesh, not a meridian mesh ({MERIDIAN_SUPPORTED}, \
                 in the x–y plane with x = R ≥ 0, y = Z)"
            )));
        }
        let first = self.cells2d.first().ok_or_else(|| {
            err(format!(
                "no surface elements: {MERIDIAN_SUPPORTED}; mesh the surfaces (`gmsh -2`) and, if \
                 physical groups are defined, put the surfaces in one (`Physical Surface`)"
            ))
        })?;
        let kind = first.kind;
        let ElementKind::Meridian(mk) = kind else {
            return Err(err("internal: a surface cell of a 3-D kind".into()));
        };
        one_kind(&self.cells2d, "surface", &err)?;
        for &(g, t, etag) in &self.odd_curves {
            if let Some(&dp) = self.groups_of(Some(g)).first() {
                return Err(err(format!(
                    "element {etag} of physical curve `{}` has type {t}, not supported: \
                     {MERIDIAN_SUPPORTED}",
                    self.group_name(dp)
                )));
            }
        }
        let node_pos = self.node_positions(&err)?;
        let cells = self.unique_cells(&self.cells2d, &node_pos, &err)?;
        let (nodes, new_index) = self.meridian_nodes(&cells.nodes, &cells.tags, scale, &err)?;
        let (connectivity, reoriented) = oriented(kind, &cells, &new_index, &nodes, &err)?;
        // sets; named groups exist even when empty
        let mut sets = self.sets(2, &cells);
        let renumbering = Renumbering {
            pos: &node_pos,
            new_index: &new_index,
            cells: "surface",
        };
        let node_of =
            |what: &str, tag: u64, t: u64, name: &str| renumbering.node(what, tag, t, name, &err);
        let npc = kind.nodes_per_cell();
        let sides = mk.sides();
        let mut side_of: HashMap<[usize; 2], FaceRef> = HashMap::new();
        for c in 0..cells.nodes.len() {
            let cell = &connectivity[c * npc..(c + 1) * npc];
            for (f, local) in sides.iter().enumerate() {
                let mut key = [cell[local[0]], cell[local[1]]];
                key.sort_unstable();
                side_of.entry(key).or_insert(FaceRef { cell: c, face: f });
            }
        }
        for line in &self.curves {
            let gs = self.groups_of(Some(line.group));
            let Some(&g0) = gs.first() else {
                continue;
            };
            let name = self.group_name(g0);
            let quadratic = line.corners.len() == 3;
            if quadratic != mk.is_quadratic() {
                return Err(err(format!(
                    "curve element {} of physical group `{name}` is a {}-node line, but the cells \
                     are {}: {} cells have {}-node sides",
                    line.tag,
                    line.corners.len(),
                    mk.name(),
                    if mk.is_quadratic() {
                        "quadratic"
                    } else {
                        "linear"
                    },
                    sides[0].len()
                )));
            }
            let mut ids = Vec::with_capacity(line.corners.len());
            for &t in &line.corners {
                ids.push(node_of("curve", line.tag, t, &name)?);
            }
            let mut key = [ids[0], ids[1]];
            key.sort_unstable();
            let f = side_of.get(&key).ok_or_else(|| {
                err(format!(
                    "curve element {} of physical group `{name}` is not a side of a {} surface \
                     element",
                    line.tag,
                    mk.name()
                ))
            })?;
            if quadratic {
                let mid = connectivity[f.cell * npc + sides[f.face][2]];
                if ids[2] != mid {
                    return Err(err(format!(
                        "curve element {} of physical group `{name}`: its middle node {} is not \
                         the mid-side node of the {} cell side it lies on",
                        line.tag,
                        line.corners[2],
                        mk.name()
                    )));
                }
            }
            for g in gs {
                sets.faces.entry(self.group_name(g)).or_default().push(*f);
            }
        }
        for point in &self.points {
            let gs = self.groups_of(Some(point.group));
            let Some(&g0) = gs.first() else {
                continue;
            };
            let Some(&t) = point.corners.first() else {
                continue;
            };
            let n = node_of("point", point.tag, t, &self.group_name(g0))?;
            for g in gs {
                sets.points.entry(self.group_name(g)).or_default().push(n);
            }
        }
        sets.distinct_names(["surface", "curve", "point"], &err)?;
        Ok(sets.mesh(kind, nodes, connectivity, reoriented, self.format()))
    }

    /// The nodes the meridian cells use (m), in file order, and the new index of each Gmsh node
    /// position (`usize::MAX` for dropped nodes): the mesh must lie in the x–y plane (|z| ≤ 1e-9
    /// of its extent) with x ≥ 0; nodes within 1e-12 of the extent from the axis are put on it.
    fn meridian_nodes(
        &self,
        cells: &[Vec<usize>],
        cell_tags: &[u64],
        scale: f64,
        err: &dyn Fn(String) -> GmshError,
    ) -> Res<(Vec<[f64; 3]>, Vec<usize>)> {
        // the extent of the meridian (m): the tolerances of the plane and the axis
        let mut used = vec![false; self.coords.len()];
        cells.iter().flatten().for_each(|&p| used[p] = true);
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (x, _) in self.coords.iter().zip(&used).filter(|(_, u)| **u) {
            for k in 0..2 {
                lo[k] = lo[k].min(scale * x[k]);
                hi[k] = hi[k].max(scale * x[k]);
            }
        }
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let (plane_tol, axis_tol) = (1e-9 * extent, 1e-12 * extent);
        for (p, x) in self.coords.iter().enumerate().filter(|(p, _)| used[*p]) {
            if (scale * x[2]).abs() > plane_tol {
                return Err(err(format!(
                    "node {} has z = {} m: a meridian mesh lies in the x–y plane (|z| ≤ 1e-9 of \
                     its extent, {extent} m)",
                    self.node_tags[p],
                    scale * x[2]
                )));
            }
        }
        for (c, cell) in cells.iter().enumerate() {
            if let Some(&p) = cell
                .iter()
                .find(|&&p| scale * self.coords[p][0] < -axis_tol)
            {
                return Err(err(format!(
                    "element {}: node {} has x = {} m < 0; cells must not cross the axis \
                     (x = R ≥ 0)",
                    cell_tags[c],
                    self.node_tags[p],
                    scale * self.coords[p][0]
                )));
            }
        }
        // compact numbering in file order; nodes within the tolerance of the axis are put on it
        let mut new_index = vec![usize::MAX; self.coords.len()];
        let mut nodes = Vec::new();
        for (p, slot) in new_index.iter_mut().enumerate() {
            if used[p] {
                *slot = nodes.len();
                let [x, y, _] = self.coords[p].map(|v| scale * v);
                nodes.push([if x.abs() <= axis_tol { 0.0 } else { x }, y, 0.0]);
            }
        }
        Ok((nodes, new_index))
    }

    /// The name of physical group (dimension, tag): its own, or `point<tag>`, `curve<tag>`,
    /// `surface<tag>` or `volume<tag>` for a group without a name.
    fn group_name(&self, (d, p): (i32, i32)) -> String {
        self.names.get(&(d, p)).cloned().unwrap_or_else(|| {
            let word = match d {
                0 => "point",
                1 => "curve",
                2 => "surface",
                _ => "volume",
            };
            format!("{word}{p}")
        })
    }

    /// The position of each node tag in `$Nodes`; a tag may appear once.
    fn node_positions(&self, err: &dyn Fn(String) -> GmshError) -> Res<HashMap<u64, usize>> {
        let node_pos: HashMap<u64, usize> = self
            .node_tags
            .iter()
            .enumerate()
            .map(|(i, &t)| (t, i))
            .collect();
        if node_pos.len() != self.node_tags.len() {
            return Err(err("a node tag appears twice in $Nodes".into()));
        }
        Ok(node_pos)
    }

    /// The distinct cells of `elements` (MSH 2.2 repeats an element once per physical group),
    /// their nodes as positions in `$Nodes` in deasim's order, with the groups of all repeats.
    fn unique_cells(
        &self,
        elements: &[Element],
        node_pos: &HashMap<u64, usize>,
        err: &dyn Fn(String) -> GmshError,
    ) -> Res<Cells> {
        let mut cells = Cells {
            nodes: Vec::new(),
            groups: Vec::new(),
            tags: Vec::new(),
        };
        let mut by_nodes: HashMap<Vec<usize>, usize> = HashMap::new();
        for e in elements {
            let mut pos = Vec::with_capacity(e.nodes.len());
            for &t in &e.nodes {
                pos.push(*node_pos.get(&t).ok_or_else(|| {
                    err(format!(
                        "element {} refers to node {t}, which is not in $Nodes",
                        e.tag
                    ))
                })?);
            }
            if e.kind == ElementKind::Tet10 {
                // Gmsh: mid-edge nodes of 0–1, 1–2, 2–0, 0–3, 2–3, 1–3; VTK: …, 1–3, 2–3
                pos.swap(8, 9);
            }
            let mut key = pos.clone();
            key.sort_unstable();
            if key.windows(2).any(|w| w[0] == w[1]) {
                return Err(err(format!("element {} repeats a node", e.tag)));
            }
            let c = *by_nodes.entry(key).or_insert_with(|| {
                cells.nodes.push(pos);
                cells.groups.push(Vec::new());
                cells.tags.push(e.tag);
                cells.nodes.len() - 1
            });
            cells.groups[c].extend(self.groups_of(e.group));
        }
        Ok(cells)
    }

    /// An empty set of each named physical group of dimension `d` (named groups exist even when
    /// empty).
    fn named_sets<T>(&self, d: i32) -> BTreeMap<String, Vec<T>> {
        self.names
            .iter()
            .filter(|(&(gd, _), _)| gd == d)
            .map(|(_, name)| (name.clone(), Vec::new()))
            .collect()
    }

    /// The sets of a mesh whose cells have dimension `dim`: the named groups' (cell sets of
    /// dimension `dim`, face sets of `dim − 1`, point sets of a meridian mesh's points), with
    /// every cell in the cell sets of its groups.
    fn sets(&self, dim: i32, cells: &Cells) -> Sets {
        let mut sets = Sets {
            cells: self.named_sets(dim),
            faces: self.named_sets(dim - 1),
            points: if dim == 2 {
                self.named_sets(0)
            } else {
                BTreeMap::new()
            },
        };
        for (c, gs) in cells.groups.iter().enumerate() {
            for &g in gs {
                sets.cells.entry(self.group_name(g)).or_default().push(c);
            }
        }
        sets
    }
}

/// The cells of a file, one per distinct set of nodes, before renumbering.
struct Cells {
    /// Each cell's nodes as positions in `$Nodes`, in deasim's node order.
    nodes: Vec<Vec<usize>>,
    /// The physical groups (dimension, tag) of each cell.
    groups: Vec<Vec<(i32, i32)>>,
    /// The tag of the element each cell was first read from.
    tags: Vec<u64>,
}

/// The mesh node of each node of the file.
struct Renumbering<'a> {
    /// The position in `$Nodes` of each node tag.
    pos: &'a HashMap<u64, usize>,
    /// The mesh node of each position, `usize::MAX` for a node no cell uses.
    new_index: &'a [usize],
    /// What the cells are: `volume` or `surface` elements.
    cells: &'static str,
}

impl Renumbering<'_> {
    /// The mesh node of node `t` of the `what` element `tag` of physical group `name`.
    fn node(
        &self,
        what: &str,
        tag: u64,
        t: u64,
        name: &str,
        err: &dyn Fn(String) -> GmshError,
    ) -> Res<usize> {
        let p = self.pos.get(&t).ok_or_else(|| {
            err(format!(
                "{what} element {tag} refers to node {t}, which is not in $Nodes"
            ))
        })?;
        match self.new_index[*p] {
            usize::MAX => Err(err(format!(
                "{what} element {tag} of physical group `{name}` has node {t}, which no {} \
                 element uses",
                self.cells
            ))),
            n => Ok(n),
        }
    }
}

/// The named sets of a mesh being built: cell, face and (meridian) point sets.
struct Sets {
    cells: BTreeMap<String, Vec<usize>>,
    faces: BTreeMap<String, Vec<FaceRef>>,
    points: BTreeMap<String, Vec<usize>>,
}

impl Sets {
    /// An error if one name names groups of two kinds; `words` are the kinds of the cell, face
    /// and point sets.
    fn distinct_names(&self, words: [&str; 3], err: &dyn Fn(String) -> GmshError) -> Res<()> {
        let names = [
            self.cells.keys().collect::<Vec<_>>(),
            self.faces.keys().collect(),
            self.points.keys().collect(),
        ];
        for i in 0..3 {
            for j in i + 1..3 {
                if let Some(n) = names[i].iter().find(|n| names[j].contains(n)) {
                    return Err(err(format!(
                        "the physical name `{n}` names both a {} and a {} group",
                        words[i], words[j]
                    )));
                }
            }
        }
        Ok(())
    }

    /// The mesh with these sets, each sorted and without repeats; its node sets are the point
    /// sets and the nodes of every face set and cell set.
    fn mesh(
        mut self,
        kind: ElementKind,
        nodes: Vec<[f64; 3]>,
        connectivity: Vec<usize>,
        reoriented: usize,
        format: &str,
    ) -> GmshMesh {
        self.cells
            .values_mut()
            .chain(self.points.values_mut())
            .for_each(|s| {
                s.sort_unstable();
                s.dedup();
            });
        self.faces.values_mut().for_each(|s| {
            s.sort_unstable();
            s.dedup();
        });
        let mut mesh = Mesh {
            kind,
            nodes,
            connectivity,
            node_sets: self.points,
            face_sets: self.faces,
            cell_sets: self.cells,
        };
        mesh.insert_face_set_nodes();
        for (name, cells) in &mesh.cell_sets {
            let mut n: Vec<usize> = cells.iter().flat_map(|&c| mesh.cell(c).to_vec()).collect();
            n.sort_unstable();
            n.dedup();
            mesh.node_sets.insert(name.clone(), n);
        }
        GmshMesh {
            mesh,
            reoriented,
            format: format.into(),
        }
    }
}

/// An error unless all `elements` (at least one) are of one kind; `what` they are: `volume` or
/// `surface` elements.
fn one_kind(elements: &[Element], what: &str, err: &dyn Fn(String) -> GmshError) -> Res<()> {
    let first = &elements[0];
    match elements.iter().find(|e| e.kind != first.kind) {
        Some(o) => Err(err(format!(
            "mixed {what} element kinds: {} (element {}) and {} (element {}); deasim needs one \
             kind per mesh",
            first.kind.name(),
            first.tag,
            o.kind.name(),
            o.tag
        ))),
        None => Ok(()),
    }
}

/// The connectivity of `cells` in the mesh's node numbers (`new_index` of their positions, at
/// `nodes`), inverted cells mirrored, and how many were; a degenerate cell is an error.
fn oriented(
    kind: ElementKind,
    cells: &Cells,
    new_index: &[usize],
    nodes: &[[f64; 3]],
    err: &dyn Fn(String) -> GmshError,
) -> Res<(Vec<usize>, usize)> {
    let npc = kind.nodes_per_cell();
    let mut connectivity = Vec::with_capacity(cells.nodes.len() * npc);
    let mut reoriented = 0;
    let mut x = vec![[0.0; 3]; npc];
    for (cell, tag) in cells.nodes.iter().zip(&cells.tags) {
        let mut ids: Vec<usize> = cell.iter().map(|&p| new_index[p]).collect();
        for (xa, &n) in x.iter_mut().zip(&ids) {
            *xa = nodes[n];
        }
        let det = orientation(kind, &x);
        if det.is_nan() || det == 0.0 {
            return Err(err(match kind {
                ElementKind::Meridian(_) => {
                    format!("surface element {tag} is degenerate (zero area)")
                }
                _ => format!("volume element {tag} is degenerate (zero volume)"),
            }));
        }
        if det < 0.0 {
            ids = mirror(kind).iter().map(|&l| ids[l]).collect();
            reoriented += 1;
        }
        connectivity.extend_from_slice(&ids);
    }
    Ok((connectivity, reoriented))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::{ReferenceElement, TET10_EDGES};

    fn data(name: &str) -> Vec<u8> {
        let p = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/gmsh")
            .join(name);
        std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
    }

    fn parse(text: &str) -> Result<GmshMesh, GmshError> {
        parse_msh(text.as_bytes(), "t.msh", 1.0)
    }

    const FORMATS: [&str; 3] = ["msh41", "msh41-bin", "msh22"];

    /// Every film file: the kind, a 10 × 10 × 1 mm volume, the named sets on their planes, the
    /// same mesh whatever the format.
    #[test]
    fn film_files_written_by_gmsh() {
        for (kind, name) in [
            (ElementKind::Tet4, "tet4"),
            (ElementKind::Tet10, "tet10"),
            (ElementKind::Hex8, "hex8"),
        ] {
            let mut first: Option<Mesh> = None;
            for f in FORMATS {
                let file = format!("film-{name}-{f}.msh");
                let g = parse_msh(&data(&file), &file, 1e-3).unwrap();
                let m = &g.mesh;
                assert_eq!(m.kind, kind, "{file}");
                assert_eq!(g.reoriented, 0, "{file}");
                let re = ReferenceElement::new(kind);
                let mut x = vec![[0.0; 3]; kind.nodes_per_cell()];
                let mut vol = 0.0;
                for c in 0..m.n_cells() {
                    m.cell_coords_into(c, &mut x);
                    let geom = re.geometry(&x).expect("positive Jacobian");
                    vol += geom.weights[..geom.n_qp].iter().sum::<f64>();
                    if kind == ElementKind::Tet10 {
                        for (e, [i, j]) in TET10_EDGES.iter().enumerate() {
                            for k in 0..3 {
                                let mid = 0.5 * (x[*i][k] + x[*j][k]);
                                assert!((x[4 + e][k] - mid).abs() < 1e-12, "{file} cell {c}");
                            }
                        }
                    }
                }
                assert!((vol - 1e-7).abs() < 1e-18, "{file}: volume {vol}");
                assert_eq!(m.cell_sets["elastomer"].len(), m.n_cells(), "{file}");
                assert_eq!(m.node_sets["elastomer"].len(), m.n_nodes(), "{file}");
                for (set, axis, value) in [
                    ("x0", 0, 0.0),
                    ("x1", 0, 10e-3),
                    ("y0", 1, 0.0),
                    ("y1", 1, 10e-3),
                    ("z0", 2, 0.0),
                    ("z1", 2, 1e-3),
                ] {
                    let on: Vec<usize> = (0..m.n_nodes())
                        .filter(|&n| (m.nodes[n][axis] - value).abs() < 1e-12)
                        .collect();
                    assert_eq!(m.node_sets[set], on, "{file} {set}");
                    assert_eq!(m.face_set_nodes(set).unwrap(), on, "{file} {set}");
                }
                assert_eq!(m.face_sets["top"], m.face_sets["z1"]);
                assert_eq!(m.face_sets["bottom"], m.face_sets["z0"]);
                match &first {
                    None => first = Some(m.clone()),
                    Some(a) => {
                        // ASCII files hold 16 significant digits
                        for (p, q) in a.nodes.iter().zip(&m.nodes) {
                            for k in 0..3 {
                                assert!((p[k] - q[k]).abs() < 1e-17, "{file}");
                            }
                        }
                        assert_eq!(a.nodes.len(), m.nodes.len(), "{file}");
                        assert_eq!(a.connectivity, m.connectivity, "{file}");
                        assert_eq!(a.face_sets, m.face_sets, "{file}");
                    }
                }
            }
        }
    }

    /// Every prefix of the files (binary and ASCII) is an error, never a panic; so is every
    /// single-byte corruption of the binary file (or it still reads).
    #[test]
    fn truncated_and_corrupted_files_are_errors() {
        for file in [
            "film-tet10-msh41-bin.msh",
            "film-hex8-msh41.msh",
            "film-tet4-msh22.msh",
        ] {
            let d = data(file);
            for len in 0..d.len() - 14 {
                let r = parse_msh(&d[..len], file, 1.0);
                assert!(r.is_err(), "{file}: prefix of {len} bytes read");
            }
        }
        let d = data("film-tet4-msh41-bin.msh");
        for i in 0..d.len() {
            for v in [0u8, 0xff, b'$', b'\n'] {
                let mut c = d.clone();
                c[i] = v;
                let _ = parse_msh(&c, "c.msh", 1.0);
            }
        }
    }

    fn replace_in(file: &str, from: &str, to: &str) -> String {
        let text = String::from_utf8(data(file)).unwrap();
        assert!(text.contains(from), "{file} has no `{from}`");
        text.replacen(from, to, 1)
    }

    #[track_caller]
    fn err_of(text: &str) -> String {
        match parse(text) {
            Ok(_) => panic!("read without error"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn bad_files_give_clear_errors() {
        // the hex8 volume block `3 1 5 18` with a 20-node hexahedron type
        let e = err_of(&replace_in(
            "film-hex8-msh41.msh",
            "\n3 1 5 18\n",
            "\n3 1 17 18\n",
        ));
        assert!(e.contains("line ") && e.contains("type 17"), "{e}");
        let e = err_of(&replace_in(
            "film-hex8-msh41.msh",
            "\n3 1 5 18\n",
            "\n3 1 99 18\n",
        ));
        assert!(e.contains("unknown element type 99"), "{e}");
        let e = err_of(&replace_in("film-tet4-msh41.msh", "4.1 0 8", "4.0 0 8"));
        assert!(e.contains("line 2: unsupported MSH version `4.0`"), "{e}");
        let text = String::from_utf8(data("film-tet4-msh22.msh")).unwrap();
        let e = err_of(&text.replace("Elements", "Elephants"));
        assert!(e.contains("no $Elements section"), "{e}");
        let e = err_of(&replace_in(
            "film-tet4-msh22.msh",
            "\n1 0 0 1\n",
            "\n1 0 zero 1\n",
        ));
        assert!(
            e.contains("line 18: expected a y coordinate in $Nodes, found `zero`"),
            "{e}"
        );
        // a node line dropped: the count claims one more than there is
        let e = err_of(&replace_in("film-tet4-msh22.msh", "\n1 0 0 1\n", "\n"));
        assert!(e.contains("truncated $Nodes section"), "{e}");
        let e = err_of(&replace_in(
            "film-tet4-msh22.msh",
            "$MeshFormat",
            "$MeshFormats",
        ));
        assert!(
            e.contains("expected `$MeshFormat` first") || e.contains("no end marker"),
            "{e}"
        );
        // binary: the element block header cut short
        let d = data("film-hex8-msh41-bin.msh");
        let at = d.windows(9).position(|w| w == b"$Elements").unwrap() + 30;
        let e = parse_msh(&d[..at], "b.msh", 1.0).unwrap_err().to_string();
        assert!(e.contains("byte ") && e.contains("truncated"), "{e}");
    }

    /// The heads of the MSH 4.1 `$Nodes` and `$Elements` sections: every number is named.
    #[test]
    fn section_heads_of_msh41_name_each_number() {
        let f = "film-tet4-msh41.msh";
        for (from, to, message) in [
            (
                "$Nodes\n23 ",
                "$Nodes\nx ",
                "the number of entity blocks in $Nodes",
            ),
            (
                "$Nodes\n23 24 ",
                "$Nodes\n23 x ",
                "the number of nodes in $Nodes",
            ),
            (
                "\n23 24 1 ",
                "\n23 24 x ",
                "the smallest node tag in $Nodes",
            ),
            (
                "\n23 24 1 24\n",
                "\n23 24 1 x\n",
                "the largest node tag in $Nodes",
            ),
            ("\n7 86 ", "\n7 x ", "the number of elements in $Elements"),
            (
                "\n7 86 1 ",
                "\n7 86 x ",
                "the smallest element tag in $Elements",
            ),
            (
                "\n7 86 1 86\n",
                "\n7 86 1 x\n",
                "the largest element tag in $Elements",
            ),
        ] {
            let e = err_of(&replace_in(f, from, to));
            assert!(e.contains(&format!("expected {message}")), "{e}");
        }
    }

    /// The checks the 3-D and the meridian builders share, as the 3-D reader words them, and the
    /// names of unnamed groups.
    #[test]
    fn shared_checks_of_a_3d_file() {
        let file = |names: &str, nodes: &str, elements: &[&str]| {
            let n = names.lines().count();
            let m = nodes.lines().count();
            format!(
                "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n{n}\n{names}\
                 $EndPhysicalNames\n$Nodes\n{m}\n{nodes}$EndNodes\n$Elements\n{}\n{}\n\
                 $EndElements\n",
                elements.len(),
                elements.join("\n")
            )
        };
        let nodes = "1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 0\n";
        let tet = "1 4 2 3 1 1 2 3 4";
        let e = err_of(&file("", &nodes.replace("5 1 1 0", "1 1 1 0"), &[tet]));
        assert!(
            e.contains("t.msh: a node tag appears twice in $Nodes"),
            "{e}"
        );
        let e = err_of(&file("", nodes, &["1 4 2 3 1 1 2 3 9"]));
        assert!(
            e.contains("t.msh: element 1 refers to node 9, which is not in $Nodes"),
            "{e}"
        );
        let e = err_of(&file("", nodes, &["1 4 2 3 1 1 2 3 5"]));
        assert!(
            e.contains("t.msh: volume element 1 is degenerate (zero volume)"),
            "{e}"
        );
        let e = err_of(&file("", nodes, &[tet, "2 2 2 4 1 1 2 8"]));
        assert!(
            e.contains("t.msh: surface element 2 refers to node 8, which is not in $Nodes"),
            "{e}"
        );
        let e = err_of(&file(
            "3 3 \"top\"\n2 4 \"top\"\n",
            nodes,
            &[tet, "2 2 2 4 1 1 2 3"],
        ));
        assert!(
            e.contains("t.msh: the physical name `top` names both a volume and a surface group"),
            "{e}"
        );
        // unnamed groups; a named one without elements; the node sets of cell and face sets
        let g = parse(&file(
            "2 6 \"side\"\n",
            nodes,
            &[tet, "2 2 2 4 1 1 2 4", "3 2 2 4 1 2 3 4"],
        ))
        .unwrap();
        let m = &g.mesh;
        assert_eq!(m.cell_sets.keys().collect::<Vec<_>>(), ["volume3"]);
        assert_eq!(m.cell_sets["volume3"], [0]);
        assert_eq!(m.face_sets.keys().collect::<Vec<_>>(), ["side", "surface4"]);
        assert!(m.face_sets["side"].is_empty());
        assert_eq!(m.face_sets["surface4"].len(), 2);
        assert_eq!(m.node_sets["volume3"], [0, 1, 2, 3]);
        assert_eq!(m.node_sets["surface4"], [0, 1, 2, 3]);
        assert_eq!(m.node_sets["side"], Vec::<usize>::new());
    }

    /// A tetrahedron and a hexahedron in one file; an inverted tetrahedron; a face not on a cell.
    #[test]
    fn mixed_inverted_and_stray_faces() {
        let head = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 7 \"top\"\n\
                    $EndPhysicalNames\n$Nodes\n9\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 0\n\
                    6 0 1 1\n7 1 0 1\n8 1 1 1\n9 5 5 5\n$EndNodes\n";
        let e = err_of(&format!(
            "{head}$Elements\n2\n1 4 0 1 2 3 4\n2 5 0 1 2 5 3 4 7 8 6\n$EndElements\n"
        ));
        assert!(
            e.contains("mixed volume element kinds: tet4 (element 1) and hex8 (element 2)"),
            "{e}"
        );
        let g = parse(&format!(
            "{head}$Elements\n1\n1 4 0 1 3 2 4\n$EndElements\n"
        ))
        .unwrap();
        assert_eq!(g.reoriented, 1);
        assert_eq!(g.mesh.cell(0), &[0, 1, 2, 3]);
        assert_eq!(g.mesh.n_nodes(), 4, "unused nodes dropped");
        let e = err_of(&format!(
            "{head}$Elements\n2\n1 4 0 1 2 3 4\n2 2 2 7 1 1 2 9\n$EndElements\n"
        ));
        assert!(
            e.contains("surface element 2 of physical group `top` has node 9"),
            "{e}"
        );
        let e = err_of(&format!(
            "{head}$Elements\n2\n1 5 0 1 2 5 3 4 7 8 6\n2 2 2 7 1 1 2 8\n$EndElements\n"
        ));
        assert!(
            e.contains("surface element 2 of physical group `top` is not a face of a hex8"),
            "{e}"
        );
        let g = parse(&format!(
            "{head}$Elements\n2\n1 4 0 1 2 3 4\n2 2 2 7 1 4 3 2\n$EndElements\n"
        ))
        .unwrap();
        assert_eq!(g.mesh.face_sets["top"], vec![FaceRef { cell: 0, face: 2 }]);
        // an inverted hexahedron and an inverted tet10 are mirrored to positive cells
        let hex = parse(&format!(
            "{head}$Elements\n1\n1 5 0 4 7 8 6 1 2 5 3\n$EndElements\n"
        ))
        .unwrap();
        assert_eq!(hex.reoriented, 1);
        let mut x = vec![[0.0; 3]; 8];
        hex.mesh.cell_coords_into(0, &mut x);
        assert!(ReferenceElement::new(ElementKind::Hex8)
            .geometry(&x)
            .is_ok());
    }
    /// Messages quote at most 40 bytes of a token or line: a cut inside a multi-byte character
    /// (`é` straddling byte 40) is an error, not a panic; so are random bytes and random mixtures
    /// of section headers, numbers and non-ASCII text (fixed seed; `DEASIM_MSH_CASES` sets the
    /// count, default 4000).
    #[test]
    fn multibyte_cuts_and_random_bytes_are_errors() {
        let long = format!("{}é{}", "x".repeat(39), "y".repeat(10));
        assert!(!long.is_char_boundary(40));
        let inputs = [
            long.clone(),
            format!("{long}\n$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"),
            format!("${long}"),
            format!(
                "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 7 {long}\n\
                 $EndPhysicalNames\n"
            ),
            format!("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n{long}\n"),
            format!("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n{long}\n$EndNodes\n"),
            format!("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n0\n{long}\n"),
        ];
        for text in &inputs {
            let e = parse(text).expect_err(text).to_string();
            assert!(!e.is_empty());
        }
        let cases: usize = std::env::var("DEASIM_MSH_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(4000);
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let words: [&[u8]; 16] = [
            b"$MeshFormat\n",
            b"2.2 0 8\n",
            b"4.1 1 8\n",
            b"$EndMeshFormat\n",
            b"$PhysicalNames\n",
            b"$EndPhysicalNames\n",
            b"$Nodes\n",
            b"$EndNodes\n",
            b"$Elements\n",
            b"$EndElements\n",
            b"$Entities\n",
            b"1 ",
            b"3 ",
            b"\"n\xc3\xa9\" ",
            "xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxé".as_bytes(),
            b"\n",
        ];
        for case in 0..cases {
            let len = (next() % 300) as usize;
            let mut d = Vec::with_capacity(len * 4);
            if case % 2 == 0 {
                // raw bytes
                d.extend((0..len).map(|_| next() as u8));
            } else {
                // tokens, with the odd random byte
                d.extend_from_slice(b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n");
                for _ in 0..len / 4 {
                    let r = next();
                    if r % 7 == 0 {
                        d.push((r >> 8) as u8);
                    } else {
                        d.extend_from_slice(words[(r >> 8) as usize % words.len()]);
                    }
                }
            }
            let m = std::panic::catch_unwind(|| parse_msh_meridian(&d, "r.msh", 1.0));
            assert!(m.is_ok(), "case {case} panicked (meridian)");
            let r = std::panic::catch_unwind(|| parse_msh(&d, "r.msh", 1.0));
            match r {
                Ok(r) => assert!(r.is_err(), "case {case} read as a mesh"),
                Err(_) => panic!("case {case} panicked on {:?}", String::from_utf8_lossy(&d)),
            }
        }
    }

    // ---- meridian (2-D) meshes ----

    use crate::fem::axisymmetric::meridian_geometry;

    /// The meridian R ∈ [0, 2], Z ∈ [0, 1] of a 2 × 1 quad4 grid, written by Gmsh 4.15 (MSH 4.1
    /// ASCII): curves `axis`, `bottom`, `top`, `outer`, surface `film`, point `corner` at (2, 0).
    const RECT_QUAD4_MSH41: &str = r#"$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
6
0 6 "corner"
1 1 "axis"
1 2 "bottom"
1 3 "top"
1 4 "outer"
2 5 "film"
$EndPhysicalNames
$Entities
4 4 1 0
1 0 0 0 0
2 2 0 0 1 6
3 2 1 0 0
4 0 1 0 0
1 0 0 0 2 0 0 1 2 2 1 -2
2 2 0 0 2 1 0 1 4 2 2 -3
3 0 1 0 2 1 0 1 3 2 3 -4
4 0 0 0 0 1 0 1 1 2 4 -1
1 0 0 0 2 1 0 1 5 4 1 2 3 4
$EndEntities
$Nodes
9 6 1 6
0 1 0 1
1
0 0 0
0 2 0 1
2
2 0 0
0 3 0 1
3
2 1 0
0 4 0 1
4
0 1 0
1 1 0 1
5
0.9999999999973842 0 0
1 2 0 0
1 3 0 1
6
1.000000000004119 1 0
1 4 0 0
2 1 0 0
$EndNodes
$Elements
6 9 1 9
0 2 15 1
1 2
1 1 1 2
2 1 5
3 5 2
1 2 1 1
4 2 3
1 3 1 2
5 3 6
6 6 4
1 4 1 1
7 4 1
2 1 3 2
8 1 5 6 4
9 5 2 3 6
$EndElements
"#;

    /// The same rectangle in four tri6 cells, written by Gmsh 4.15 (MSH 2.2 ASCII).
    const RECT_TRI6_MSH22: &str = r#"$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
6
0 6 "corner"
1 1 "axis"
1 2 "bottom"
1 3 "top"
1 4 "outer"
2 5 "film"
$EndPhysicalNames
$Nodes
15
1 0 0 0
2 2 0 0
3 2 1 0
4 0 1 0
5 0.9999999999973842 0 0
6 0.4999999999988369 0 0
7 1.499999999998692 0 0
8 2 0.4999999999986718 0
9 1.000000000004119 1 0
10 1.50000000000152 1 0
11 0.5000000000020595 1 0
12 0 0.5000000000013304 0
13 0.4999999999986921 0.5 0
14 1.000000000000752 0.5 0
15 1.500000000002059 0.5 0
$EndNodes
$Elements
11
1 15 2 6 2 2
2 8 2 2 1 1 5 6
3 8 2 2 1 5 2 7
4 8 2 4 2 2 3 8
5 8 2 3 3 3 9 10
6 8 2 3 3 9 4 11
7 8 2 1 4 4 1 12
8 9 2 5 1 1 5 4 6 13 12
9 9 2 5 1 4 5 9 13 14 11
10 9 2 5 1 5 2 9 7 15 14
11 9 2 5 1 9 2 3 15 8 10
$EndElements
"#;

    fn meridian(text: &str) -> Result<GmshMesh, GmshError> {
        parse_msh_meridian(text.as_bytes(), "m.msh", 1.0)
    }

    #[track_caller]
    fn meridian_err(text: &str) -> String {
        match meridian(text) {
            Ok(_) => panic!("read without error"),
            Err(e) => e.to_string(),
        }
    }

    /// The sum of the ring weights 2πR·w·det J of every cell: the volume of the solid of
    /// revolution (m³).
    fn ring_volume(m: &Mesh) -> f64 {
        let k = m.kind.meridian().expect("a meridian mesh");
        let mut x = vec![[0.0; 2]; k.nodes_per_cell()];
        (0..m.n_cells())
            .map(|c| {
                for (xa, &n) in x.iter_mut().zip(m.cell(c)) {
                    *xa = [m.nodes[n][0], m.nodes[n][1]];
                }
                let g = meridian_geometry(k, &x).expect("a valid meridian cell");
                g.weights[..g.n_qp].iter().sum::<f64>()
            })
            .sum()
    }

    /// The sets of the rectangle R ∈ [0, 2], Z ∈ [0, 1]: each curve's nodes are the nodes on its
    /// line (the axis ones at exactly R = 0), `film` holds every cell and node, `corner` the
    /// node at (2, 0); every side of a face set lies on its line; the ring volume is π R² H.
    #[track_caller]
    fn check_rectangle(m: &Mesh, what: &str) {
        let vol = ring_volume(m);
        let exact = std::f64::consts::PI * 4.0;
        assert!((vol - exact).abs() < 1e-12 * exact, "{what}: volume {vol}");
        assert_eq!(m.cell_sets["film"], (0..m.n_cells()).collect::<Vec<_>>());
        assert_eq!(m.node_sets["film"].len(), m.n_nodes(), "{what}");
        assert!(m.nodes.iter().all(|x| x[2] == 0.0 && x[0] >= 0.0), "{what}");
        let on = |axis: usize, value: f64| -> Vec<usize> {
            (0..m.n_nodes())
                .filter(|&n| (m.nodes[n][axis] - value).abs() < 1e-9)
                .collect()
        };
        for (set, axis, value) in [
            ("axis", 0, 0.0),
            ("bottom", 1, 0.0),
            ("top", 1, 1.0),
            ("outer", 0, 2.0),
        ] {
            let nodes = on(axis, value);
            assert_eq!(m.node_sets[set], nodes, "{what} {set}");
            assert_eq!(m.face_set_nodes(set).unwrap(), nodes, "{what} {set}");
            assert!(!m.face_sets[set].is_empty(), "{what} {set}");
        }
        assert!(m.node_sets["axis"].iter().all(|&n| m.nodes[n][0] == 0.0));
        let corner = m.node_sets["corner"].clone();
        assert_eq!(corner.len(), 1, "{what}");
        assert_eq!(m.nodes[corner[0]], [2.0, 0.0, 0.0], "{what}");
    }

    /// Straight sides: the mid-side nodes of quad8, quad9 and tri6 cells sit at the midpoints of
    /// their sides in MeridianKind's order (sides 0–1, 1–2, 2–3, 3–0, then the centre), which is
    /// Gmsh's; every cell is counter-clockwise.
    #[track_caller]
    fn check_node_order(m: &Mesh, what: &str) {
        let k = m.kind.meridian().unwrap();
        let sides = k.sides();
        let corners = sides.len();
        for c in 0..m.n_cells() {
            let x: Vec<[f64; 3]> = m.cell(c).iter().map(|&n| m.nodes[n]).collect();
            assert!(orientation(m.kind, &x) > 0.0, "{what} cell {c}");
            if !k.is_quadratic() {
                continue;
            }
            for (s, side) in sides.iter().enumerate() {
                assert_eq!(side[2], corners + s, "{what}");
                for i in 0..2 {
                    let mid = 0.5 * (x[side[0]][i] + x[side[1]][i]);
                    assert!(
                        (x[side[2]][i] - mid).abs() < 1e-9,
                        "{what} cell {c} side {s}"
                    );
                }
            }
            if k == MeridianKind::Quad9 {
                for i in 0..2 {
                    let centre = x[..4].iter().map(|p| p[i]).sum::<f64>() / 4.0;
                    assert!((x[8][i] - centre).abs() < 1e-9, "{what} cell {c}");
                }
            }
        }
    }

    /// Every meridian file written by Gmsh (tests/data/gmsh/meridian.geo: quad4, quad8, quad9,
    /// tri3, tri6 in MSH 4.1 ASCII, 4.1 binary and 2.2 ASCII): the kind, the sets on their lines,
    /// the ring volume π R² H, Gmsh's node order, the same mesh whatever the format.
    #[test]
    fn meridian_files_written_by_gmsh() {
        for kind in MeridianKind::ALL {
            let mut first: Option<Mesh> = None;
            for f in FORMATS {
                let file = format!("meridian-{}-{f}.msh", kind.name());
                let g = parse_msh_meridian(&data(&file), &file, 1.0).unwrap();
                let m = &g.mesh;
                assert_eq!(m.kind, ElementKind::Meridian(kind), "{file}");
                assert_eq!(g.reoriented, 0, "{file}");
                if !matches!(kind, MeridianKind::Tri3 | MeridianKind::Tri6) {
                    assert_eq!(m.n_cells(), 8, "{file}");
                }
                check_rectangle(m, &file);
                check_node_order(m, &file);
                match &first {
                    None => first = Some(m.clone()),
                    Some(a) => {
                        assert_eq!(a.nodes.len(), m.nodes.len(), "{file}");
                        for (p, q) in a.nodes.iter().zip(&m.nodes) {
                            for k in 0..3 {
                                assert!((p[k] - q[k]).abs() < 1e-15, "{file}");
                            }
                        }
                        assert_eq!(a.connectivity, m.connectivity, "{file}");
                        assert_eq!(a.face_sets, m.face_sets, "{file}");
                        assert_eq!(a.node_sets, m.node_sets, "{file}");
                    }
                }
                // read as a 3-D mesh: a clear error
                let e = parse_msh(&data(&file), &file, 1.0).unwrap_err().to_string();
                assert!(
                    e.contains("only surface elements") && e.contains("2-D mesh"),
                    "{e}"
                );
            }
        }
    }

    /// The MSH 4.1 quad4 and MSH 2.2 tri6 strings: counts, kinds, sets, ring volume, scale.
    #[test]
    fn meridian_strings_in_msh41_and_msh22() {
        let g = meridian(RECT_QUAD4_MSH41).unwrap();
        assert_eq!(g.format, "4.1 ASCII");
        let m = &g.mesh;
        assert_eq!(m.kind, ElementKind::Meridian(MeridianKind::Quad4));
        assert_eq!((m.n_cells(), m.n_nodes()), (2, 6));
        check_rectangle(m, "quad4");
        // the bottom's sides are side 0 of both cells, the axis side 3 of the first
        assert_eq!(
            m.face_sets["bottom"],
            vec![FaceRef { cell: 0, face: 0 }, FaceRef { cell: 1, face: 0 }]
        );
        assert_eq!(m.face_sets["axis"], vec![FaceRef { cell: 0, face: 3 }]);
        let g = meridian(RECT_TRI6_MSH22).unwrap();
        assert_eq!(g.format, "2.2 ASCII");
        let m = &g.mesh;
        assert_eq!(m.kind, ElementKind::Meridian(MeridianKind::Tri6));
        assert_eq!((m.n_cells(), m.n_nodes()), (4, 15));
        check_rectangle(m, "tri6");
        check_node_order(m, "tri6");
        // drawn in mm: the volume scales with the cube
        let g = parse_msh_meridian(RECT_TRI6_MSH22.as_bytes(), "mm.msh", 1e-3).unwrap();
        let v = ring_volume(&g.mesh);
        assert!((v - 4e-9 * std::f64::consts::PI).abs() < 1e-12 * v, "{v}");
    }

    /// A 2.2 file: nodes (tag i + 1), the names `axis` (curve 1), `bottom` (curve 2), `film`
    /// (surface 5), and the element lines.
    fn msh22(nodes: &[[f64; 3]], elements: &[&str]) -> String {
        let mut t = String::from(
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n3\n1 1 \"axis\"\n\
             1 2 \"bottom\"\n2 5 \"film\"\n$EndPhysicalNames\n$Nodes\n",
        );
        t += &format!("{}\n", nodes.len());
        for (i, x) in nodes.iter().enumerate() {
            t += &format!("{} {:e} {:e} {:e}\n", i + 1, x[0], x[1], x[2]);
        }
        t += &format!("$EndNodes\n$Elements\n{}\n", elements.len());
        for e in elements {
            t += e;
            t += "\n";
        }
        t + "$EndElements\n"
    }

    /// The unit square [0, 1]² with corners 1–4 counter-clockwise from the origin.
    const SQUARE: [[f64; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];

    /// A clockwise cell is mirrored (and counted); its sides are matched after the mirroring.
    #[test]
    fn clockwise_meridian_cells_are_reoriented() {
        let g = meridian(&msh22(
            &SQUARE,
            &["1 3 2 5 1 1 4 3 2", "2 1 2 2 1 2 1", "3 1 2 1 1 4 1"],
        ))
        .unwrap();
        assert_eq!(g.reoriented, 1);
        assert_eq!(g.mesh.cell(0), &[0, 1, 2, 3]);
        assert_eq!(
            g.mesh.face_sets["bottom"],
            vec![FaceRef { cell: 0, face: 0 }]
        );
        assert_eq!(g.mesh.face_sets["axis"], vec![FaceRef { cell: 0, face: 3 }]);
        let v = ring_volume(&g.mesh);
        assert!((v - std::f64::consts::PI).abs() < 1e-12, "{v}");
        // a clockwise tri6: the triangle (0, 0), (1, 0), (0, 1) given as 1, 3, 2 (and mid-sides)
        let mut nodes = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        nodes.extend([[0.5, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.5, 0.0]]);
        let g = meridian(&msh22(&nodes, &["1 9 2 5 1 1 3 2 6 5 4"])).unwrap();
        assert_eq!(g.reoriented, 1);
        check_node_order(&g.mesh, "tri6");
        let v = ring_volume(&g.mesh);
        // ∫ 2πR dA over the triangle 0 ≤ R, 0 ≤ Z ≤ 1 − R: 2π/6
        assert!((v - std::f64::consts::PI / 3.0).abs() < 1e-12, "{v}");
    }

    /// The axis: a node a hair off it is put on it; one at x < 0 is an error; so is z ≠ 0.
    #[test]
    fn the_axis_and_the_plane_are_checked() {
        for x in [1e-17, -1e-17] {
            let mut nodes = SQUARE;
            nodes[3][0] = x;
            let g = meridian(&msh22(&nodes, &["1 3 2 5 1 1 2 3 4"])).unwrap();
            assert_eq!(g.mesh.nodes[3][0].to_bits(), 0.0f64.to_bits(), "{x}");
        }
        let mut nodes = SQUARE;
        nodes[3][0] = -1e-3;
        let e = meridian_err(&msh22(&nodes, &["7 3 2 5 1 1 2 3 4"]));
        assert!(
            e.starts_with("m.msh: element 7: node 4 has x = -0.001 m < 0")
                && e.contains("cells must not cross the axis (x = R ≥ 0)"),
            "{e}"
        );
        let mut nodes = SQUARE;
        nodes[2][2] = 1e-3;
        let e = meridian_err(&msh22(&nodes, &["1 3 2 5 1 1 2 3 4"]));
        assert!(
            e.starts_with("m.msh: node 3 has z = 0.001 m") && e.contains("x–y plane"),
            "{e}"
        );
        // within 1e-9 of the extent, z is dropped
        let mut nodes = SQUARE;
        nodes[2][2] = 1e-10;
        let g = meridian(&msh22(&nodes, &["1 3 2 5 1 1 2 3 4"])).unwrap();
        assert!(g.mesh.nodes.iter().all(|x| x[2] == 0.0));
    }

    #[test]
    fn bad_meridian_files_give_clear_errors() {
        let mut nodes = SQUARE.to_vec();
        nodes.push([0.5, 0.0, 0.0]);
        let quad = "1 3 2 5 1 1 2 3 4";
        let e = meridian_err(&msh22(&nodes, &[quad, "2 2 2 5 1 1 2 4"]));
        assert!(
            e.contains(
                "m.msh: mixed surface element kinds: quad4 (element 1) and tri3 (element 2)"
            ),
            "{e}"
        );
        let e = meridian_err(&msh22(&nodes, &["2 1 2 2 1 1 2"]));
        assert!(e.contains("m.msh: no surface elements"), "{e}");
        let e = meridian_err(&msh22(&nodes, &[quad, "2 4 2 5 1 1 2 3 5"]));
        assert!(
            e.contains("element 2 is a 4-node tetrahedron: a 3-D mesh"),
            "{e}"
        );
        let e = meridian_err(&msh22(&nodes, &[quad, "2 8 2 2 1 1 2 5"]));
        assert!(
            e.contains("curve element 2 of physical group `bottom` is a 3-node line, but the cells are quad4"),
            "{e}"
        );
        let e = meridian_err(&msh22(&nodes, &[quad, "2 1 2 2 1 1 3"]));
        assert!(
            e.contains("curve element 2 of physical group `bottom` is not a side of a quad4"),
            "{e}"
        );
        let e = meridian_err(&msh22(&nodes, &[quad, "2 1 2 2 1 1 5"]));
        assert!(
            e.contains("has node 5, which no surface element uses"),
            "{e}"
        );
        let e = meridian_err(&msh22(&nodes, &["1 3 2 5 1 1 2 2 4"]));
        assert!(e.contains("element 1 repeats a node"), "{e}");
        let e = meridian_err(&msh22(&nodes, &["1 3 2 5 1 1 2 5 1"]));
        assert!(e.contains("repeats a node"), "{e}");
        let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        let e = meridian_err(&msh22(&flat, &["1 2 2 5 1 1 2 3"]));
        assert!(e.contains("surface element 1 is degenerate"), "{e}");
        let e = meridian_err(&msh22(&nodes, &["1 20 2 5 1 1 2 3 4 5 1 2 3 4"]));
        assert!(
            e.contains("type 20 (9-node triangle) is not supported"),
            "{e}"
        );
        let e = meridian_err(&msh22(&nodes, &[quad]).replace("\"bottom\"", "\"film\""));
        assert!(
            e.contains("the physical name `film` names both a surface and a curve group"),
            "{e}"
        );
        // a tri6 whose line's middle node is not the side's
        let mut tri = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        tri.extend([[0.5, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.5, 0.0]]);
        let e = meridian_err(&msh22(&tri, &["1 9 2 5 1 1 2 3 4 5 6", "2 8 2 2 1 1 2 5"]));
        assert!(
            e.contains("its middle node 5 is not the mid-side node"),
            "{e}"
        );
        // MSH 4.1: a 9-node triangle block
        let e = meridian_err(&RECT_QUAD4_MSH41.replace("\n2 1 3 2\n", "\n2 1 20 2\n"));
        assert!(e.contains("line ") && e.contains("type 20"), "{e}");
    }

    /// Every prefix of meridian files is an error for the meridian reader, never a panic; so is
    /// every single-byte corruption of a binary one (or it still reads).
    #[test]
    fn truncated_and_corrupted_meridian_files_are_errors() {
        for file in ["meridian-quad9-msh41-bin.msh", "meridian-tri6-msh22.msh"] {
            let d = data(file);
            for len in 0..d.len() - 14 {
                let r = parse_msh_meridian(&d[..len], file, 1.0);
                assert!(r.is_err(), "{file}: prefix of {len} bytes read");
            }
        }
        let d = data("meridian-quad8-msh41-bin.msh");
        for i in 0..d.len() {
            for v in [0u8, 0xff, b'$', b'\n'] {
                let mut c = d.clone();
                c[i] = v;
                let _ = parse_msh_meridian(&c, "c.msh", 1.0);
            }
        }
    }
}
