//! Point clouds as PLY files (Stanford polygon format): ASCII or binary little-endian (the
//! default), big-endian on request.
//!
//! # Layout written
//! ```text
//! ply
//! format binary_little_endian 1.0        (or: format ascii 1.0)
//! comment scanhil point cloud
//! comment model small_angle              (the GeometryModel name: small_angle or exact_reflection)
//! comment units x y z z_meas_mm in millimetres, d_alpha_rad d_beta_rad in radians, t_s in seconds
//! element vertex <n>
//! property double x
//! property double y
//! property double z
//! property double t_s
//! property double d_alpha_rad
//! property double d_beta_rad
//! property double z_meas_mm
//! end_header
//! ```
//! Every header line ends in a single `\n`. `x y z` keep the names every point-cloud tool
//! looks for; the extra per-vertex properties are ignored by tools that do not know them.
//!
//! The reader accepts any PLY file: ASCII, binary little- or big-endian, every scalar type
//! of the spec (and its sized aliases), list properties and further elements (read and
//! skipped). It never panics; a bad file gives a [`PlyError`] naming the line or byte offset.

use std::io::{self, Write};
use std::path::Path;

use super::reconstruct::{GeometryModel, PointCloud, ScanPoint, model_from_name};

/// The vertex properties scanhil writes, in order.
pub const VERTEX_PROPERTIES: [&str; 7] = [
    "x",
    "y",
    "z",
    "t_s",
    "d_alpha_rad",
    "d_beta_rad",
    "z_meas_mm",
];

const MODEL_COMMENT: &str = "model ";

/// How the vertex data after the header is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlyEncoding {
    /// Whitespace-separated decimal text, one vertex per line.
    Ascii,
    /// IEEE 754 little-endian binary.
    BinaryLittleEndian,
    /// IEEE 754 big-endian binary (scanhil writes little-endian unless asked).
    BinaryBigEndian,
}

impl PlyEncoding {
    /// The keyword of the `format` header line.
    #[must_use]
    pub fn keyword(self) -> &'static str {
        match self {
            PlyEncoding::Ascii => "ascii",
            PlyEncoding::BinaryLittleEndian => "binary_little_endian",
            PlyEncoding::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// Why a PLY file could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    /// Reading or writing the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        source: io::Error,
    },
    /// The header is malformed.
    #[error("PLY header line {line}: {reason}")]
    Header {
        /// 1-based header line number.
        line: usize,
        /// What was wrong.
        reason: String,
    },
    /// The data after the header is malformed or truncated.
    #[error("PLY data at byte {offset}: {reason}")]
    Data {
        /// Byte offset from the start of the file.
        offset: usize,
        /// What was wrong.
        reason: String,
    },
    /// The file is valid PLY but lacks what a scanhil point cloud needs.
    #[error("PLY point cloud: {reason}")]
    NotAPointCloud {
        /// What is missing.
        reason: String,
    },
}

/// Writes the header and the vertices of `cloud` to `out`.
pub fn write_ply<W: Write>(
    mut out: W,
    cloud: &PointCloud,
    encoding: PlyEncoding,
) -> io::Result<()> {
    let mut header = format!("ply\nformat {} 1.0\n", encoding.keyword());
    header.push_str("comment scanhil point cloud\n");
    header.push_str(&format!("comment {MODEL_COMMENT}{}\n", cloud.model.name()));
    header.push_str(
        "comment units x y z z_meas_mm in millimetres, d_alpha_rad d_beta_rad in radians, \
         t_s in seconds\n",
    );
    header.push_str(&format!("element vertex {}\n", cloud.points.len()));
    for name in VERTEX_PROPERTIES {
        header.push_str(&format!("property double {name}\n"));
    }
    header.push_str("end_header\n");
    out.write_all(header.as_bytes())?;
    for p in &cloud.points {
        let row = point_row(p);
        match encoding {
            PlyEncoding::Ascii => {
                for (i, v) in row.iter().enumerate() {
                    let separator = if i == 0 { "" } else { " " };
                    write!(out, "{separator}{v:?}")?;
                }
                out.write_all(b"\n")?;
            }
            PlyEncoding::BinaryLittleEndian => {
                for v in row {
                    out.write_all(&v.to_le_bytes())?;
                }
            }
            PlyEncoding::BinaryBigEndian => {
                for v in row {
                    out.write_all(&v.to_be_bytes())?;
                }
            }
        }
    }
    out.flush()
}

