//! PCD point clouds (the Point Cloud Library's format, v0.7): `DATA ascii`, `binary` and
//! `binary_compressed` (LZF) are read; `ascii` and `binary` are written. Organized clouds keep
//! their grid; a missing point is NaN in the file and `None` in [`PointCloud`]. Colour is the
//! packed `rgb`/`rgba` field (`0x00RRGGBB`, stored as `F 4` by PCL or as `U 4`).

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Point3;

use crate::depth::memory_path;
use crate::error::{KinectError, Result};
use crate::pointcloud::PointCloud;
use crate::scalar::Scalar;

/// Encoding of the data section of a written PCD file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PcdData {
    /// Text.
    Ascii,
    /// Binary, little-endian, point by point (the default).
    #[default]
    Binary,
}

/// Coordinate type of a written PCD file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PcdPrecision {
    /// `F 4`: what PCL's `PointXYZ`/`PointXYZRGB` load (the default). Rounds coordinates to
    /// `f32` (about 0.1 µm at 1 m, 8 mm at 100 km: fine for camera-frame data; use
    /// [`PcdPrecision::Float64`] for georeferenced coordinates).
    #[default]
    Float32,
    /// `F 8`: exact `f64` coordinates (PCL's `PointXYZ` will not load these).
    Float64,
}

/// Options of [`write_pcd`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PcdWriteOptions {
    /// Data encoding.
    pub data: PcdData,
    /// Coordinate type.
    pub precision: PcdPrecision,
}

#[derive(Debug, Clone)]
struct Field {
    name: String,
    ty: Scalar,
    count: usize,
    offset: usize,
}

/// Read a PCD file.
///
/// # Errors
/// [`KinectError::Io`] when unreadable; [`KinectError::Format`] for a malformed header or
/// value or missing `x y z`; [`KinectError::CountMismatch`] when `POINTS` differs from
/// `WIDTH * HEIGHT` or from the data.
pub fn read_pcd(path: &Path) -> Result<PointCloud> {
    let bytes = std::fs::read(path).map_err(|e| KinectError::io(path, e))?;
    parse_pcd_at(&bytes, path)
}

/// Parse a PCD file from bytes.
///
/// # Errors
/// As [`read_pcd`].
pub fn parse_pcd(bytes: &[u8]) -> Result<PointCloud> {
    parse_pcd_at(bytes, memory_path())
}

fn parse_pcd_at(bytes: &[u8], path: &Path) -> Result<PointCloud> {
    let header = read_header(bytes, path)?;
    let layout = Layout::new(header.clone(), path)?;
    let data = &bytes[header.body_at..];
    let xyz_rgb = match header.data_kind {
        "ascii" => read_ascii(data, &layout, path)?,
        "binary" => read_binary(data, &layout, path)?,
        _ => read_compressed(data, &layout, path)?,
    };
    assemble(xyz_rgb, &layout, path)
}

/// A header's values as read, up to its DATA line.
#[derive(Debug, Clone)]
struct Header {
    names: Vec<String>,
    sizes: Vec<usize>,
    types: Vec<char>,
    counts: Vec<usize>,
    width: Option<usize>,
    height: Option<usize>,
    points: Option<usize>,
    /// `ascii`, `binary` or `binary_compressed`.
    data_kind: &'static str,
    /// Offset of the data after the DATA line.
    body_at: usize,
}

