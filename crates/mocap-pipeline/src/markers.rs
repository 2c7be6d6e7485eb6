//! The markers file of a capture (`markers.json`, described in `docs/capture.md`): each
//! marker's name, its parent in the hierarchy, its window on the first colour image and, for
//! a branch, the time window of its own pull-and-release test; plus the camera's height and
//! pitch for the tree frame.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{PipelineError, Result};
use crate::pipeline::short;

/// Camera height above the ground assumed when the file gives none, metres.
pub const DEFAULT_CAMERA_HEIGHT_M: f64 = 1.0;

/// Smallest marker window side, pixels (a mean-shift window needs a centre and a ring).
pub const MIN_WINDOW_PX: f64 = 3.0;

/// The markers of one capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkersFile {
    /// The markers; exactly one has no parent (the trunk's, the root of the hierarchy).
    pub markers: Vec<MarkerEntry>,
    /// Camera height above the ground, metres (for the Z-up tree frame). Default 1.0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_height_m: Option<f64>,
    /// Camera pitch below the horizon, degrees. Default 0 (level).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_down_deg: Option<f64>,
    /// The file it was read from, to name in errors (not part of the file).
    #[serde(skip)]
    pub source: Option<PathBuf>,
}

/// One marker of a [`MarkersFile`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerEntry {
    /// Marker name (a CSV column name: no comma, quote or line break).
    pub id: String,
    /// Parent marker, `None` (`null`) for the root.
    pub parent: Option<String>,
    /// Left edge of the window on the first colour image, pixels.
    pub x: f64,
    /// Top edge of the window, pixels.
    pub y: f64,
    /// Window width, pixels.
    pub w: f64,
    /// Window height, pixels.
    pub h: f64,
    /// The branch's own pull-and-release test, seconds from the first frame: the branch is
    /// measured inside it only. Default: the whole recording.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_s: Option<[f64; 2]>,
}

impl MarkerEntry {
    /// Centre of the window, colour pixels.
    pub fn center_px(&self) -> [f64; 2] {
        [self.x + 0.5 * self.w, self.y + 0.5 * self.h]
    }
}

impl MarkersFile {
    /// Read and check a markers file.
    ///
    /// # Errors
    /// [`PipelineError::Io`] when it cannot be read, [`PipelineError::Markers`] naming the
    /// marker and field when it is not valid JSON of this schema or breaks a rule of
    /// [`MarkersFile::validate`].
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| PipelineError::io(path, e))?;
        Self::parse(&text, path)
    }

    /// Parse and check the text of a markers file; `path` only names it in errors.
    ///
    /// # Errors
    /// As [`MarkersFile::read`], without the I/O.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let file: Self = serde_json::from_str(text).map_err(|e| PipelineError::Markers {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        let file = Self {
            source: Some(path.to_path_buf()),
            ..file
        };
        file.validate().map_err(|reason| file.error(reason))?;
        Ok(file)
    }

    /// Write the file as pretty JSON (through a temporary file, so a failure leaves no half
    /// file).
    ///
    /// # Errors
    /// [`PipelineError::Io`] naming the file.
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(|source| PipelineError::Json {
            what: "markers file",
            source,
        })? + "\n";
        crate::report::write_atomic(path, text.as_bytes())
    }

    /// Check the rules a reader of the file relies on: at least one marker, exactly one
    /// root, unique non-empty ids without comma, quote or line break, parents that exist,
    /// finite windows at least [`MIN_WINDOW_PX`] wide, `0 <= start < end` test windows, a
    /// finite camera height and pitch.
    ///
    /// # Errors
    /// The first rule broken, naming the marker and field.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if self.markers.is_empty() {
            return Err("no markers".into());
        }
        let roots: Vec<&str> = self
            .markers
            .iter()
            .filter(|m| m.parent.is_none())
            .map(|m| m.id.as_str())
            .collect();
        if roots.len() != 1 {
            let found = if roots.is_empty() {
                "none has".to_string()
            } else {
                format!("{} have ({})", roots.len(), roots.join(", "))
            };
            return Err(format!(
                "exactly one marker must have \"parent\": null (the trunk's, the root of the hierarchy); {found}"
            ));
        }
        for m in &self.markers {
            check_marker(self, m)?;
        }
        if let Some(h) = self.camera_height_m
            && !(h.is_finite() && h.abs() <= 1e3)
        {
            return Err(format!(
                "camera_height_m {} must be a finite height in metres (|h| <= 1000)",
                short(h)
            ));
        }
        if let Some(p) = self.pitch_down_deg
            && !(p.is_finite() && p.abs() <= 90.0)
        {
            return Err(format!(
                "pitch_down_deg {} must lie in -90..=90 degrees",
                short(p)
            ));
        }
        Ok(())
    }

    /// Each branch's test window, seconds, by marker id.
    pub fn windows_s(&self) -> std::collections::BTreeMap<String, (f64, f64)> {
        self.markers
            .iter()
            .filter_map(|m| m.window_s.map(|w| (m.id.clone(), (w[0], w[1]))))
            .collect()
    }

    /// An error about this file: [`PipelineError::Markers`] naming its source (or
    /// `<markers in memory>`).
    pub(crate) fn error(&self, reason: String) -> PipelineError {
        PipelineError::Markers {
            path: self
                .source
                .clone()
                .unwrap_or_else(|| PathBuf::from("<markers in memory>")),
            reason,
        }
    }
}