/// Writes `cloud` to the file at `path`.
pub fn write_ply_file(
    path: &Path,
    cloud: &PointCloud,
    encoding: PlyEncoding,
) -> Result<(), PlyError> {
    let io_err = |source| PlyError::Io {
        path: path.display().to_string(),
        source,
    };
    let file = std::fs::File::create(path).map_err(io_err)?;
    write_ply(io::BufWriter::new(file), cloud, encoding).map_err(io_err)
}

fn point_row(p: &ScanPoint) -> [f64; 7] {
    [
        p.x_mm,
        p.y_mm,
        p.z_mm,
        p.t_s,
        p.d_alpha_rad,
        p.d_beta_rad,
        p.z_meas_mm,
    ]
}

/// The vertex element of a PLY file: its scalar properties as `f64` values, a row per vertex.
#[derive(Debug, Clone, PartialEq)]
pub struct PlyVertices {
    /// The data encoding the file declared.
    pub encoding: PlyEncoding,
    /// The `comment` lines, without the keyword.
    pub comments: Vec<String>,
    /// The names of the vertex element's scalar properties, in file order.
    pub property_names: Vec<String>,
    /// How many vertices the file holds.
    pub count: usize,
    /// Every vertex's values, row after row (`property_names.len()` a row): one allocation
    /// for the whole element, not one a vertex.
    pub values: Vec<f64>,
}

impl PlyVertices {
    /// The vertices' rows, `property_names.len()` values each, in file order.
    pub fn rows(&self) -> impl Iterator<Item = &[f64]> {
        let width = self.property_names.len();
        (0..self.count).map(move |i| &self.values[i * width..(i + 1) * width])
    }

    /// The values of one named property over all vertices, or `None` if there is none.
    #[must_use]
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.property_names.iter().position(|n| n == name)?;
        Some(self.rows().map(|r| r[i]).collect())
    }

    /// The scanhil point cloud stored in the file: all of [`VERTEX_PROPERTIES`] and the
    /// `comment model ...` line must be present.
    pub fn to_point_cloud(&self) -> Result<PointCloud, PlyError> {
        let layout = CloudLayout::of(&self.comments, &self.property_names)?;
        Ok(PointCloud {
            model: layout.model,
            points: self.rows().map(|row| layout.point(row)).collect(),
        })
    }
}

/// Where a scanhil point cloud's model and properties sit in a PLY file.
struct CloudLayout {
    model: GeometryModel,
    /// The row index of each of [`VERTEX_PROPERTIES`].
    index: [usize; 7],
}

impl CloudLayout {
    fn of(comments: &[String], property_names: &[String]) -> Result<CloudLayout, PlyError> {
        let model_name = comments
            .iter()
            .find_map(|c| c.strip_prefix(MODEL_COMMENT))
            .ok_or_else(|| PlyError::NotAPointCloud {
                reason: "no 'comment model ...' line names the reconstruction model".into(),
            })?;
        let model = model_from_name(model_name.trim()).ok_or_else(|| PlyError::NotAPointCloud {
            reason: format!("unknown reconstruction model '{model_name}'"),
        })?;
        let mut index = [0usize; 7];
        for (slot, name) in index.iter_mut().zip(VERTEX_PROPERTIES) {
            *slot = property_names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| PlyError::NotAPointCloud {
                    reason: format!("vertex property '{name}' is missing"),
                })?;
        }
        Ok(CloudLayout { model, index })
    }

    fn point(&self, row: &[f64]) -> ScanPoint {
        let [x, y, z, t, alpha, beta, z_meas] = self.index.map(|i| row[i]);
        ScanPoint {
            x_mm: x,
            y_mm: y,
            z_mm: z,
            t_s: t,
            d_alpha_rad: alpha,
            d_beta_rad: beta,
            z_meas_mm: z_meas,
        }
    }
}

/// Reads the PLY file at `path`.
pub fn read_ply_file(path: &Path) -> Result<PlyVertices, PlyError> {
    read_ply(&read_file(path)?)
}

/// Reads the scanhil point cloud in the PLY file at `path`: the points are made as the
/// vertices are read, so the file's bytes and the points are all it holds.
pub fn read_point_cloud_file(path: &Path) -> Result<PointCloud, PlyError> {
    read_point_cloud(&read_file(path)?)
}