/// The header's lines up to DATA.
fn read_header(bytes: &[u8], path: &Path) -> Result<Header> {
    let fmt = |what: String| KinectError::format(path, what);
    let mut pos = 0;
    let mut names: Vec<String> = Vec::new();
    let mut sizes: Vec<usize> = Vec::new();
    let mut types: Vec<char> = Vec::new();
    let mut counts: Vec<usize> = Vec::new();
    let (mut width, mut height, mut points) = (None, None, None);
    let mut lineno = 0;
    loop {
        let rest = &bytes[pos..];
        let Some(nl) = rest.iter().position(|&b| b == b'\n') else {
            return Err(fmt("header ends before a DATA line".into()));
        };
        lineno += 1;
        let line = std::str::from_utf8(&rest[..nl])
            .map_err(|_| fmt(format!("header line {lineno} is not text")))?
            .trim();
        pos += nl + 1;
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or_default().to_ascii_uppercase();
        let args: Vec<&str> = words.collect();
        let numbers = |what: &str| -> Result<Vec<usize>> {
            args.iter()
                .map(|a| {
                    a.parse::<usize>().map_err(|_| {
                        fmt(format!("line {lineno}: {what} value {a:?} is not a count"))
                    })
                })
                .collect()
        };
        let one = |what: &str| -> Result<usize> {
            match numbers(what)?.as_slice() {
                [v] => Ok(*v),
                _ => Err(fmt(format!("line {lineno}: {what} needs one value"))),
            }
        };
        match key.as_str() {
            "VERSION" | "VIEWPOINT" => {}
            "FIELDS" | "COLUMNS" => names = args.iter().map(|s| (*s).to_string()).collect(),
            "SIZE" => sizes = numbers("SIZE")?,
            "TYPE" => {
                types = args
                    .iter()
                    .map(|s| match *s {
                        "F" | "I" | "U" => Ok(s.chars().next().unwrap_or('F')),
                        other => Err(fmt(format!(
                            "line {lineno}: TYPE {other:?} is not F, I or U"
                        ))),
                    })
                    .collect::<Result<_>>()?;
            }
            "COUNT" => counts = numbers("COUNT")?,
            "WIDTH" => width = Some(one("WIDTH")?),
            "HEIGHT" => height = Some(one("HEIGHT")?),
            "POINTS" => points = Some(one("POINTS")?),
            "DATA" => {
                let data_kind = match args.first().map(|s| s.to_ascii_lowercase()).as_deref() {
                    Some("ascii") => "ascii",
                    Some("binary") => "binary",
                    Some("binary_compressed") => "binary_compressed",
                    other => return Err(fmt(format!("line {lineno}: unknown DATA {other:?}"))),
                };
                return Ok(Header {
                    names,
                    sizes,
                    types,
                    counts,
                    width,
                    height,
                    points,
                    data_kind,
                    body_at: pos,
                });
            }
            other => return Err(fmt(format!("line {lineno}: unknown header key {other:?}"))),
        }
    }
}

/// Where each point's values lie: the fields, the record size, the organisation and the
/// fields that hold x, y, z and the packed colour.
struct Layout {
    fields: Vec<Field>,
    record: usize,
    width: usize,
    height: usize,
    /// Points, width x height.
    n: usize,
    xyz: [usize; 3],
    rgb: Option<usize>,
}

