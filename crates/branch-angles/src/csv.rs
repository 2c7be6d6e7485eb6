//! CSV files: trajectories (`t,id,x,y,z`, an empty position for a lost frame) and angle
//! tables (`t,<branch>,...`, degrees at this file edge, an empty cell where unknown).
//!
//! Numbers are written in Rust's shortest round-trip form, so a write–read cycle gives the
//! same `f64`s back. Fields are not quoted; ids cannot hold commas, quotes or line breaks.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Point3;

use crate::angles::AngleSet;
use crate::error::{AngleError, Result};
use crate::hierarchy::valid_id;
use crate::series::Series;
use crate::trajectory::{MarkerTrack, Trajectories};

/// One parsed trajectory row: time (s), position (m) or lost, line number.
type Row = (f64, Option<Point3<f64>>, usize);

/// The header of a trajectories file.
pub const TRAJECTORY_HEADER: &str = "t,id,x,y,z";

/// Read a whole text file.
///
/// # Errors
/// [`AngleError::Io`] naming the file.
pub fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| AngleError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Write a whole text file.
///
/// # Errors
/// [`AngleError::Io`] naming the file.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|source| AngleError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Lines with their 1-based numbers, without line ends, blank lines skipped.
fn lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(k, l)| (k + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim().is_empty())
}

fn number(line: usize, name: &str, field: &str) -> Result<f64> {
    let v: f64 = field
        .trim()
        .parse()
        .map_err(|_| AngleError::csv(line, format!("{name} {field:?} is not a number")))?;
    if !v.is_finite() {
        return Err(AngleError::csv(
            line,
            format!("{name} {field:?} is not finite"),
        ));
    }
    Ok(v)
}

/// Parse a trajectories file. Rows may come in any marker order (frame by frame, or marker by
/// marker), but each marker's timestamps must increase. The time base is the union of all
/// timestamps; a marker without a row at one of them is lost there.
///
/// # Errors
/// [`AngleError::Csv`] with the line for a missing or wrong header, a wrong number of fields,
/// a timestamp or coordinate that is not a finite number, a partly empty position, or an
/// invalid id; [`AngleError::UnsortedTimestamps`] / [`AngleError::DuplicateTimestamp`] for a
/// marker whose timestamps go backwards or repeat.
pub fn read_trajectories_csv(text: &str) -> Result<Trajectories> {
    let mut it = lines(text);
    match it.next() {
        Some((_, h)) if h.split(',').map(str::trim).eq(TRAJECTORY_HEADER.split(',')) => {}
        Some((line, h)) => {
            return Err(AngleError::csv(
                line,
                format!("header {h:?} is not {TRAJECTORY_HEADER:?}"),
            ));
        }
        None => return Err(AngleError::csv(1, "empty file: no header")),
    }
    let mut order: Vec<String> = Vec::new();
    let mut rows: BTreeMap<String, Vec<Row>> = BTreeMap::new();
    for (line, l) in it {
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != 5 {
            return Err(AngleError::csv(
                line,
                format!("{} fields, expected 5 ({TRAJECTORY_HEADER})", f.len()),
            ));
        }
        // Adding 0 turns -0 into 0, so that the two are one timestamp of the time base.
        let t = number(line, "t", f[0])? + 0.0;
        let id = f[1].trim();
        if !valid_id(id) {
            return Err(AngleError::csv(line, format!("invalid id {id:?}")));
        }
        let empty = f[2..]
            .iter()
            .map(|s| s.trim().is_empty())
            .collect::<Vec<_>>();
        let p = if empty.iter().all(|&e| e) {
            None
        } else if empty.iter().any(|&e| e) {
            return Err(AngleError::csv(
                line,
                "a position is either all three coordinates or all empty (lost)",
            ));
        } else {
            Some(Point3::new(
                number(line, "x", f[2])?,
                number(line, "y", f[3])?,
                number(line, "z", f[4])?,
            ))
        };
        let entry = rows.entry(id.to_string()).or_insert_with(|| {
            order.push(id.to_string());
            Vec::new()
        });
        if let Some(&(previous_s, _, previous_line)) = entry.last() {
            let what = format!("marker {id:?}, CSV lines {previous_line} and {line}");
            if t == previous_s {
                return Err(AngleError::DuplicateTimestamp { what, t_s: t });
            }
            if t < previous_s {
                return Err(AngleError::UnsortedTimestamps {
                    what,
                    t_s: t,
                    previous_s,
                });
            }
        }
        entry.push((t, p, line));
    }
    let mut times: Vec<f64> = rows.values().flatten().map(|r| r.0).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let markers = order
        .iter()
        .map(|id| {
            let mut positions = vec![None; times.len()];
            for &(t, p, _) in &rows[id] {
                // Every row's time is in the union (no -0 left, no NaN).
                if let Some(slot) = positions.get_mut(times.partition_point(|x| *x < t)) {
                    *slot = p;
                }
            }
            MarkerTrack {
                id: id.clone(),
                positions_m: positions,
            }
        })
        .collect();
    Trajectories::new(times, markers)
}