fn read_file(path: &Path) -> Result<Vec<u8>, PlyError> {
    std::fs::read(path).map_err(|source| PlyError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// A scalar type of the PLY spec.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(word: &str) -> Option<Scalar> {
        Some(match word {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn decode(self, b: &[u8], little: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:literal) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                f64::from(if little {
                    <$t>::from_le_bytes(a)
                } else {
                    <$t>::from_be_bytes(a)
                })
            }};
        }
        match self {
            Scalar::I8 => num!(i8, 1),
            Scalar::U8 => num!(u8, 1),
            Scalar::I16 => num!(i16, 2),
            Scalar::U16 => num!(u16, 2),
            Scalar::I32 => num!(i32, 4),
            Scalar::U32 => num!(u32, 4),
            Scalar::F32 => num!(f32, 4),
            Scalar::F64 => num!(f64, 8),
        }
    }
}

/// One property of an element: a scalar, or a list with its count and item types.
#[derive(Debug, Clone, PartialEq)]
enum Property {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone, PartialEq)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<(String, Property)>,
}

impl Element {
    /// The names of the scalar properties: a row's values, in order.
    fn scalar_names(&self) -> Vec<String> {
        self.properties
            .iter()
            .filter(|(_, p)| matches!(p, Property::Scalar(_)))
            .map(|(n, _)| n.clone())
            .collect()
    }

    /// The rows `data_len` bytes can hold at most, so a count in a header cannot ask for more
    /// memory than the file could fill: a binary row is at least its scalars and list counts,
    /// an ASCII value at least a digit and a separator.
    fn rows_that_fit(&self, encoding: PlyEncoding, data_len: usize) -> usize {
        let row_bytes: usize = self
            .properties
            .iter()
            .map(|(_, p)| match (encoding, p) {
                (PlyEncoding::Ascii, _) => 2,
                (_, Property::Scalar(s)) => s.size(),
                (_, Property::List { count, .. }) => count.size(),
            })
            .sum();
        self.count.min(data_len / row_bytes.max(1))
    }
}

/// Where a value sits in the data, spelled out only when an error names it.
#[derive(Clone, Copy)]
struct Place<'a> {
    element: &'a str,
    index: usize,
    property: &'a str,
    part: &'static str,
}

impl std::fmt::Display for Place<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} {} {}{}",
            self.element, self.index, self.property, self.part
        )
    }
}

struct Header {
    encoding: PlyEncoding,
    comments: Vec<String>,
    elements: Vec<Element>,
    data_offset: usize,
}

impl Header {
    /// The first element named `vertex`.
    fn vertex(&self) -> Result<&Element, PlyError> {
        self.elements
            .iter()
            .find(|e| e.name == "vertex")
            .ok_or_else(|| PlyError::NotAPointCloud {
                reason: "the file has no 'vertex' element".into(),
            })
    }
}

/// Parses a whole PLY file held in memory.
pub fn read_ply(bytes: &[u8]) -> Result<PlyVertices, PlyError> {
    let header = parse_header(bytes)?;
    let vertex = header.vertex()?;
    let property_names = vertex.scalar_names();
    let rows = vertex.rows_that_fit(header.encoding, bytes.len() - header.data_offset);
    let mut values = Vec::with_capacity(rows.saturating_mul(property_names.len()));
    read_data(bytes, &header, |row| values.extend_from_slice(row))?;
    Ok(PlyVertices {
        encoding: header.encoding,
        count: vertex.count,
        property_names,
        values,
        comments: header.comments,
    })
}

/// Parses the scanhil point cloud of a PLY file held in memory, making each point as its
/// vertex is read (no table of the file's values in between).
pub fn read_point_cloud(bytes: &[u8]) -> Result<PointCloud, PlyError> {
    let header = parse_header(bytes)?;
    let vertex = header.vertex()?;
    let layout = CloudLayout::of(&header.comments, &vertex.scalar_names())?;
    let mut points =
        Vec::with_capacity(vertex.rows_that_fit(header.encoding, bytes.len() - header.data_offset));
    read_data(bytes, &header, |row| points.push(layout.point(row)))?;
    Ok(PointCloud {
        model: layout.model,
        points,
    })
}