impl Layout {
    /// The layout the header declares: one SIZE, TYPE and COUNT per field, a supported type
    /// for each, POINTS = WIDTH x HEIGHT, fields x, y and z.
    fn new(mut h: Header, path: &Path) -> Result<Self> {
        let fmt = |what: String| KinectError::format(path, what);
        if h.names.is_empty() {
            return Err(fmt("no FIELDS line".into()));
        }
        if h.counts.is_empty() {
            h.counts = vec![1; h.names.len()];
        }
        if h.sizes.len() != h.names.len()
            || h.types.len() != h.names.len()
            || h.counts.len() != h.names.len()
        {
            return Err(fmt(format!(
                "FIELDS ({}), SIZE ({}), TYPE ({}) and COUNT ({}) must have one entry per field",
                h.names.len(),
                h.sizes.len(),
                h.types.len(),
                h.counts.len()
            )));
        }
        let mut fields = Vec::with_capacity(h.names.len());
        let mut offset = 0usize;
        for k in 0..h.names.len() {
            let ty = match (h.types[k], h.sizes[k]) {
                ('F', 4) => Scalar::F32,
                ('F', 8) => Scalar::F64,
                ('I', 1) => Scalar::I8,
                ('U', 1) => Scalar::U8,
                ('I', 2) => Scalar::I16,
                ('U', 2) => Scalar::U16,
                ('I', 4) => Scalar::I32,
                ('U', 4) => Scalar::U32,
                (t, s) => {
                    return Err(KinectError::Unsupported {
                        path: path.to_path_buf(),
                        what: format!("field {:?} of TYPE {t} SIZE {s}", h.names[k]),
                    });
                }
            };
            fields.push(Field {
                name: h.names[k].clone(),
                ty,
                count: h.counts[k],
                offset,
            });
            offset = offset
                .checked_add(ty.size().saturating_mul(h.counts[k]))
                .ok_or_else(|| fmt("point record size overflows".into()))?;
        }
        let record = offset;
        let width = h.width.ok_or_else(|| fmt("no WIDTH line".into()))?;
        let height = h.height.unwrap_or(1);
        let n = width
            .checked_mul(height)
            .ok_or_else(|| fmt("WIDTH * HEIGHT overflows".into()))?;
        let points_declared = h.points.unwrap_or(n);
        if points_declared != n {
            return Err(KinectError::CountMismatch {
                path: path.to_path_buf(),
                what: "points (POINTS vs WIDTH x HEIGHT)",
                declared: points_declared,
                found: n,
            });
        }
        if width > u32::MAX as usize || height > u32::MAX as usize {
            return Err(fmt("WIDTH or HEIGHT exceeds u32".into()));
        }
        let find = |name: &str| fields.iter().position(|f| f.name == name);
        let (Some(ix), Some(iy), Some(iz)) = (find("x"), find("y"), find("z")) else {
            return Err(fmt("FIELDS lacks x, y or z".into()));
        };
        let rgb = find("rgb").or_else(|| find("rgba"));
        Ok(Self {
            fields,
            record,
            width,
            height,
            n,
            xyz: [ix, iy, iz],
            rgb,
        })
    }

    /// Bytes of binary point data the header declares.
    fn data_bytes(&self, path: &Path) -> Result<usize> {
        self.n
            .checked_mul(self.record)
            .ok_or_else(|| KinectError::format(path, "data size overflows"))
    }

    /// A point's coordinates and packed colour from the bytes where each field starts
    /// (`at(k)`: field `k`'s value and what follows it). A value that cannot be read is NaN.
    fn raw_point<'d>(&self, at: impl Fn(usize) -> &'d [u8]) -> RawPoint {
        let get = |k: usize| self.fields[k].ty.read(at(k), true).unwrap_or(f64::NAN);
        let [ix, iy, iz] = self.xyz;
        (
            [get(ix), get(iy), get(iz)],
            self.rgb.map(|k| packed_rgb_bytes(at(k))),
        )
    }

    /// The error for a file that holds `found` of the declared points.
    fn truncated(&self, path: &Path, found: usize) -> KinectError {
        KinectError::CountMismatch {
            path: path.to_path_buf(),
            what: "points",
            declared: self.n,
            found,
        }
    }
}

/// A point's coordinates and packed colour, before the finiteness check.
type RawPoint = ([f64; 3], Option<[u8; 3]>);

/// ASCII data: one line per point.
fn read_ascii(data: &[u8], layout: &Layout, path: &Path) -> Result<Vec<RawPoint>> {
    let fmt = |what: String| KinectError::format(path, what);
    let Layout { fields, n, .. } = layout;
    let (n, [ix, iy, iz], irgb) = (*n, layout.xyz, layout.rgb);
    let truncated = |found: usize| layout.truncated(path, found);
    let mut xyz_rgb = Vec::with_capacity(n.min(data.len()));
    let text = std::str::from_utf8(data).map_err(|_| fmt("ASCII data is not text".into()))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    for index in 0..n {
        let line = lines.next().ok_or_else(|| truncated(index))?;
        let tokens: Vec<&str> = line.split_whitespace().collect();
        let per_point: usize = fields.iter().map(|f| f.count).sum();
        if tokens.len() != per_point {
            return Err(fmt(format!(
                "point {index}: {} values, the header declares {per_point}",
                tokens.len()
            )));
        }
        let mut first_token = Vec::with_capacity(fields.len());
        let mut t = 0;
        for f in fields {
            first_token.push(t);
            t += f.count;
        }
        let value = |k: usize| -> Result<f64> {
            let s = tokens[first_token[k]];
            if s.eq_ignore_ascii_case("nan") {
                return Ok(f64::NAN);
            }
            fields[k].ty.parse(s).ok_or_else(|| {
                fmt(format!(
                    "point {index}: {s:?} is not a valid {:?}",
                    fields[k].ty
                ))
            })
        };
        let rgb = match irgb {
            Some(k) => Some(
                packed_rgb_text(tokens[first_token[k]], fields[k].ty).ok_or_else(|| {
                    fmt(format!(
                        "point {index}: rgb {:?} is not a packed colour",
                        tokens[first_token[k]]
                    ))
                })?,
            ),
            None => None,
        };
        xyz_rgb.push(([value(ix)?, value(iy)?, value(iz)?], rgb));
    }
    let extra = lines.count();
    if extra > 0 {
        return Err(KinectError::CountMismatch {
            path: path.to_path_buf(),
            what: "points",
            declared: n,
            found: n + extra,
        });
    }
    Ok(xyz_rgb)
}

