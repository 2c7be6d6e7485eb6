//! Point clouds as files hold them, and XYZ text files.
//!
//! [`PointCloud`] is the exchange type of the file readers and writers ([`crate::read_ply`],
//! [`crate::read_pcd`], [`read_xyz`], and [`read_point_cloud`] which picks by extension). It
//! may be organized (`height > 1`, one entry per pixel, `None` where a pixel has no point, as
//! PCD stores NaN) or not (`height == 1`).

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Point3;

use crate::cloud::TexturedCloud;
use crate::error::{KinectError, Result};

/// A point cloud with optional colour.
#[derive(Debug, Clone, PartialEq)]
pub struct PointCloud {
    /// Entries per row (all entries when not organized).
    pub width: u32,
    /// Rows (1 when not organized).
    pub height: u32,
    /// `width * height` entries, row-major; `None` marks a pixel without a point.
    pub points: Vec<Option<Point3<f64>>>,
    /// One colour per entry when the cloud has colour.
    pub colors: Option<Vec<[u8; 3]>>,
}

impl PointCloud {
    /// An unorganized cloud of the given points (no colour).
    pub fn from_points(points: Vec<Point3<f64>>) -> Self {
        Self {
            width: points.len() as u32,
            height: 1,
            points: points.into_iter().map(Some).collect(),
            colors: None,
        }
    }

    /// An organized cloud from a textured cloud; points that have depth but no colour get
    /// `fill_rgb` (the file formats have no "no colour" value, so the choice is the caller's).
    pub fn from_textured(cloud: &TexturedCloud, fill_rgb: [u8; 3]) -> Self {
        Self {
            width: cloud.width(),
            height: cloud.height(),
            points: (0..cloud.len()).map(|i| cloud.position_m(i)).collect(),
            colors: Some(
                (0..cloud.len())
                    .map(|i| cloud.color(i).unwrap_or(fill_rgb))
                    .collect(),
            ),
        }
    }

    /// Check that the entry and colour counts match the size.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] naming the mismatch, or a point that is not finite.
    pub fn validate(&self) -> Result<()> {
        let n = self.width as usize * self.height as usize;
        if self.points.len() != n {
            return Err(KinectError::param(
                "point cloud",
                format!(
                    "{} entries for {}x{} (needs {n})",
                    self.points.len(),
                    self.width,
                    self.height
                ),
            ));
        }
        if let Some(c) = &self.colors
            && c.len() != n
        {
            return Err(KinectError::param(
                "point cloud colours",
                format!("{} colours for {n} entries", c.len()),
            ));
        }
        if let Some(i) = self
            .points
            .iter()
            .position(|p| p.is_some_and(|p| !p.iter().all(|c| c.is_finite())))
        {
            return Err(KinectError::param(
                "point cloud",
                format!("entry {i} is not finite (use None for a missing point)"),
            ));
        }
        Ok(())
    }

    /// True when the cloud has rows (`height > 1`).
    pub fn is_organized(&self) -> bool {
        self.height > 1
    }

    /// Number of entries that hold a point.
    pub fn valid_count(&self) -> usize {
        self.points.iter().filter(|p| p.is_some()).count()
    }

    /// The points (and colours) that exist, in order.
    pub fn valid_points(&self) -> impl Iterator<Item = (Point3<f64>, Option<[u8; 3]>)> + '_ {
        self.points.iter().enumerate().filter_map(|(i, p)| {
            p.map(|p| (p, self.colors.as_ref().and_then(|c| c.get(i).copied())))
        })
    }
}

/// Read a point cloud, choosing the reader by extension: `.ply`, `.pcd`, or XYZ text
/// (`.xyz`, `.txt`, `.csv`, `.pts` and anything else).
///
/// # Errors
/// As the reader chosen.
pub fn read_point_cloud(path: &Path) -> Result<PointCloud> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        "ply" => crate::ply::read_ply(path),
        "pcd" => crate::pcd::read_pcd(path),
        _ => read_xyz(path),
    }
}

/// Read an XYZ text file: one point per line, `x y z` or `x y z r g b`, separated by
/// whitespace and/or commas. Blank lines and lines starting with `#` or `//` are skipped, as
/// is a first line that is a header (first field not a number). Colour is read when the first
/// point has six or more fields whose 4th–6th are integers in 0..=255; then every line must
/// have them. Further fields (normals, intensity) are not read.
///
/// # Errors
/// [`KinectError::Io`] when unreadable; [`KinectError::Format`] naming the line of a
/// malformed or non-finite value, a missing colour, or a file without points.
pub fn read_xyz(path: &Path) -> Result<PointCloud> {
    let bytes = std::fs::read(path).map_err(|e| KinectError::io(path, e))?;
    parse_xyz(&bytes, path)
}

