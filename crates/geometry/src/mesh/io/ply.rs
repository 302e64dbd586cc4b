//! Stanford PLY, ASCII and binary (little- or big-endian).
//!
//! Reads `x y z` of element `vertex` (any numeric type) and the list `vertex_indices` (or `vertex_index`) of
//! element `face` (any integer types; polygons are fan-triangulated). Other properties and elements are
//! skipped. A small parser of our own: the format is simple and we want errors that name the element.

use std::fmt::Write as _;

use super::{MeshFormat, MeshIoError, PlyEncoding, WriteParams, fan_triangulate};
use crate::math::Vec3;
use crate::mesh::TriMesh;

const FORMAT: MeshFormat = MeshFormat::Ply;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }

    /// Decodes one value from `b` (exactly `self.size()` bytes).
    fn decode(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! get {
            ($t:ty) => {{
                let arr = b.try_into().expect("slice of the scalar's size");
                (if big_endian {
                    <$t>::from_be_bytes(arr)
                } else {
                    <$t>::from_le_bytes(arr)
                }) as f64
            }};
        }
        match self {
            Self::I8 => get!(i8),
            Self::U8 => get!(u8),
            Self::I16 => get!(i16),
            Self::U16 => get!(u16),
            Self::I32 => get!(i32),
            Self::U32 => get!(u32),
            Self::F32 => get!(f32),
            Self::F64 => get!(f64),
        }
    }
}

#[derive(Clone, Debug)]
enum PropertyKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: PropertyKind,
}

#[derive(Clone, Debug)]
struct PlyElement {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Binary { big_endian: bool },
}

struct Header {
    encoding: Encoding,
    elements: Vec<PlyElement>,
    /// Byte offset of the body.
    body: usize,
    /// Number of header lines (ASCII body line numbers continue from here).
    lines: usize,
}

fn header_error(line: usize, message: impl Into<String>) -> MeshIoError {
    MeshIoError::syntax(FORMAT, line, message)
}

fn parse_header(bytes: &[u8]) -> Result<Header, MeshIoError> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut encoding = None;
    let mut elements: Vec<PlyElement> = Vec::new();
    loop {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(MeshIoError::invalid(
                FORMAT,
                "PLY header has no end_header line",
            ));
        };
        let raw = &bytes[pos..pos + len];
        pos += len + 1;
        line_no += 1;
        let line = String::from_utf8_lossy(raw);
        let mut t = line.split_ascii_whitespace();
        let keyword = t.next().unwrap_or("");
        if line_no == 1 {
            if keyword != "ply" {
                return Err(MeshIoError::invalid(
                    FORMAT,
                    "not a PLY file: it does not start with the line \"ply\"",
                ));
            }
            continue;
        }
        match keyword {
            "format" => {
                let kind = t.next().unwrap_or("");
                encoding = Some(match kind {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Binary { big_endian: false },
                    "binary_big_endian" => Encoding::Binary { big_endian: true },
                    other => {
                        return Err(header_error(line_no, format!("unknown format {other:?}")));
                    }
                });
            }
            "element" => {
                let name = t.next().unwrap_or("").to_string();
                let count = t
                    .next()
                    .and_then(|c| c.parse::<usize>().ok())
                    .ok_or_else(|| {
                        header_error(line_no, format!("element {name:?} lacks a count"))
                    })?;
                elements.push(PlyElement {
                    name,
                    count,
                    properties: Vec::new(),
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(header_error(line_no, "property before any element"));
                };
                let ty = t.next().unwrap_or("");
                let kind = if ty == "list" {
                    let count = t.next().and_then(Scalar::parse);
                    let item = t.next().and_then(Scalar::parse);
                    match (count, item) {
                        (Some(count), Some(item)) if count.is_integer() => {
                            PropertyKind::List { count, item }
                        }
                        _ => return Err(header_error(line_no, "bad list property types")),
                    }
                } else {
                    PropertyKind::Scalar(Scalar::parse(ty).ok_or_else(|| {
                        header_error(line_no, format!("unknown property type {ty:?}"))
                    })?)
                };
                let name = t
                    .next()
                    .ok_or_else(|| header_error(line_no, "property lacks a name"))?
                    .to_string();
                element.properties.push(Property { name, kind });
            }
            "end_header" => break,
            "comment" | "obj_info" | "" => {}
            other => {
                return Err(header_error(
                    line_no,
                    format!("unknown header line {other:?}"),
                ));
            }
        }
    }
    let encoding =
        encoding.ok_or_else(|| MeshIoError::invalid(FORMAT, "PLY header lacks a format line"))?;
    Ok(Header {
        encoding,
        elements,
        body: pos,
        lines: line_no,
    })
}