/// Binary data: one record per point, little-endian.
fn read_binary(data: &[u8], layout: &Layout, path: &Path) -> Result<Vec<RawPoint>> {
    let needed = layout.data_bytes(path)?;
    let record = layout.record;
    if data.len() < needed {
        return Err(layout.truncated(path, data.len() / record.max(1)));
    }
    if data.len() > needed {
        return Err(KinectError::format(
            path,
            format!(
                "{} bytes after the {} points the header declares",
                data.len() - needed,
                layout.n
            ),
        ));
    }
    Ok((0..layout.n)
        .map(|index| {
            let rec = &data[index * record..(index + 1) * record];
            layout.raw_point(|k| &rec[layout.fields[k].offset..])
        })
        .collect())
}

/// LZF-compressed binary data, field-major.
fn read_compressed(data: &[u8], layout: &Layout, path: &Path) -> Result<Vec<RawPoint>> {
    let fmt = |what: String| KinectError::format(path, what);
    let header = data.get(..8).ok_or_else(|| layout.truncated(path, 0))?;
    let compressed = u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize;
    let uncompressed = u32::from_le_bytes([header[4], header[5], header[6], header[7]]) as usize;
    let needed = layout.data_bytes(path)?;
    if uncompressed != needed {
        return Err(KinectError::CountMismatch {
            path: path.to_path_buf(),
            what: "bytes of uncompressed point data",
            declared: needed,
            found: uncompressed,
        });
    }
    let body = data.get(8..8 + compressed).ok_or_else(|| {
        fmt(format!(
            "compressed data is {} bytes, the file holds {}",
            compressed,
            data.len().saturating_sub(8)
        ))
    })?;
    let raw = lzf_decompress(body, uncompressed).ok_or_else(|| fmt("corrupt LZF data".into()))?;
    // Field-major layout: all values of field 0, then field 1, ...
    let n = layout.n;
    let mut starts = Vec::with_capacity(layout.fields.len());
    let mut s = 0;
    for f in &layout.fields {
        starts.push(s);
        s += n * f.ty.size() * f.count;
    }
    Ok((0..n)
        .map(|index| {
            layout.raw_point(|k| {
                let f = &layout.fields[k];
                &raw[starts[k] + index * f.ty.size() * f.count..]
            })
        })
        .collect())
}

/// The cloud: NaN coordinates are missing points, infinite ones an error.
fn assemble(xyz_rgb: Vec<RawPoint>, layout: &Layout, path: &Path) -> Result<PointCloud> {
    let fmt = |what: String| KinectError::format(path, what);
    let irgb = layout.rgb;
    let mut cloud_points = Vec::with_capacity(xyz_rgb.len());
    let mut colors = irgb.map(|_| Vec::with_capacity(xyz_rgb.len()));
    for (index, ([x, y, z], rgb)) in xyz_rgb.into_iter().enumerate() {
        let finite = x.is_finite() && y.is_finite() && z.is_finite();
        let nan = x.is_nan() || y.is_nan() || z.is_nan();
        if !finite && !nan {
            return Err(fmt(format!("point {index} is infinite")));
        }
        cloud_points.push(finite.then(|| Point3::new(x, y, z)));
        if let (Some(c), Some(rgb)) = (colors.as_mut(), rgb) {
            c.push(rgb);
        }
    }
    Ok(PointCloud {
        width: layout.width as u32,
        height: layout.height as u32,
        points: cloud_points,
        colors,
    })
}

