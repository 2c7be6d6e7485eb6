//! PLY point clouds (Turk 1994; the format as Paul Bourke documents it): ASCII, binary little-
//! and big-endian. Reads the `vertex` element's `x y z` and optional `red green blue`, skipping
//! every other element and property (faces, normals) correctly; writes `double x y z` and
//! `uchar red green blue`.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Point3;

use crate::depth::memory_path;
use crate::error::{KinectError, Result};
use crate::pointcloud::PointCloud;
use crate::scalar::Scalar;

/// Encoding of a written PLY file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlyFormat {
    /// Text, one vertex per line.
    Ascii,
    /// Binary little-endian (compact, fast; the default).
    #[default]
    BinaryLittleEndian,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

#[derive(Debug, Clone)]
enum Property {
    Scalar(String, Scalar),
    List(Scalar, Scalar),
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

impl Element {
    /// The error for data that ends after `found` of this element's items.
    fn truncated(&self, path: &Path, found: usize) -> KinectError {
        KinectError::CountMismatch {
            path: path.to_path_buf(),
            what: if self.name == "vertex" {
                "vertices"
            } else {
                "elements"
            },
            declared: self.count,
            found,
        }
    }
}

fn scalar_type(name: &str) -> Option<Scalar> {
    Some(match name {
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

/// Read a PLY file.
///
/// # Errors
/// [`KinectError::Io`] when unreadable; [`KinectError::Format`] for a malformed header or
/// value, a missing `vertex` element or `x`/`y`/`z` property;
/// [`KinectError::CountMismatch`] when the header's counts do not match the data.
pub fn read_ply(path: &Path) -> Result<PointCloud> {
    let bytes = std::fs::read(path).map_err(|e| KinectError::io(path, e))?;
    parse_ply_at(&bytes, path)
}

/// Parse a PLY file from bytes.
///
/// # Errors
/// As [`read_ply`].
pub fn parse_ply(bytes: &[u8]) -> Result<PointCloud> {
    parse_ply_at(bytes, memory_path())
}

fn parse_ply_at(bytes: &[u8], path: &Path) -> Result<PointCloud> {
    let (header_lines, pos) = header_lines(bytes, path)?;
    let (encoding, elements) = parse_header(&header_lines, path)?;
    let mut vertices = Vertices::new(&elements, path, bytes.len())?;
    let data = &bytes[pos..];
    match encoding {
        Encoding::Ascii => read_ascii(data, &elements, path, &mut vertices)?,
        Encoding::Little | Encoding::Big => read_binary(
            data,
            &elements,
            path,
            encoding == Encoding::Little,
            &mut vertices,
        )?,
    }
    Ok(PointCloud {
        width: vertices.points.len() as u32,
        height: 1,
        points: vertices.points,
        colors: vertices.colors,
    })
}

/// The header's lines (after the file's first `\n`-ended lines up to `end_header`, which is
/// not among them) and the offset of the body.
fn header_lines(bytes: &[u8], path: &Path) -> Result<(Vec<String>, usize)> {
    let fmt = |what: String| KinectError::format(path, what);
    // The header is ASCII lines up to and including "end_header\n".
    let marker = b"end_header";
    let mut pos = 0;
    let mut header_lines = Vec::new();
    loop {
        let rest = &bytes[pos..];
        let Some(nl) = rest.iter().position(|&b| b == b'\n') else {
            return Err(fmt("header is not terminated by `end_header`".into()));
        };
        let line = std::str::from_utf8(&rest[..nl])
            .map_err(|_| {
                fmt(format!(
                    "header line {} is not text",
                    header_lines.len() + 1
                ))
            })?
            .trim_end_matches('\r');
        pos += nl + 1;
        if line.as_bytes() == marker {
            break;
        }
        header_lines.push(line.to_string());
        if header_lines.len() > 10_000 {
            return Err(fmt("header longer than 10000 lines".into()));
        }
    }
    Ok((header_lines, pos))
}

/// The body's encoding and the elements the header declares.
fn parse_header(header_lines: &[String], path: &Path) -> Result<(Encoding, Vec<Element>)> {
    let fmt = |what: String| KinectError::format(path, what);
    if header_lines.first().map(|l| l.trim()) != Some("ply") {
        return Err(fmt("does not start with `ply`".into()));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    for (k, line) in header_lines.iter().enumerate().skip(1) {
        let lineno = k + 1;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] => {}
            ["comment", ..] | ["obj_info", ..] => {}
            ["format", kind, _version] => {
                encoding = Some(match *kind {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Little,
                    "binary_big_endian" => Encoding::Big,
                    other => return Err(fmt(format!("line {lineno}: unknown format `{other}`"))),
                });
            }
            ["element", name, count] => {
                let count = count.parse::<usize>().map_err(|_| {
                    fmt(format!(
                        "line {lineno}: element count {count:?} is not a count"
                    ))
                })?;
                elements.push(Element {
                    name: (*name).to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", count_ty, item_ty, _name] => {
                let (Some(c), Some(i)) = (scalar_type(count_ty), scalar_type(item_ty)) else {
                    return Err(fmt(format!(
                        "line {lineno}: unknown list types in {line:?}"
                    )));
                };
                if c.is_float() {
                    return Err(fmt(format!(
                        "line {lineno}: a list count must be an integer type"
                    )));
                }
                elements
                    .last_mut()
                    .ok_or_else(|| fmt(format!("line {lineno}: property before any element")))?
                    .properties
                    .push(Property::List(c, i));
            }
            ["property", ty, name] => {
                let ty = scalar_type(ty)
                    .ok_or_else(|| fmt(format!("line {lineno}: unknown property type `{ty}`")))?;
                elements
                    .last_mut()
                    .ok_or_else(|| fmt(format!("line {lineno}: property before any element")))?
                    .properties
                    .push(Property::Scalar((*name).to_string(), ty));
            }
            _ => {
                return Err(fmt(format!(
                    "line {lineno}: cannot read header line {line:?}"
                )));
            }
        }
    }
    let encoding = encoding.ok_or_else(|| fmt("no `format` line".into()))?;
    Ok((encoding, elements))
}

/// The vertex element's points (and colours) as they are read.
struct Vertices<'a> {
    path: &'a Path,
    /// The vertex element's properties.
    properties: &'a [Property],
    /// Indices of x, y and z among them.
    xyz: [usize; 3],
    /// Indices of red, green and blue, when all three are there.
    rgb: Option<[usize; 3]>,
    points: Vec<Option<Point3<f64>>>,
    colors: Option<Vec<[u8; 3]>>,
}

impl<'a> Vertices<'a> {
    /// The reader of `elements`' vertex element: it must have x, y and z. `bytes` bounds the
    /// allocation (a vertex takes at least 3 bytes).
    fn new(elements: &'a [Element], path: &'a Path, bytes: usize) -> Result<Self> {
        let fmt = |what: String| KinectError::format(path, what);
        let vertex = elements
            .iter()
            .find(|e| e.name == "vertex")
            .ok_or_else(|| fmt("no `vertex` element".into()))?;
        let find = |names: &[&str]| {
            vertex
                .properties
                .iter()
                .position(|p| matches!(p, Property::Scalar(n, _) if names.contains(&n.as_str())))
        };
        let (Some(ix), Some(iy), Some(iz)) = (find(&["x"]), find(&["y"]), find(&["z"])) else {
            return Err(fmt("the vertex element lacks an x, y or z property".into()));
        };
        let rgb = match (
            find(&["red", "r", "diffuse_red"]),
            find(&["green", "g", "diffuse_green"]),
            find(&["blue", "b", "diffuse_blue"]),
        ) {
            (Some(r), Some(g), Some(b)) => Some([r, g, b]),
            _ => None,
        };
        let capacity = vertex.count.min(bytes / 3 + 1);
        Ok(Self {
            path,
            properties: &vertex.properties,
            xyz: [ix, iy, iz],
            rgb,
            points: Vec::with_capacity(capacity),
            colors: rgb.map(|_| Vec::with_capacity(capacity)),
        })
    }

    /// Vertex `index` from its property `values`.
    fn push(&mut self, values: &[f64], index: usize) -> Result<()> {
        let [ix, iy, iz] = self.xyz;
        let p = Point3::new(values[ix], values[iy], values[iz]);
        if !p.iter().all(|c| c.is_finite()) {
            return Err(KinectError::format(
                self.path,
                format!("vertex {index} is not finite: {p:?}"),
            ));
        }
        self.points.push(Some(p));
        if let (Some(colors), Some([r, g, b])) = (self.colors.as_mut(), self.rgb) {
            let ty = |i: usize| match &self.properties[i] {
                Property::Scalar(_, t) => *t,
                Property::List(_, t) => *t,
            };
            colors.push([
                ty(r).to_channel(values[r]),
                ty(g).to_channel(values[g]),
                ty(b).to_channel(values[b]),
            ]);
        }
        Ok(())
    }
}

/// An ASCII body: every element's lines, the vertices into `vertices`.
fn read_ascii(
    data: &[u8],
    elements: &[Element],
    path: &Path,
    vertices: &mut Vertices<'_>,
) -> Result<()> {
    let fmt = |what: String| KinectError::format(path, what);
    let mut values: Vec<f64> = Vec::new();
    let text = std::str::from_utf8(data).map_err(|_| fmt("ASCII body is not text".into()))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    for element in elements {
        for index in 0..element.count {
            let Some(line) = lines.next() else {
                return Err(element.truncated(path, index));
            };
            let mut tokens = line.split_whitespace();
            values.clear();
            for property in &element.properties {
                let mut next = |ty: Scalar| -> Result<f64> {
                    let t = tokens
                        .next()
                        .ok_or_else(|| fmt(format!("{} {index}: too few values", element.name)))?;
                    ty.parse(t).ok_or_else(|| {
                        fmt(format!(
                            "{} {index}: {t:?} is not a valid {ty:?}",
                            element.name
                        ))
                    })
                };
                match property {
                    Property::Scalar(_, ty) => values.push(next(*ty)?),
                    Property::List(cty, ity) => {
                        let n = next(*cty)?;
                        if n < 0.0 {
                            return Err(fmt(format!(
                                "{} {index}: negative list length",
                                element.name
                            )));
                        }
                        for _ in 0..n as usize {
                            next(*ity)?;
                        }
                        values.push(n);
                    }
                }
            }
            if tokens.next().is_some() {
                return Err(fmt(format!(
                    "{} {index}: more values than properties",
                    element.name
                )));
            }
            if element.name == "vertex" {
                vertices.push(&values, index)?;
            }
        }
    }
    let extra = lines.count();
    if extra > 0 {
        let last = elements.last().map(|e| e.count).unwrap_or(0);
        return Err(KinectError::CountMismatch {
            path: path.to_path_buf(),
            what: "elements (last element)",
            declared: last,
            found: last + extra,
        });
    }
    Ok(())
}

/// A binary body (little- or big-endian): every element's records, the vertices into
/// `vertices`.
fn read_binary(
    data: &[u8],
    elements: &[Element],
    path: &Path,
    le: bool,
    vertices: &mut Vertices<'_>,
) -> Result<()> {
    let fmt = |what: String| KinectError::format(path, what);
    let mut values: Vec<f64> = Vec::new();
    let mut at = 0usize;
    for element in elements {
        for index in 0..element.count {
            values.clear();
            let truncated = || element.truncated(path, index);
            for property in &element.properties {
                match property {
                    Property::Scalar(_, ty) => {
                        let v = data
                            .get(at..)
                            .and_then(|b| ty.read(b, le))
                            .ok_or_else(truncated)?;
                        at += ty.size();
                        values.push(v);
                    }
                    Property::List(cty, ity) => {
                        let n = data
                            .get(at..)
                            .and_then(|b| cty.read(b, le))
                            .ok_or_else(truncated)?;
                        at += cty.size();
                        if n < 0.0 {
                            return Err(fmt(format!(
                                "{} {index}: negative list length",
                                element.name
                            )));
                        }
                        let skip = (n as usize).saturating_mul(ity.size());
                        at = at.saturating_add(skip);
                        if at > data.len() {
                            return Err(truncated());
                        }
                        values.push(n);
                    }
                }
            }
            if element.name == "vertex" {
                vertices.push(&values, index)?;
            }
        }
    }
    if at < data.len() {
        return Err(fmt(format!(
            "{} bytes after the last element the header declares",
            data.len() - at
        )));
    }
    Ok(())
}

/// Write the existing points of a cloud (organized clouds lose their grid: PLY has none) as
/// PLY with `double` coordinates and, when the cloud has colour, `uchar` colours.
///
/// # Errors
/// [`KinectError::InvalidParameter`] for an invalid cloud; [`KinectError::Io`] when the file
/// cannot be written.
pub fn write_ply(cloud: &PointCloud, path: &Path, format: PlyFormat) -> Result<()> {
    let bytes = encode_ply(cloud, format)?;
    std::fs::write(path, bytes).map_err(|e| KinectError::io(path, e))
}

/// Encode a cloud as PLY bytes (see [`write_ply`]).
///
/// # Errors
/// [`KinectError::InvalidParameter`] for an invalid cloud.
pub fn encode_ply(cloud: &PointCloud, format: PlyFormat) -> Result<Vec<u8>> {
    cloud.validate()?;
    let n = cloud.valid_count();
    let mut header = String::new();
    header.push_str("ply\n");
    header.push_str(match format {
        PlyFormat::Ascii => "format ascii 1.0\n",
        PlyFormat::BinaryLittleEndian => "format binary_little_endian 1.0\n",
    });
    header.push_str("comment written by treemocap kinect-io; units: metres\n");
    let _ = writeln!(header, "element vertex {n}");
    header.push_str("property double x\nproperty double y\nproperty double z\n");
    if cloud.colors.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    header.push_str("end_header\n");
    let mut out = header.into_bytes();
    match format {
        PlyFormat::Ascii => {
            let mut body = String::with_capacity(n * 48);
            for (p, c) in cloud.valid_points() {
                let _ = write!(body, "{} {} {}", p.x, p.y, p.z);
                if let Some([r, g, b]) = c {
                    let _ = write!(body, " {r} {g} {b}");
                }
                body.push('\n');
            }
            out.extend_from_slice(body.as_bytes());
        }
        PlyFormat::BinaryLittleEndian => {
            out.reserve(n * 27);
            for (p, c) in cloud.valid_points() {
                for v in [p.x, p.y, p.z] {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                if let Some(c) = c {
                    out.extend_from_slice(&c);
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_faces_after_vertices_and_float_colours() {
        let text = "ply\nformat ascii 1.0\ncomment x\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float red\nproperty float green\nproperty float blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n1 2 3 1 0 0.5\n4 5 6 0 1 0\n3 0 1 1\n";
        let cloud = parse_ply(text.as_bytes()).expect("valid");
        assert_eq!(cloud.points[1], Some(Point3::new(4.0, 5.0, 6.0)));
        assert_eq!(cloud.colors.expect("colour")[0], [255, 0, 128]);
    }

    #[test]
    fn lying_counts_are_reported() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 5 6\n";
        let err = parse_ply(text.as_bytes()).expect_err("short");
        assert!(
            matches!(
                err,
                KinectError::CountMismatch {
                    declared: 3,
                    found: 2,
                    ..
                }
            ),
            "{err}"
        );
        let text = text.replace("vertex 3", "vertex 1");
        let err = parse_ply(text.as_bytes()).expect_err("long");
        assert!(
            matches!(
                err,
                KinectError::CountMismatch {
                    declared: 1,
                    found: 2,
                    ..
                }
            ),
            "{err}"
        );
    }

    #[test]
    fn truncated_binary_is_reported() {
        let cloud = PointCloud::from_points(vec![Point3::new(1.0, 2.0, 3.0); 4]);
        let bytes = encode_ply(&cloud, PlyFormat::BinaryLittleEndian).expect("valid");
        let err = parse_ply(&bytes[..bytes.len() - 5]).expect_err("truncated");
        assert!(
            matches!(
                err,
                KinectError::CountMismatch {
                    declared: 4,
                    found: 3,
                    ..
                }
            ),
            "{err}"
        );
    }

    #[test]
    fn big_endian_is_read() {
        let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
        for v in [1.5f32, -2.0, 3.25] {
            bytes.extend_from_slice(&v.to_be_bytes());
        }
        let cloud = parse_ply(&bytes).expect("valid");
        assert_eq!(cloud.points[0], Some(Point3::new(1.5, -2.0, 3.25)));
    }
}
