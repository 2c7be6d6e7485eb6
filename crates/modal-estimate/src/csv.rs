//! Signal files: rows of comma-separated numbers, by default `t,value` (seconds, any unit); an
//! empty value is a missing sample. A first line that is not all numbers is a header.
//! [`CsvLayout`] picks another value column, or gives a sample rate for files without a time
//! column (many loggers write one column per channel and state the rate elsewhere).

use std::path::Path;

use crate::error::{ModalError, Result};
use crate::signal::Signal;

/// Where the timestamps and the values are in each row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CsvLayout {
    /// Column of the timestamps (0-based), or `None` when the file has none and the samples
    /// are `1 / sample_rate_hz` apart from t = 0.
    pub time_column: Option<usize>,
    /// Sample rate, hertz, when there is no time column.
    pub sample_rate_hz: Option<f64>,
    /// Column of the values (0-based).
    pub value_column: usize,
}

impl Default for CsvLayout {
    /// `t,value`: timestamps in column 0, values in column 1.
    fn default() -> Self {
        Self {
            time_column: Some(0),
            sample_rate_hz: None,
            value_column: 1,
        }
    }
}

/// Largest column index accepted (a wider row is not a signal file).
const MAX_COLUMN: usize = 1 << 16;

impl CsvLayout {
    /// Values in `value_column` sampled at `sample_rate_hz`, no time column.
    #[must_use]
    pub fn sampled(sample_rate_hz: f64, value_column: usize) -> Self {
        Self {
            time_column: None,
            sample_rate_hz: Some(sample_rate_hz),
            value_column,
        }
    }

    /// Check that the layout says where time comes from exactly once.
    ///
    /// # Errors
    /// [`ModalError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        match (self.time_column, self.sample_rate_hz) {
            (Some(_), Some(r)) => Err(ModalError::InvalidParameter {
                name: "sample_rate_hz",
                reason: format!("{r} (expected absent when the file has a time column)"),
            }),
            (None, None) => Err(ModalError::InvalidParameter {
                name: "sample_rate_hz",
                reason: "none given (expected given when the file has no time column)".to_string(),
            }),
            (None, Some(r)) if !(r.is_finite() && r > 0.0) => Err(ModalError::InvalidParameter {
                name: "sample_rate_hz",
                reason: format!("{r} (expected positive and finite)"),
            }),
            (Some(t), _) if t == self.value_column => Err(ModalError::InvalidParameter {
                name: "value_column",
                reason: format!(
                    "{} (expected different from the time column)",
                    self.value_column
                ),
            }),
            _ if self.value_column > MAX_COLUMN => Err(ModalError::InvalidParameter {
                name: "value_column",
                reason: format!("{} (expected at most 65536)", self.value_column),
            }),
            _ => Ok(()),
        }
    }

    /// Columns a row must have.
    fn columns_needed(&self) -> usize {
        self.value_column.max(self.time_column.unwrap_or(0)) + 1
    }
}

/// The 0-based index of the column named `name` in the header of a signal file's `text`
/// (its first non-blank line, when that line is a header: not all numbers), so that a
/// file with named columns, such as branch-angles' `t,<branch>...`, can be read by name.
/// `None` when the file has no header or no such column.
pub fn header_column(text: &str, name: &str) -> Option<usize> {
    let line = text.lines().map(str::trim).find(|l| !l.is_empty())?;
    let fields: Vec<&str> = line.split(',').map(str::trim).collect();
    let header = fields
        .iter()
        .any(|f| !f.is_empty() && f.parse::<f64>().is_err());
    if !header {
        return None;
    }
    fields.iter().position(|f| *f == name.trim())
}