fn unpack(v: u32) -> [u8; 3] {
    [(v >> 16) as u8, (v >> 8) as u8, v as u8]
}

fn packed_rgb_bytes(b: &[u8]) -> [u8; 3] {
    match b.get(..4) {
        Some(&[b0, b1, b2, b3]) => unpack(u32::from_le_bytes([b0, b1, b2, b3])),
        _ => [0, 0, 0],
    }
}

fn packed_rgb_text(s: &str, ty: Scalar) -> Option<[u8; 3]> {
    if ty == Scalar::F32 {
        s.parse::<f32>().ok().map(|f| unpack(f.to_bits()))
    } else {
        s.parse::<u32>()
            .ok()
            .or_else(|| s.parse::<i32>().ok().map(|v| v as u32))
            .map(unpack)
    }
}

/// LZF decompression (Marc Lehmann's liblzf format, as PCL's `binary_compressed` uses it).
fn lzf_decompress(input: &[u8], expected: usize) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(expected);
    let mut i = 0;
    while i < input.len() {
        let ctrl = usize::from(input[i]);
        i += 1;
        if ctrl < 32 {
            let len = ctrl + 1;
            out.extend_from_slice(input.get(i..i + len)?);
            i += len;
        } else {
            let mut len = ctrl >> 5;
            if len == 7 {
                len += usize::from(*input.get(i)?);
                i += 1;
            }
            let back = ((ctrl & 0x1f) << 8) + usize::from(*input.get(i)?) + 1;
            i += 1;
            let start = out.len().checked_sub(back)?;
            for k in 0..len + 2 {
                let b = out[start + k];
                out.push(b);
            }
        }
        if out.len() > expected {
            return None;
        }
    }
    (out.len() == expected).then_some(out)
}

/// Write a PCD file. Organized clouds keep `WIDTH`/`HEIGHT`, missing points are NaN. Colour
/// is written as PCL's packed `rgb` (`U 4`).
///
/// # Errors
/// [`KinectError::InvalidParameter`] for an invalid cloud; [`KinectError::Io`] when the file
/// cannot be written.
pub fn write_pcd(cloud: &PointCloud, path: &Path, options: PcdWriteOptions) -> Result<()> {
    let bytes = encode_pcd(cloud, options)?;
    std::fs::write(path, bytes).map_err(|e| KinectError::io(path, e))
}