/// Parse XYZ text from bytes; `path` only names it in errors.
///
/// # Errors
/// As [`read_xyz`].
pub fn parse_xyz(bytes: &[u8], path: &Path) -> Result<PointCloud> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| KinectError::format(path, format!("not UTF-8 text ({e})")))?;
    let mut points = Vec::new();
    let mut colors: Option<Vec<[u8; 3]>> = None;
    let mut seen_data = false;
    for (lineno, line) in text.lines().enumerate() {
        let lineno = lineno + 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with("//") {
            continue;
        }
        let fields: Vec<&str> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .collect();
        if !seen_data && fields.first().is_some_and(|f| f.parse::<f64>().is_err()) {
            seen_data = true; // a header line
            continue;
        }
        seen_data = true;
        if fields.len() < 3 {
            return Err(KinectError::format(
                path,
                format!(
                    "line {lineno}: {} fields, need at least x y z",
                    fields.len()
                ),
            ));
        }
        let mut xyz = [0.0; 3];
        for (k, f) in fields[..3].iter().enumerate() {
            xyz[k] = f
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    KinectError::format(
                        path,
                        format!("line {lineno}: {f:?} is not a finite number"),
                    )
                })?;
        }
        let rgb = (fields.len() >= 6)
            .then(|| {
                let mut c = [0u8; 3];
                for k in 0..3 {
                    c[k] = fields[3 + k].parse::<u8>().ok()?;
                }
                Some(c)
            })
            .flatten();
        if points.is_empty() {
            colors = rgb.map(|_| Vec::new());
        }
        if let Some(colors) = colors.as_mut() {
            let c = rgb.ok_or_else(|| {
                KinectError::format(
                    path,
                    format!(
                        "line {lineno}: expected r g b (0..=255) after x y z, as on the first point"
                    ),
                )
            })?;
            colors.push(c);
        }
        points.push(Some(Point3::new(xyz[0], xyz[1], xyz[2])));
    }
    if points.is_empty() {
        return Err(KinectError::format(path, "no points"));
    }
    Ok(PointCloud {
        width: points.len() as u32,
        height: 1,
        points,
        colors,
    })
}

/// Write XYZ text: `x y z` or `x y z r g b` per existing point, space-separated, with full
/// `f64` precision (values round-trip exactly).
///
/// # Errors
/// [`KinectError::InvalidParameter`] for an invalid cloud, [`KinectError::Io`] when the file
/// cannot be written.
pub fn write_xyz(cloud: &PointCloud, path: &Path) -> Result<()> {
    cloud.validate()?;
    let mut out = String::with_capacity(cloud.points.len() * 40);
    for (p, c) in cloud.valid_points() {
        let _ = write!(out, "{} {} {}", p.x, p.y, p.z);
        if let Some([r, g, b]) = c {
            let _ = write!(out, " {r} {g} {b}");
        }
        out.push('\n');
    }
    std::fs::write(path, out).map_err(|e| KinectError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth::memory_path;

    #[test]
    fn xyz_with_commas_header_and_colour() {
        let cloud = parse_xyz(
            b"X,Y,Z,R,G,B\n1,2,3,4,5,6\n\n# c\n7 8 9 10 11 12\n",
            memory_path(),
        )
        .expect("valid");
        assert_eq!(cloud.points.len(), 2);
        assert_eq!(cloud.colors, Some(vec![[4, 5, 6], [10, 11, 12]]));
        assert_eq!(cloud.points[1], Some(Point3::new(7.0, 8.0, 9.0)));
    }

    #[test]
    fn xyz_errors_name_the_line() {
        let err = parse_xyz(b"1 2 3\n4 5\n", memory_path()).expect_err("short line");
        assert!(err.to_string().contains("line 2"), "{err}");
        let err = parse_xyz(b"1 2 3 0 0 0\n4 5 6\n", memory_path()).expect_err("colour lost");
        assert!(err.to_string().contains("line 2"), "{err}");
        assert!(parse_xyz(b"1 2 nan\n", memory_path()).is_err());
        assert!(parse_xyz(b"", memory_path()).is_err());
    }

    #[test]
    fn invalid_clouds_are_not_written() {
        let mut cloud = PointCloud::from_points(vec![Point3::new(0.0, 0.0, 0.0)]);
        cloud.width = 2;
        assert!(cloud.validate().is_err());
    }
}