/// Reads every element's data, handing each row of the first `vertex` element (its scalar
/// values) to `on_vertex` and skipping the rest.
fn read_data(
    bytes: &[u8],
    header: &Header,
    mut on_vertex: impl FnMut(&[f64]),
) -> Result<(), PlyError> {
    let mut cursor = Cursor {
        bytes,
        offset: header.data_offset,
    };
    let vertex = header.vertex()?;
    for element in &header.elements {
        if std::ptr::eq(element, vertex) {
            read_element(&mut cursor, element, header.encoding, &mut on_vertex)?;
        } else {
            read_element(&mut cursor, element, header.encoding, &mut |_: &[f64]| {})?;
        }
    }
    Ok(())
}

fn parse_header(bytes: &[u8]) -> Result<Header, PlyError> {
    let mut offset = 0;
    let mut line_no = 0;
    let mut encoding = None;
    let mut comments = Vec::new();
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line_no += 1;
        let err = |reason: String| PlyError::Header {
            line: line_no,
            reason,
        };
        let rest = &bytes[offset..];
        let end = rest
            .iter()
            .position(|&b| b == b'\n')
            .ok_or_else(|| err("header ends before 'end_header'".into()))?;
        let raw = &rest[..end];
        offset += end + 1;
        let text = std::str::from_utf8(raw)
            .map_err(|_| err("header line is not ASCII text".into()))?
            .trim_end_matches('\r');
        if line_no == 1 {
            if text != "ply" {
                return Err(err(format!("expected the magic 'ply', found '{text}'")));
            }
            continue;
        }
        let mut words = text.split_whitespace();
        match words.next() {
            Some("format") => {
                let kind = words.next().unwrap_or("");
                encoding = Some(match kind {
                    "ascii" => PlyEncoding::Ascii,
                    "binary_little_endian" => PlyEncoding::BinaryLittleEndian,
                    "binary_big_endian" => PlyEncoding::BinaryBigEndian,
                    other => return Err(err(format!("unknown format '{other}'"))),
                });
                if words.next() != Some("1.0") {
                    return Err(err("only PLY version 1.0 is defined".into()));
                }
            }
            Some("comment") => {
                let body = text.strip_prefix("comment").unwrap_or("");
                comments.push(body.strip_prefix(' ').unwrap_or(body).to_string());
            }
            Some("obj_info") => {}
            Some("element") => {
                let name = words
                    .next()
                    .ok_or_else(|| err("element without a name".into()))?;
                let count = words
                    .next()
                    .and_then(|c| c.parse::<usize>().ok())
                    .ok_or_else(|| err(format!("element '{name}' has no valid count")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            Some("property") => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| err("property before any element".into()))?;
                let first = words.next().unwrap_or("");
                let property = if first == "list" {
                    let count = words.next().and_then(Scalar::parse);
                    let item = words.next().and_then(Scalar::parse);
                    match (count, item) {
                        (Some(count), Some(item)) => Property::List { count, item },
                        _ => return Err(err("list property with an unknown type".into())),
                    }
                } else {
                    Property::Scalar(
                        Scalar::parse(first)
                            .ok_or_else(|| err(format!("unknown property type '{first}'")))?,
                    )
                };
                let name = words
                    .next()
                    .ok_or_else(|| err("property without a name".into()))?;
                element.properties.push((name.to_string(), property));
            }
            Some("end_header") => break,
            Some(other) => return Err(err(format!("unknown header keyword '{other}'"))),
            None => return Err(err("empty header line".into())),
        }
    }
    let encoding = encoding.ok_or(PlyError::Header {
        line: line_no,
        reason: "no 'format' line before 'end_header'".into(),
    })?;
    Ok(Header {
        encoding,
        comments,
        elements,
        data_offset: offset,
    })
}

struct Cursor<'a> {
    bytes: &'a [u8],
    offset: usize,
}