/// Parse a signal CSV laid out as `t,value` ([`CsvLayout::default`]). A first line whose
/// fields are not all numbers is a header and is skipped; blank lines are skipped; every
/// other line holds a timestamp in seconds and a value (empty for a missing sample).
/// Timestamps must increase strictly.
///
/// # Errors
/// [`ModalError::Csv`] with the line number for a line without two fields, a field that is
/// not a number, or a NaN or infinite number; the errors of [`Signal::new`].
pub fn parse_signal_csv(text: &str) -> Result<Signal> {
    parse_signal_csv_with(text, &CsvLayout::default())
}

/// Parse a signal CSV with the columns of `layout`. Rows may hold more columns than the
/// layout uses; every row must hold the same number.
///
/// # Errors
/// [`ModalError::InvalidParameter`] for a layout that does not validate; [`ModalError::Csv`]
/// with the line number for a row with too few or a changing number of fields, a field
/// that is not a number, or a NaN or infinite number; the errors of [`Signal::new`].
pub fn parse_signal_csv_with(text: &str, layout: &CsvLayout) -> Result<Signal> {
    layout.validate()?;
    let needed = layout.columns_needed();
    let mut times = Vec::new();
    let mut values = Vec::new();
    let mut width = None;
    let mut first = true;
    for (index, line) in text.lines().enumerate() {
        let line_no = index + 1;
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if std::mem::take(&mut first)
            && fields
                .iter()
                .any(|f| !f.is_empty() && f.parse::<f64>().is_err())
        {
            continue; // the header
        }
        if fields.len() < needed {
            return Err(ModalError::Csv {
                line: line_no,
                message: format!(
                    "expected at least {needed} fields ({}), found {}",
                    describe(layout),
                    fields.len()
                ),
            });
        }
        match width {
            None => width = Some(fields.len()),
            Some(w) if w != fields.len() => {
                return Err(ModalError::Csv {
                    line: line_no,
                    message: format!("{} fields where the rows above have {w}", fields.len()),
                });
            }
            Some(_) => {}
        }
        let number = |s: &str, what: &str| -> Result<f64> {
            let v: f64 = s.parse().map_err(|_| ModalError::Csv {
                line: line_no,
                message: format!("{what} {s:?} is not a number"),
            })?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(ModalError::Csv {
                    line: line_no,
                    message: format!("{what} {s:?} is not finite"),
                })
            }
        };
        if let Some(c) = layout.time_column {
            times.push(number(fields[c], "time")?);
        }
        let v = fields[layout.value_column];
        values.push(if v.is_empty() {
            None
        } else {
            Some(number(v, "value")?)
        });
    }
    match layout.sample_rate_hz {
        Some(rate) if layout.time_column.is_none() => Signal::uniform(rate, values),
        _ => Signal::new(times, values),
    }
}

/// What the layout expects of a row, for messages.
fn describe(layout: &CsvLayout) -> String {
    match layout.time_column {
        Some(t) => format!(
            "time in column {t}, value in column {}",
            layout.value_column
        ),
        None => format!("value in column {}", layout.value_column),
    }
}

/// Read a signal CSV file laid out as `t,value`, see [`parse_signal_csv`].
///
/// # Errors
/// [`ModalError::Io`] when the file cannot be read; the errors of [`parse_signal_csv`].
pub fn read_signal_csv(path: &Path) -> Result<Signal> {
    read_signal_csv_with(path, &CsvLayout::default())
}

