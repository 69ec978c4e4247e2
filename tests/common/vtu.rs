//! A reader for the `.vtu` and `.pvtu` files deasim writes, for the integration tests: exactly
//! the subset of VTK XML UnstructuredGrid that `deasim::io::vtu` writes (one piece; ascii, binary
//! or zlib-compressed arrays). Malformed or truncated input is an error, never a panic.

use std::collections::BTreeMap;
use std::io;
use std::path::{Path, PathBuf};

/// The size of one zlib block of a compressed array, as the writer cuts them (32 KiB).
pub const BLOCK: usize = 32 * 1024;

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

/// Errors of the reader. Every message starts with the file path.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("{}: I/O error: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("{}: malformed VTU file: {reason}", .path.display())]
    Parse { path: PathBuf, reason: String },
}

/// Reads a `.vtu` file of the kind [`deasim::io::vtu::write_vtu_as`] writes (one piece, any of
/// its encodings).
///
/// Malformed or truncated input gives [`ReadError::Parse`]; the reader never panics.
pub fn read_vtu(path: &Path) -> Result<VtuData, ReadError> {
    let text = std::fs::read_to_string(path).map_err(|source| ReadError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_vtu(&text).map_err(|reason| ReadError::Parse {
        path: path.to_path_buf(),
        reason,
    })
}

/// Reads a `.pvtu` index as [`deasim::io::vtu::write_pvtu`] writes it and every piece it lists (with
/// [`read_vtu`], paths relative to the index's directory), in the index's order.
pub fn read_pvtu(path: &Path) -> Result<Vec<VtuData>, ReadError> {
    let parse = |reason: String| ReadError::Parse {
        path: path.to_path_buf(),
        reason,
    };
    let text = std::fs::read_to_string(path).map_err(|source| ReadError::Io {
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