/// Where in an element's record the needed values are.
struct Wanted {
    /// Property index of x, y, z (vertex element).
    xyz: Option<[usize; 3]>,
    /// Property index of the index list (face element).
    indices: Option<usize>,
}

fn wanted(element: &PlyElement) -> Result<Wanted, MeshIoError> {
    let find = |n: &str| element.properties.iter().position(|p| p.name == n);
    let mut w = Wanted {
        xyz: None,
        indices: None,
    };
    if element.name == "vertex" {
        let xyz = [find("x"), find("y"), find("z")];
        let [Some(x), Some(y), Some(z)] = xyz else {
            return Err(MeshIoError::invalid(
                FORMAT,
                "PLY element vertex lacks one of the properties x, y, z",
            ));
        };
        for i in [x, y, z] {
            if !matches!(element.properties[i].kind, PropertyKind::Scalar(_)) {
                return Err(MeshIoError::invalid(
                    FORMAT,
                    format!(
                        "PLY vertex property {} is a list",
                        element.properties[i].name
                    ),
                ));
            }
        }
        w.xyz = Some([x, y, z]);
    } else if element.name == "face" {
        let i = find("vertex_indices")
            .or_else(|| find("vertex_index"))
            .ok_or_else(|| {
                MeshIoError::invalid(
                    FORMAT,
                    "PLY element face lacks the list property vertex_indices",
                )
            })?;
        match element.properties[i].kind {
            PropertyKind::List { item, .. } if item.is_integer() => {}
            _ => {
                return Err(MeshIoError::invalid(
                    FORMAT,
                    "PLY face property vertex_indices is not a list of integers",
                ));
            }
        }
        w.indices = Some(i);
    }
    Ok(w)
}