/// Read a signal CSV file with the columns of `layout`, see [`parse_signal_csv_with`].
///
/// # Errors
/// [`ModalError::Io`] when the file cannot be read or is not UTF-8 text; the errors of
/// [`parse_signal_csv_with`].
pub fn read_signal_csv_with(path: &Path, layout: &CsvLayout) -> Result<Signal> {
    let text = std::fs::read_to_string(path).map_err(|source| ModalError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_signal_csv_with(&text, layout)
}

/// Write a signal as CSV (`t,value`, empty for a missing sample), full precision.
#[must_use]
pub fn signal_to_csv(signal: &Signal) -> String {
    let mut out = String::from("t,value\n");
    for (t, v) in signal.times_s().iter().zip(signal.values()) {
        match v {
            Some(v) => out.push_str(&format!("{t:?},{v:?}\n")),
            None => out.push_str(&format!("{t:?},\n")),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn reads_missing_values_and_names_bad_lines() {
        let s = parse_signal_csv("t,angle\n0,1.5\n0.1,\n\n0.2,-2e-3\n").unwrap();
        assert_eq!(s.values(), &[Some(1.5), None, Some(-0.002)]);
        let e = parse_signal_csv("t,v\n0,1\n0.1,abc\n").unwrap_err();
        assert!(matches!(e, ModalError::Csv { line: 3, .. }), "{e}");
        let e = parse_signal_csv("t,v\n0,NaN\n").unwrap_err();
        assert!(matches!(e, ModalError::Csv { line: 2, .. }), "{e}");
        let e = parse_signal_csv("t,v\n0,1\n0,2\n").unwrap_err();
        assert!(
            matches!(e, ModalError::NonIncreasingTime { index: 1, .. }),
            "{e}"
        );
    }

    #[test]
    fn a_headerless_file_loses_no_row_and_columns_can_be_chosen() {
        // A logger file: no header, no time column, one column per channel.
        let text = "4.782,4.968\n4.781,4.967\n4.779,4.966\n";
        let s = parse_signal_csv_with(text, &CsvLayout::sampled(20.0, 1)).unwrap();
        assert_eq!(s.values(), &[Some(4.968), Some(4.967), Some(4.966)]);
        assert_eq!(s.times_s(), &[0.0, 0.05, 0.1]);
        // `t,value` without a header: the first row is data.
        let s = parse_signal_csv("0,1\n0.1,2\n").unwrap();
        assert_eq!(s.values(), &[Some(1.0), Some(2.0)]);
        let layout = CsvLayout {
            value_column: 2,
            ..CsvLayout::default()
        };
        let s = parse_signal_csv_with("t,x,y\n0,1,5\n0.1,2,6\n", &layout).unwrap();
        assert_eq!(s.values(), &[Some(5.0), Some(6.0)]);
        let e = parse_signal_csv_with("0,1\n0.1,2\n", &layout).unwrap_err();
        assert!(matches!(e, ModalError::Csv { line: 1, .. }), "{e}");
        let e = parse_signal_csv_with("0,1,5\n0.1,2\n", &CsvLayout::default()).unwrap_err();
        assert!(matches!(e, ModalError::Csv { line: 2, .. }), "{e}");
        let bad = CsvLayout {
            value_column: 0,
            ..CsvLayout::default()
        };
        assert!(matches!(
            parse_signal_csv_with("0,1\n", &bad),
            Err(ModalError::InvalidParameter { .. })
        ));
    }

    proptest! {
        #[test]
        fn parser_never_panics_and_round_trips(text in "\\PC{0,200}") {
            if let Ok(signal) = parse_signal_csv(&text) {
                let again = parse_signal_csv(&signal_to_csv(&signal)).unwrap();
                prop_assert_eq!(again, signal);
            }
        }

        #[test]
        fn written_signals_read_back(values in proptest::collection::vec(proptest::option::of(-1e6f64..1e6), 0..50)) {
            let times = (0..values.len()).map(|i| i as f64 * 0.033).collect();
            let signal = Signal::new(times, values).unwrap();
            prop_assert_eq!(parse_signal_csv(&signal_to_csv(&signal)).unwrap(), signal);
        }
    }
}

#[cfg(test)]
mod header_tests {
    use super::*;

    #[test]
    fn columns_are_found_by_name_in_a_header_only() {
        let text = "\n t, B , C\n0,1,2\n";
        assert_eq!(header_column(text, "C"), Some(2));
        assert_eq!(header_column(text, "B"), Some(1));
        assert_eq!(header_column(text, "D"), None);
        assert_eq!(
            header_column("0,1,2\n", "0"),
            None,
            "numbers are not a header"
        );
        assert_eq!(header_column("", "t"), None);
    }
}