fn check_marker(file: &MarkersFile, m: &MarkerEntry) -> std::result::Result<(), String> {
    if m.id.trim().is_empty() || m.id.contains([',', '"', '\n', '\r']) {
        return Err(format!(
            "marker id {:?} is empty or holds a comma, quote or line break",
            m.id
        ));
    }
    if file.markers.iter().filter(|q| q.id == m.id).count() > 1 {
        return Err(format!("marker id {:?} appears twice", m.id));
    }
    if let Some(p) = &m.parent
        && !file.markers.iter().any(|q| q.id == *p)
    {
        return Err(format!(
            "marker {} names parent {p:?}, which is not in the file",
            m.id
        ));
    }
    if let Some([start, end]) = m.window_s
        && !(start.is_finite() && end.is_finite() && start >= 0.0 && start < end)
    {
        return Err(format!(
            "marker {}: window_s [{}, {}] must be [start, end] in seconds from the first frame, 0 <= start < end",
            m.id,
            short(start),
            short(end)
        ));
    }
    if ![m.x, m.y, m.w, m.h].iter().all(|v| v.is_finite())
        || m.w < MIN_WINDOW_PX
        || m.h < MIN_WINDOW_PX
    {
        return Err(format!(
            "marker {}: window x {}, y {}, w {}, h {} must be finite and at least {MIN_WINDOW_PX} px wide",
            m.id,
            short(m.x),
            short(m.y),
            short(m.w),
            short(m.h)
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(id: &str, parent: Option<&str>) -> MarkerEntry {
        MarkerEntry {
            id: id.into(),
            parent: parent.map(str::to_string),
            x: 10.0,
            y: 20.0,
            w: 8.0,
            h: 8.0,
            window_s: None,
        }
    }

    #[test]
    fn round_trip_and_rules() {
        let file = MarkersFile {
            markers: vec![entry("A", None), entry("B", Some("A"))],
            camera_height_m: Some(1.2),
            pitch_down_deg: None,
            source: None,
        };
        let text = serde_json::to_string(&file).expect("encodes");
        let back = MarkersFile::parse(&text, Path::new("m.json")).expect("valid");
        assert_eq!(back.source.as_deref(), Some(Path::new("m.json")));
        assert_eq!(back.markers, file.markers);
        assert_eq!(back.markers[1].center_px(), [14.0, 24.0]);

        let two_roots = MarkersFile {
            markers: vec![entry("A", None), entry("B", None)],
            ..file.clone()
        };
        assert!(two_roots.validate().unwrap_err().contains("B"));
        let unknown_parent = MarkersFile {
            markers: vec![entry("A", None), entry("B", Some("Z"))],
            ..file.clone()
        };
        assert!(unknown_parent.validate().unwrap_err().contains("\"Z\""));
        let mut small = file.clone();
        small.markers[1].w = 2.0;
        assert!(small.validate().unwrap_err().contains("marker B"));
        let mut reversed = file;
        reversed.markers[1].window_s = Some([3.0, 1.0]);
        assert!(reversed.validate().unwrap_err().contains("window_s"));
        let err = MarkersFile::parse(r#"{"markers": [], "extra": 1}"#, Path::new("m.json"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("m.json") && err.contains("extra"), "{err}");
    }
}