/// Reads a PLY file.
pub fn read_ply(bytes: &[u8]) -> Result<TriMesh, MeshIoError> {
    let header = parse_header(bytes)?;
    if !header.elements.iter().any(|e| e.name == "vertex") {
        return Err(MeshIoError::invalid(
            FORMAT,
            "PLY file has no vertex element",
        ));
    }
    let mut positions: Vec<Vec3> = Vec::new();
    let mut faces: Vec<[usize; 3]> = Vec::new();
    // Faces are checked against the vertex count once all elements are read (a face element may precede
    // the vertex element).
    let mut polygon_faces: Vec<usize> = Vec::new(); // PLY face number of each triangle
    let body = &bytes[header.body..];
    let mut reader: Box<dyn ValueReader + '_> = match header.encoding {
        Encoding::Ascii => Box::new(AsciiReader::new(body, header.lines)),
        Encoding::Binary { big_endian } => Box::new(BinaryReader {
            bytes: body,
            pos: 0,
            big_endian,
        }),
    };
    let mut poly: Vec<usize> = Vec::with_capacity(8);
    let mut values: Vec<f64> = Vec::new();
    for element in &header.elements {
        let w = wanted(element)?;
        if element.properties.is_empty() {
            // Records without properties occupy nothing in a binary body; in ASCII they are empty lines,
            // which the reader skips anyway. Do not loop over a possibly huge count.
            continue;
        }
        let cap = element.count.min(body.len());
        if w.xyz.is_some() {
            positions.reserve(cap);
        }
        for n in 0..element.count {
            reader.start_record(&element.name, n)?;
            let mut xyz = [0.0; 3];
            for (pi, p) in element.properties.iter().enumerate() {
                match p.kind {
                    PropertyKind::Scalar(s) => {
                        let x = reader.value(s, &element.name, n)?;
                        if let Some(k) = w.xyz.and_then(|xyz| xyz.iter().position(|&i| i == pi)) {
                            xyz[k] = x;
                        }
                    }
                    PropertyKind::List { count, item } => {
                        let len = reader.value(count, &element.name, n)?;
                        if len < 0.0 {
                            return Err(MeshIoError::invalid(
                                FORMAT,
                                format!("PLY {} {n}: negative list length {len}", element.name),
                            ));
                        }
                        values.clear();
                        for _ in 0..len as usize {
                            values.push(reader.value(item, &element.name, n)?);
                        }
                        if w.indices == Some(pi) {
                            poly.clear();
                            for &v in &values {
                                if v < 0.0 {
                                    return Err(MeshIoError::invalid(
                                        FORMAT,
                                        format!("PLY face {n} has negative vertex index {v}"),
                                    ));
                                }
                                poly.push(v as usize);
                            }
                            if poly.len() < 3 {
                                return Err(MeshIoError::invalid(
                                    FORMAT,
                                    format!(
                                        "PLY face {n} has {} vertices, needs at least 3",
                                        poly.len()
                                    ),
                                ));
                            }
                            fan_triangulate(&poly, &mut faces);
                            polygon_faces.resize(faces.len(), n);
                        }
                    }
                }
            }
            reader.end_record(&element.name, n)?;
            if w.xyz.is_some() {
                positions.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
            }
        }
    }
    let nv = positions.len();
    for (t, face) in faces.iter().enumerate() {
        if let Some(&v) = face.iter().find(|&&v| v >= nv) {
            return Err(MeshIoError::invalid(
                FORMAT,
                format!(
                    "PLY face {} names vertex {v}, but the file has {nv} vertices",
                    polygon_faces[t]
                ),
            ));
        }
    }
    Ok(TriMesh::new(positions, faces))
}

/// Reads the values of the body one by one, whatever the encoding.
trait ValueReader {
    fn start_record(&mut self, element: &str, n: usize) -> Result<(), MeshIoError>;
    fn value(&mut self, s: Scalar, element: &str, n: usize) -> Result<f64, MeshIoError>;
    fn end_record(&mut self, element: &str, n: usize) -> Result<(), MeshIoError>;
}

struct BinaryReader<'a> {
    bytes: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl ValueReader for BinaryReader<'_> {
    fn start_record(&mut self, _: &str, _: usize) -> Result<(), MeshIoError> {
        Ok(())
    }

    fn value(&mut self, s: Scalar, element: &str, n: usize) -> Result<f64, MeshIoError> {
        let end = self.pos + s.size();
        let b = self.bytes.get(self.pos..end).ok_or_else(|| {
            MeshIoError::invalid(
                FORMAT,
                format!(
                    "binary PLY truncated in {element} {n} (body has {} bytes)",
                    self.bytes.len()
                ),
            )
        })?;
        self.pos = end;
        Ok(s.decode(b, self.big_endian))
    }

    fn end_record(&mut self, _: &str, _: usize) -> Result<(), MeshIoError> {
        Ok(())
    }
}

/// ASCII body: one record per line.
struct AsciiReader<'a> {
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
    tokens: std::str::SplitAsciiWhitespace<'a>,
    line: usize,
    first_line: usize,
}

impl<'a> AsciiReader<'a> {
    fn new(body: &'a [u8], header_lines: usize) -> Self {
        // A non-UTF-8 body is not valid ASCII PLY; treat it as empty so the first record reports it.
        let text = std::str::from_utf8(body).unwrap_or("");
        Self {
            lines: text.lines().enumerate(),
            tokens: "".split_ascii_whitespace(),
            line: header_lines,
            first_line: header_lines + 1,
        }
    }
}

