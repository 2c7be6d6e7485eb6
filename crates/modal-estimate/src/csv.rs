//! Signal files: a header line, then `t,value` rows (seconds, any unit); an empty value is a
//! missing sample.

use std::path::Path;

use crate::error::{ModalError, Result};
use crate::signal::Signal;

/// Parse a signal CSV. The first line is a header and is skipped; blank lines are skipped;
/// each other line holds a timestamp in seconds and a value (empty for a missing sample),
/// separated by a comma. Timestamps must increase strictly.
///
/// # Errors
/// [`ModalError::Csv`] with the line number for a line without two fields, a field that is
/// not a number, or a NaN or infinite number; the errors of [`Signal::new`].
pub fn parse_signal_csv(text: &str) -> Result<Signal> {
    let mut times = Vec::new();
    let mut values = Vec::new();
    for (index, line) in text.lines().enumerate().skip(1) {
        let line_no = index + 1;
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 2 {
            return Err(ModalError::Csv {
                line: line_no,
                message: format!("expected 2 fields `t,value`, found {}", fields.len()),
            });
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
        times.push(number(fields[0], "time")?);
        values.push(if fields[1].is_empty() {
            None
        } else {
            Some(number(fields[1], "value")?)
        });
    }
    Signal::new(times, values)
}

/// Read a signal CSV file, see [`parse_signal_csv`].
///
/// # Errors
/// [`ModalError::Io`] when the file cannot be read; the errors of [`parse_signal_csv`].
pub fn read_signal_csv(path: &Path) -> Result<Signal> {
    let text = std::fs::read_to_string(path).map_err(|source| ModalError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse_signal_csv(&text)
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