impl Cursor<'_> {
    fn data_err(&self, reason: String) -> PlyError {
        PlyError::Data {
            offset: self.offset,
            reason,
        }
    }

    fn take(&mut self, n: usize, what: Place<'_>) -> Result<&[u8], PlyError> {
        let end = self
            .offset
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len());
        match end {
            Some(end) => {
                let s = &self.bytes[self.offset..end];
                self.offset = end;
                Ok(s)
            }
            None => Err(self.data_err(format!("file ends inside {what}"))),
        }
    }

    /// The next whitespace-separated token (ASCII data).
    fn token(&mut self, what: Place<'_>) -> Result<(usize, &str), PlyError> {
        while self.offset < self.bytes.len() && self.bytes[self.offset].is_ascii_whitespace() {
            self.offset += 1;
        }
        let start = self.offset;
        while self.offset < self.bytes.len() && !self.bytes[self.offset].is_ascii_whitespace() {
            self.offset += 1;
        }
        if start == self.offset {
            return Err(self.data_err(format!("file ends inside {what}")));
        }
        let text =
            std::str::from_utf8(&self.bytes[start..self.offset]).map_err(|_| PlyError::Data {
                offset: start,
                reason: format!("{what} is not ASCII text"),
            })?;
        Ok((start, text))
    }

    /// The next value of type `scalar`.
    fn value(
        &mut self,
        encoding: PlyEncoding,
        scalar: Scalar,
        what: Place<'_>,
    ) -> Result<f64, PlyError> {
        match encoding {
            PlyEncoding::Ascii => self.ascii_number(what),
            PlyEncoding::BinaryLittleEndian => {
                Ok(scalar.decode(self.take(scalar.size(), what)?, true))
            }
            PlyEncoding::BinaryBigEndian => {
                Ok(scalar.decode(self.take(scalar.size(), what)?, false))
            }
        }
    }

    /// Passes over `n` values of type `scalar` (a list's items).
    fn skip_values(
        &mut self,
        encoding: PlyEncoding,
        scalar: Scalar,
        n: usize,
        what: Place<'_>,
    ) -> Result<(), PlyError> {
        if encoding == PlyEncoding::Ascii {
            for _ in 0..n {
                self.ascii_number(what)?;
            }
        } else {
            let items = Place {
                part: " items",
                ..what
            };
            self.take(n.saturating_mul(scalar.size()), items)?;
        }
        Ok(())
    }

    fn ascii_number(&mut self, what: Place<'_>) -> Result<f64, PlyError> {
        let (start, text) = self.token(what)?;
        text.parse::<f64>().map_err(|_| PlyError::Data {
            offset: start,
            reason: format!("{what}: '{text}' is not a number"),
        })
    }
}

fn list_len(value: f64, cursor: &Cursor<'_>) -> Result<usize, PlyError> {
    if value.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&value) {
        Ok(value as usize)
    } else {
        Err(cursor.data_err(format!("list count {value} is not a non-negative integer")))
    }
}

/// Reads one element's rows, handing each row's scalar values to `on_row`.
fn read_element(
    cursor: &mut Cursor<'_>,
    element: &Element,
    encoding: PlyEncoding,
    on_row: &mut dyn FnMut(&[f64]),
) -> Result<(), PlyError> {
    // Rows of no property take no bytes: reading 4e10 of them once took minutes (found by
    // AFL++). Such an element holds nothing, so it is refused rather than counted through.
    if element.properties.is_empty() && element.count > 0 {
        return Err(cursor.data_err(format!(
            "element '{}' has {} rows but no property: there is nothing to read",
            element.name, element.count
        )));
    }
    let fixed_row: Option<usize> = element
        .properties
        .iter()
        .map(|(_, p)| match p {
            Property::Scalar(s) => Some(s.size()),
            Property::List { .. } => None,
        })
        .sum();
    if let (false, Some(row)) = (encoding == PlyEncoding::Ascii, fixed_row) {
        let needed = row.checked_mul(element.count);
        if needed.is_none_or(|n| n > cursor.bytes.len() - cursor.offset) {
            return Err(cursor.data_err(format!(
                "{} '{}' elements of {row} bytes do not fit in the {} bytes left",
                element.count,
                element.name,
                cursor.bytes.len() - cursor.offset
            )));
        }
    }
    let mut row = Vec::new();
    for index in 0..element.count {
        row.clear();
        for (property, kind) in &element.properties {
            let place = |part| Place {
                element: &element.name,
                index,
                property,
                part,
            };
            match *kind {
                Property::Scalar(s) => row.push(cursor.value(encoding, s, place(""))?),
                Property::List { count, item } => {
                    let n = cursor.value(encoding, count, place(" count"))?;
                    let n = list_len(n, cursor)?;
                    cursor.skip_values(encoding, item, n, place(" item"))?;
                }
            }
        }
        on_row(&row);
    }
    Ok(())
}