/// Encode a cloud as PCD bytes (see [`write_pcd`]).
///
/// # Errors
/// [`KinectError::InvalidParameter`] for an invalid cloud.
pub fn encode_pcd(cloud: &PointCloud, options: PcdWriteOptions) -> Result<Vec<u8>> {
    cloud.validate()?;
    let has_rgb = cloud.colors.is_some();
    let size = match options.precision {
        PcdPrecision::Float32 => 4,
        PcdPrecision::Float64 => 8,
    };
    let mut h = String::new();
    h.push_str("# .PCD v0.7 - Point Cloud Data file format (written by treemocap kinect-io; metres)\nVERSION 0.7\n");
    if has_rgb {
        let _ = writeln!(
            h,
            "FIELDS x y z rgb\nSIZE {size} {size} {size} 4\nTYPE F F F U\nCOUNT 1 1 1 1"
        );
    } else {
        let _ = writeln!(
            h,
            "FIELDS x y z\nSIZE {size} {size} {size}\nTYPE F F F\nCOUNT 1 1 1"
        );
    }
    let _ = writeln!(
        h,
        "WIDTH {}\nHEIGHT {}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {}",
        cloud.width,
        cloud.height,
        cloud.points.len()
    );
    h.push_str(match options.data {
        PcdData::Ascii => "DATA ascii\n",
        PcdData::Binary => "DATA binary\n",
    });
    let mut out = h.into_bytes();
    let packed = |i: usize| -> u32 {
        cloud
            .colors
            .as_ref()
            .and_then(|c| c.get(i))
            .map_or(0, |&[r, g, b]| {
                (u32::from(r) << 16) | (u32::from(g) << 8) | u32::from(b)
            })
    };
    match options.data {
        PcdData::Ascii => {
            let mut body = String::with_capacity(cloud.points.len() * 40);
            for (i, p) in cloud.points.iter().enumerate() {
                match (p, options.precision) {
                    (Some(p), PcdPrecision::Float64) => {
                        let _ = write!(body, "{} {} {}", p.x, p.y, p.z);
                    }
                    (Some(p), PcdPrecision::Float32) => {
                        let _ = write!(body, "{} {} {}", p.x as f32, p.y as f32, p.z as f32);
                    }
                    (None, _) => body.push_str("nan nan nan"),
                }
                if has_rgb {
                    let _ = write!(body, " {}", packed(i));
                }
                body.push('\n');
            }
            out.extend_from_slice(body.as_bytes());
        }
        PcdData::Binary => {
            for (i, p) in cloud.points.iter().enumerate() {
                let xyz = p.map_or([f64::NAN; 3], |p| [p.x, p.y, p.z]);
                for v in xyz {
                    match options.precision {
                        PcdPrecision::Float32 => out.extend_from_slice(&(v as f32).to_le_bytes()),
                        PcdPrecision::Float64 => out.extend_from_slice(&v.to_le_bytes()),
                    }
                }
                if has_rgb {
                    out.extend_from_slice(&packed(i).to_le_bytes());
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
    fn pcl_style_ascii_with_float_rgb_and_nan() {
        let rgb = f32::from_bits(0x00FF_8001);
        let text = format!(
            "# .PCD v.7\nVERSION .7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n1 2 3 {rgb:e}\nnan nan nan {rgb:e}\n"
        );
        let cloud = parse_pcd(text.as_bytes()).expect("valid");
        assert_eq!(cloud.points, vec![Some(Point3::new(1.0, 2.0, 3.0)), None]);
        assert_eq!(cloud.colors.expect("rgb")[0], [255, 128, 1]);
    }

    #[test]
    fn points_must_match_width_times_height() {
        let text = "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n";
        assert!(matches!(
            parse_pcd(text.as_bytes()),
            Err(KinectError::CountMismatch { .. })
        ));
    }

    #[test]
    fn lzf_literal_and_back_reference() {
        // "abcabcabc": literal "abc" (ctrl 2), then a back reference of length 6 at distance 3
        // (len - 2 = 4 in the top bits, offset - 1 = 2).
        let input = [2u8, b'a', b'b', b'c', (4 << 5) as u8, 2];
        assert_eq!(
            lzf_decompress(&input, 9).expect("valid"),
            b"abcabcabc".to_vec()
        );
        assert!(
            lzf_decompress(&[(4 << 5) as u8, 200], 6).is_none(),
            "reference before start"
        );
    }

    #[test]
    fn binary_compressed_is_read() {
        // Two points, fields x y z (F 4): field-major, stored as literals.
        let mut raw = Vec::new();
        for v in [1.0f32, 4.0, 2.0, 5.0, 3.0, 6.0] {
            raw.extend_from_slice(&v.to_le_bytes());
        }
        let mut lzf = vec![(raw.len() - 1) as u8];
        lzf.extend_from_slice(&raw);
        let mut bytes = b"VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary_compressed\n".to_vec();
        bytes.extend_from_slice(&(lzf.len() as u32).to_le_bytes());
        bytes.extend_from_slice(&(raw.len() as u32).to_le_bytes());
        bytes.extend_from_slice(&lzf);
        let cloud = parse_pcd(&bytes).expect("valid");
        assert_eq!(cloud.points[1], Some(Point3::new(4.0, 5.0, 6.0)));
    }
}