impl ValueReader for AsciiReader<'_> {
    fn start_record(&mut self, element: &str, n: usize) -> Result<(), MeshIoError> {
        for (i, l) in self.lines.by_ref() {
            if !l.trim().is_empty() {
                self.line = self.first_line + i;
                self.tokens = l.split_ascii_whitespace();
                return Ok(());
            }
        }
        Err(MeshIoError::invalid(
            FORMAT,
            format!("ASCII PLY ends before {element} {n}"),
        ))
    }

    fn value(&mut self, s: Scalar, element: &str, n: usize) -> Result<f64, MeshIoError> {
        let tok = self.tokens.next().ok_or_else(|| {
            MeshIoError::syntax(
                FORMAT,
                self.line,
                format!("{element} {n} has too few values"),
            )
        })?;
        let x: f64 = tok.parse().map_err(|_| {
            MeshIoError::syntax(FORMAT, self.line, format!("{tok:?} is not a number"))
        })?;
        if s.is_integer() && x.fract() != 0.0 {
            return Err(MeshIoError::syntax(
                FORMAT,
                self.line,
                format!("{tok:?} is not an integer"),
            ));
        }
        Ok(x)
    }

    fn end_record(&mut self, element: &str, n: usize) -> Result<(), MeshIoError> {
        if self.tokens.next().is_some() {
            return Err(MeshIoError::syntax(
                FORMAT,
                self.line,
                format!("{element} {n} has more values than its properties"),
            ));
        }
        Ok(())
    }
}

