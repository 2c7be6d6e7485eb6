//! The subset of OpenCV's `FileStorage` YAML that camera calibrations use.
//!
//! OpenCV writes `%YAML:1.0` (not valid YAML 1.1/1.2 for a general YAML parser), then top-level
//! `key: value` pairs where a matrix is a `!!opencv-matrix` mapping of `rows`, `cols`, `dt` and a
//! flow sequence `data: [ ... ]` that may span lines. That is all iai_kinect2's `calib_*.yaml`
//! files hold, and all this reader accepts; anything else is a [`KinectError::Format`] naming
//! the line.

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::{KinectError, Result};

/// A value of a top-level key.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum YamlValue {
    /// A scalar, as written (quotes removed).
    Scalar(String),
    /// An `!!opencv-matrix`, row-major.
    Matrix {
        rows: usize,
        cols: usize,
        data: Vec<f64>,
    },
}

/// Parse a FileStorage YAML document into its top-level keys.
pub(crate) fn parse(text: &str, path: &Path) -> Result<BTreeMap<String, YamlValue>> {
    let mut out = BTreeMap::new();
    let lines: Vec<&str> = text.lines().collect();
    let mut i = 0;
    while i < lines.len() {
        let line = strip_comment(lines[i]);
        let lineno = i + 1;
        i += 1;
        if line.trim().is_empty() || line.starts_with('%') || line.trim() == "---" {
            continue;
        }
        if line.starts_with(char::is_whitespace) {
            return Err(KinectError::format(
                path,
                format!(
                    "line {lineno}: indented line outside a mapping: {:?}",
                    line.trim()
                ),
            ));
        }
        let (key, rest) = split_key(line).ok_or_else(|| {
            KinectError::format(path, format!("line {lineno}: expected `key: value`"))
        })?;
        let rest = rest.trim();
        if rest.starts_with("!!opencv-matrix") {
            let mut body = String::new();
            while i < lines.len() && lines[i].starts_with(char::is_whitespace) {
                body.push_str(strip_comment(lines[i]));
                body.push('\n');
                i += 1;
            }
            let value = parse_matrix(&body, path, lineno, key)?;
            out.insert(key.to_string(), value);
        } else if rest.is_empty() {
            // A nested mapping we do not interpret (ROS header, etc.): skip its block.
            while i < lines.len()
                && (lines[i].starts_with(char::is_whitespace) || lines[i].trim().is_empty())
            {
                i += 1;
            }
        } else {
            out.insert(
                key.to_string(),
                YamlValue::Scalar(unquote(rest).to_string()),
            );
        }
    }
    Ok(out)
}

fn strip_comment(line: &str) -> &str {
    match line.find(" #") {
        Some(at) => &line[..at],
        None if line.trim_start().starts_with('#') => "",
        None => line,
    }
}

fn split_key(line: &str) -> Option<(&str, &str)> {
    let at = line.find(':')?;
    let key = line[..at].trim();
    (!key.is_empty()).then(|| (key, &line[at + 1..]))
}

fn unquote(s: &str) -> &str {
    let s = s.trim();
    if s.len() >= 2
        && ((s.starts_with('"') && s.ends_with('"')) || (s.starts_with('\'') && s.ends_with('\'')))
    {
        &s[1..s.len() - 1]
    } else {
        s
    }
}

fn parse_matrix(body: &str, path: &Path, lineno: usize, key: &str) -> Result<YamlValue> {
    let bad =
        |what: String| KinectError::format(path, format!("line {lineno}: matrix `{key}`: {what}"));
    let mut rows = None;
    let mut cols = None;
    let mut data = None;
    let mut rest = body;
    while let Some(colon) = rest.find(':') {
        let field = rest[..colon].trim();
        let after = &rest[colon + 1..];
        match field {
            "rows" | "cols" | "dt" => {
                let end = after.find('\n').unwrap_or(after.len());
                let value = after[..end].trim();
                match field {
                    "rows" => rows = value.parse::<usize>().ok(),
                    "cols" => cols = value.parse::<usize>().ok(),
                    _ => {
                        if value != "d" && value != "f" {
                            return Err(bad(format!("element type `{value}` (expected d or f)")));
                        }
                    }
                }
                rest = &after[end..];
            }
            "data" => {
                let open = after
                    .find('[')
                    .ok_or_else(|| bad("`data` is not a `[ ... ]` sequence".into()))?;
                let close = after
                    .find(']')
                    .ok_or_else(|| bad("`data` sequence is not closed with `]`".into()))?;
                if close < open {
                    return Err(bad("`data` sequence is malformed".into()));
                }
                let values: std::result::Result<Vec<f64>, _> = after[open + 1..close]
                    .split(',')
                    .map(str::trim)
                    .filter(|s| !s.is_empty())
                    .map(|s| s.parse::<f64>())
                    .collect();
                data = Some(values.map_err(|e| bad(format!("`data` holds a non-number ({e})")))?);
                rest = &after[close + 1..];
            }
            other => return Err(bad(format!("unknown field `{other}`"))),
        }
    }
    let rows = rows.ok_or_else(|| bad("missing or malformed `rows`".into()))?;
    let cols = cols.ok_or_else(|| bad("missing or malformed `cols`".into()))?;
    let data = data.ok_or_else(|| bad("missing `data`".into()))?;
    if rows.checked_mul(cols) != Some(data.len()) {
        return Err(KinectError::CountMismatch {
            path: path.to_path_buf(),
            what: "matrix elements",
            declared: rows.saturating_mul(cols),
            found: data.len(),
        });
    }
    if data.iter().any(|v| !v.is_finite()) {
        return Err(bad("`data` holds a value that is not finite".into()));
    }
    Ok(YamlValue::Matrix { rows, cols, data })
}