/// Write trajectories frame by frame (`t,id,x,y,z`, metres), one row per marker and
/// timestamp, an empty position where the marker is lost.
pub fn trajectories_to_csv(trajectories: &Trajectories) -> String {
    let mut out = String::from(TRAJECTORY_HEADER);
    out.push('\n');
    for (k, t) in trajectories.times_s().iter().enumerate() {
        for m in trajectories.markers() {
            // Writing to a String cannot fail.
            let _ = match m.positions_m[k] {
                Some(p) => writeln!(out, "{t},{},{},{},{}", m.id, p.x, p.y, p.z),
                None => writeln!(out, "{t},{},,,", m.id),
            };
        }
    }
    out
}

/// An angle table: the time base and one column per series, radians.
#[derive(Debug, Clone, PartialEq)]
pub struct AngleTable {
    /// Timestamps, seconds.
    pub times_s: Vec<f64>,
    /// The columns, radians (`measured` is true wherever a value is known: a file does not
    /// say which values came from filled gaps).
    pub columns: Vec<Series>,
}

/// The columns of an angle CSV for `set`: eq. (1) per branch, or with `signed` the two
/// signed angles per branch (`<id>_u`, `<id>_w`).
pub fn angle_columns(set: &AngleSet, signed: bool) -> Vec<&Series> {
    let mut cols = Vec::new();
    for b in &set.branches {
        match (&b.signed, signed) {
            (Some(s), true) => {
                cols.push(&s.u_rad);
                cols.push(&s.w_rad);
            }
            (None, true) => {}
            (_, false) => cols.push(&b.angle_rad),
        }
    }
    cols
}

/// Write `t,<column>...` with the values in degrees and an empty cell where unknown.
pub fn angles_to_csv(times_s: &[f64], columns: &[&Series]) -> String {
    let mut out = String::from("t");
    for c in columns {
        out.push(',');
        out.push_str(&c.name);
    }
    out.push('\n');
    for (k, t) in times_s.iter().enumerate() {
        let _ = write!(out, "{t}");
        for c in columns {
            out.push(',');
            if let Some(v) = c.values.get(k).copied().flatten() {
                let _ = write!(out, "{}", v.to_degrees());
            }
        }
        out.push('\n');
    }
    out
}

/// Parse an angle table written by [`angles_to_csv`] (degrees in the file, radians out).
///
/// # Errors
/// [`AngleError::Csv`] for a header that does not start with `t` or repeats a column, a row
/// with another number of fields, or a value that is not a finite number; the time base
/// errors of [`Trajectories::new`].
pub fn read_angles_csv(text: &str) -> Result<AngleTable> {
    let mut it = lines(text);
    let Some((hl, header)) = it.next() else {
        return Err(AngleError::csv(1, "empty file: no header"));
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    if names.first() != Some(&"t") {
        return Err(AngleError::csv(hl, "the first column must be t"));
    }
    for (k, n) in names.iter().enumerate().skip(1) {
        if !valid_id(n) || names[..k].contains(n) {
            return Err(AngleError::csv(
                hl,
                format!("column {n:?} is invalid or repeated"),
            ));
        }
    }
    let mut times = Vec::new();
    let mut values: Vec<Vec<Option<f64>>> = vec![Vec::new(); names.len() - 1];
    for (line, l) in it {
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != names.len() {
            return Err(AngleError::csv(
                line,
                format!("{} fields, expected {}", f.len(), names.len()),
            ));
        }
        times.push(number(line, "t", f[0])?);
        for (col, field) in values.iter_mut().zip(&f[1..]) {
            col.push(if field.trim().is_empty() {
                None
            } else {
                Some(number(line, "angle", field)?.to_radians())
            });
        }
    }
    let columns = names[1..]
        .iter()
        .zip(values)
        .map(|(n, v)| {
            let measured = v.iter().map(Option::is_some).collect();
            Series::new(*n, times.clone(), v, measured)
        })
        .collect::<Result<_>>()?;
    Ok(AngleTable {
        times_s: times,
        columns,
    })
}