/// Writes a PLY file: `double x y z`, optional `double nx ny nz` and `uchar red green blue`, and faces as
/// `list uchar int vertex_indices`.
pub fn write_ply(mesh: &TriMesh, params: &WriteParams<'_>) -> Vec<u8> {
    let ascii = params.ply_encoding == PlyEncoding::Ascii;
    let mut h = String::new();
    h.push_str("ply\n");
    h.push_str(if ascii {
        "format ascii 1.0\n"
    } else {
        "format binary_little_endian 1.0\n"
    });
    h.push_str("comment skintight mesh, metres\n");
    let _ = writeln!(h, "element vertex {}", mesh.num_vertices());
    for c in ["x", "y", "z"] {
        let _ = writeln!(h, "property double {c}");
    }
    if params.normals.is_some() {
        for c in ["nx", "ny", "nz"] {
            let _ = writeln!(h, "property double {c}");
        }
    }
    if params.colors.is_some() {
        for c in ["red", "green", "blue"] {
            let _ = writeln!(h, "property uchar {c}");
        }
    }
    let _ = writeln!(h, "element face {}", mesh.num_faces());
    h.push_str("property list uchar int vertex_indices\nend_header\n");
    let byte = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u8;

    let mut out = h.into_bytes();
    if ascii {
        let mut s = String::new();
        for (v, p) in mesh.positions.iter().enumerate() {
            let _ = write!(s, "{} {} {}", p.x, p.y, p.z);
            if let Some(n) = params.normals {
                let _ = write!(s, " {} {} {}", n[v].x, n[v].y, n[v].z);
            }
            if let Some(c) = params.colors {
                let _ = write!(s, " {} {} {}", byte(c[v][0]), byte(c[v][1]), byte(c[v][2]));
            }
            s.push('\n');
        }
        for [a, b, c] in &mesh.faces {
            let _ = writeln!(s, "3 {a} {b} {c}");
        }
        out.extend_from_slice(s.as_bytes());
    } else {
        out.reserve(mesh.num_vertices() * 51 + mesh.num_faces() * 13);
        for (v, p) in mesh.positions.iter().enumerate() {
            for x in p.iter() {
                out.extend_from_slice(&x.to_le_bytes());
            }
            if let Some(n) = params.normals {
                for x in n[v].iter() {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
            if let Some(c) = params.colors {
                out.extend(c[v].iter().map(|&x| byte(x)));
            }
        }
        for face in &mesh.faces {
            out.push(3);
            for &v in face {
                out.extend_from_slice(&(v as i32).to_le_bytes());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::octahedron;

    const QUAD_ASCII: &str = "ply\nformat ascii 1.0\ncomment hello\nelement vertex 4\nproperty float x\n\
        property float y\nproperty float z\nproperty uchar red\nelement face 1\n\
        property list uchar uint vertex_index\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n\
        end_header\n0 0 0 255\n1 0 0 0\n1 1 0 0\n0 1 0 0\n4 0 1 2 3\n0 1\n";

    #[test]
    fn ascii_quad_is_fan_triangulated() {
        let m = read_ply(QUAD_ASCII.as_bytes()).unwrap();
        assert_eq!(m.num_vertices(), 4);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.positions[2], Vec3::new(1.0, 1.0, 0.0));
    }

    #[test]
    fn binary_with_other_types_and_big_endian() {
        for big_endian in [false, true] {
            let mut b: Vec<u8> = format!(
                "ply\r\nformat {} 1.0\r\nelement vertex 3\r\nproperty short w\r\nproperty float x\r\n\
                 property double y\r\nproperty int z\r\nelement face 1\r\n\
                 property list ushort short vertex_indices\r\nproperty char flag\r\nend_header\r\n",
                if big_endian { "binary_big_endian" } else { "binary_little_endian" }
            )
            .into_bytes();
            // Binary body starts right after "end_header\r\n"; the header reader splits at '\n'.
            for v in 0..3i32 {
                let w = 7i16;
                let x = v as f32 * 0.5;
                let y = -(v as f64);
                let z = 10 * v;
                if big_endian {
                    b.extend(w.to_be_bytes());
                    b.extend(x.to_be_bytes());
                    b.extend(y.to_be_bytes());
                    b.extend(z.to_be_bytes());
                } else {
                    b.extend(w.to_le_bytes());
                    b.extend(x.to_le_bytes());
                    b.extend(y.to_le_bytes());
                    b.extend(z.to_le_bytes());
                }
            }
            let enc16 = |x: u16| {
                if big_endian {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            };
            b.extend(enc16(3));
            for i in [2u16, 1, 0] {
                b.extend(enc16(i));
            }
            b.push(1);
            let m = read_ply(&b).unwrap();
            assert_eq!(m.faces, vec![[2, 1, 0]]);
            assert_eq!(m.positions[2], Vec3::new(1.0, -2.0, 20.0));
        }
    }

    #[test]
    fn errors_are_clear() {
        let cut = &QUAD_ASCII.as_bytes()[..QUAD_ASCII.len() - 14];
        let e = read_ply(cut).unwrap_err().to_string();
        assert!(e.contains("ends before face 0"), "{e}");

        let bad = QUAD_ASCII.replace("1 1 0 0", "1 1 zero 0");
        let e = read_ply(bad.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("PLY line 17") && e.contains("\"zero\""), "{e}");

        let bad = QUAD_ASCII.replace("4 0 1 2 3", "4 0 1 2 9");
        let e = read_ply(bad.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("face 0 names vertex 9"), "{e}");

        let e = read_ply(b"solid x\n").unwrap_err().to_string();
        assert!(e.contains("not a PLY file"), "{e}");

        let mut bin = write_ply(&octahedron(), &WriteParams::default());
        bin.truncate(bin.len() - 5);
        let e = read_ply(&bin).unwrap_err().to_string();
        assert!(e.contains("binary PLY truncated in face 7"), "{e}");
    }

    #[test]
    fn huge_element_count_does_not_allocate_or_hang() {
        let text = "ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\n\
            property float x\nproperty float y\nproperty float z\nend_header\n";
        let e = read_ply(text.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("truncated in vertex 0"), "{e}");
    }

    #[test]
    fn write_then_read_ascii_and_binary_with_attributes() {
        let m = octahedron();
        let normals: Vec<Vec3> = m.positions.iter().map(|p| p.normalize()).collect();
        let colors: Vec<[f32; 3]> = (0..6).map(|i| [i as f32 / 5.0, 0.0, 1.0]).collect();
        for enc in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian] {
            let params = WriteParams {
                normals: Some(&normals),
                colors: Some(&colors),
                ply_encoding: enc,
                ..Default::default()
            };
            let bytes = write_ply(&m, &params);
            let back = read_ply(&bytes).unwrap();
            assert_eq!(back.positions, m.positions);
            assert_eq!(back.faces, m.faces);
        }
    }
}