/// Fetch a matrix of a given shape.
pub(crate) fn matrix<'a>(
    doc: &'a BTreeMap<String, YamlValue>,
    key: &str,
    shape: (usize, usize),
    path: &Path,
) -> Result<&'a [f64]> {
    match doc.get(key) {
        Some(YamlValue::Matrix { rows, cols, data }) if (*rows, *cols) == shape => Ok(data),
        Some(YamlValue::Matrix { rows, cols, .. }) => Err(KinectError::calibration(
            path,
            format!("`{key}` is {rows}x{cols}, expected {}x{}", shape.0, shape.1),
        )),
        Some(YamlValue::Scalar(_)) => Err(KinectError::calibration(
            path,
            format!("`{key}` is a scalar, expected an opencv-matrix"),
        )),
        None => Err(KinectError::calibration(
            path,
            format!("`{key}` is missing"),
        )),
    }
}

/// Fetch a matrix holding a vector of any orientation.
pub(crate) fn vector<'a>(
    doc: &'a BTreeMap<String, YamlValue>,
    key: &str,
    path: &Path,
) -> Result<&'a [f64]> {
    match doc.get(key) {
        Some(YamlValue::Matrix { rows, cols, data }) if *rows == 1 || *cols == 1 => Ok(data),
        Some(_) => Err(KinectError::calibration(
            path,
            format!("`{key}` is not a 1xN or Nx1 opencv-matrix"),
        )),
        None => Err(KinectError::calibration(
            path,
            format!("`{key}` is missing"),
        )),
    }
}

/// Fetch a floating-point scalar.
pub(crate) fn scalar(doc: &BTreeMap<String, YamlValue>, key: &str, path: &Path) -> Result<f64> {
    match doc.get(key) {
        Some(YamlValue::Scalar(s)) => {
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    KinectError::calibration(path, format!("`{key}` = {s:?} is not a number"))
                })
        }
        Some(_) => Err(KinectError::calibration(
            path,
            format!("`{key}` is not a scalar"),
        )),
        None => Err(KinectError::calibration(
            path,
            format!("`{key}` is missing"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = "%YAML:1.0\ncameraMatrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1.0e+03, 0., 9.5e+02, 0.,\n       1.0e+03, 5.4e+02, 0., 0., 1. ]\ndepthShift: -1.3e+01\n";

    #[test]
    fn reads_multiline_matrices_and_scalars() {
        let doc = parse(SAMPLE, Path::new("x")).expect("valid");
        let k = matrix(&doc, "cameraMatrix", (3, 3), Path::new("x")).expect("3x3");
        assert_eq!(k[2], 950.0);
        assert_eq!(k[8], 1.0);
        assert_eq!(
            scalar(&doc, "depthShift", Path::new("x")).expect("num"),
            -13.0
        );
    }

    #[test]
    fn element_count_must_match() {
        let text = SAMPLE.replace("0., 0., 1. ]", "0., 0. ]");
        let err = parse(&text, Path::new("x")).expect_err("8 of 9");
        assert!(matches!(
            err,
            KinectError::CountMismatch {
                declared: 9,
                found: 8,
                ..
            }
        ));
    }

    #[test]
    fn unclosed_data_is_an_error() {
        let text = SAMPLE.replace("1. ]", "1.");
        assert!(parse(&text, Path::new("x")).is_err());
    }
}
