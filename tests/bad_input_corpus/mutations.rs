//! How a valid file is broken: its bytes (truncations, bit flips, an empty file), its
//! numbers (NaN, inf, 1e300, an empty field, a word) and its JSON values (wrong types,
//! unknown fields at every level).

use super::*;

/// Variants of a file's bytes, each with a label: truncations, bit flips, an empty file.
pub(super) fn byte_mutations(bytes: &[u8], rng: &mut Mix, flips: usize) -> Vec<(String, Vec<u8>)> {
    let n = bytes.len();
    let mut out = Vec::new();
    for frac in [0.0, 0.1, 0.25, 0.5, 0.75, 0.95] {
        let cut = ((n as f64) * frac) as usize;
        if cut < n {
            out.push((format!("cut at {cut} of {n} bytes"), bytes[..cut].to_vec()));
        }
    }
    out.push((format!("last byte of {n} cut"), bytes[..n - 1].to_vec()));
    for _ in 0..flips {
        let mut b = bytes.to_vec();
        let at = rng.below(n);
        b[at] ^= 1 << rng.below(8);
        out.push((format!("bit flipped at byte {at}"), b));
    }
    out
}

/// Variants of a text file: every number at a few places replaced by NaN, inf, 1e300, -1e300,
/// an empty field or a word.
pub(super) fn value_mutations(text: &str, rng: &mut Mix, places: usize) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let numbers: Vec<(usize, usize)> = {
        let b = text.as_bytes();
        let mut v = Vec::new();
        let mut i = 0;
        while i < b.len() {
            if b[i].is_ascii_digit() && (i == 0 || !(b[i - 1].is_ascii_alphanumeric())) {
                let start = if i > 0 && b[i - 1] == b'-' { i - 1 } else { i };
                let mut j = i;
                while j < b.len()
                    && (b[j].is_ascii_digit() || matches!(b[j], b'.' | b'e' | b'E' | b'-' | b'+'))
                {
                    j += 1;
                }
                v.push((start, j));
                i = j;
            } else {
                i += 1;
            }
        }
        v
    };
    if numbers.is_empty() {
        return out;
    }
    for _ in 0..places {
        let (a, b) = numbers[rng.below(numbers.len())];
        for replacement in ["NaN", "inf", "1e300", "-1e300", "", "abc"] {
            let t = format!("{}{replacement}{}", &text[..a], &text[b..]);
            out.push((format!("number at byte {a} replaced by {replacement:?}"), t));
        }
    }
    out
}

/// Variants of a JSON document: wrong types, an unknown field, extreme values, at every level.
pub(super) fn json_mutations(value: &serde_json::Value) -> Vec<(String, String)> {
    use serde_json::Value;
    let mut out = Vec::new();
    // Every path to a leaf or a container, breadth first, limited.
    let mut paths: Vec<Vec<String>> = vec![vec![]];
    let mut k = 0;
    while k < paths.len() && paths.len() < 40 {
        let node = get(value, &paths[k]);
        match node {
            Value::Object(o) => {
                for key in o.keys() {
                    let mut p = paths[k].clone();
                    p.push(key.clone());
                    paths.push(p);
                }
            }
            Value::Array(a) => {
                for i in 0..a.len().min(2) {
                    let mut p = paths[k].clone();
                    p.push(i.to_string());
                    paths.push(p);
                }
            }
            _ => {}
        }
        k += 1;
    }
    for path in paths.iter().skip(1) {
        let at = path.join(".");
        let node = get(value, path);
        let replacements: Vec<(&str, Value)> = match node {
            Value::Number(_) => vec![
                ("a string", Value::String("12".into())),
                ("1e300", serde_json::json!(1e300)),
                ("-1e300", serde_json::json!(-1e300)),
                ("null", Value::Null),
            ],
            Value::String(_) => vec![("a number", serde_json::json!(7)), ("empty", "".into())],
            Value::Array(_) => vec![
                ("an object", serde_json::json!({})),
                ("empty", serde_json::json!([])),
            ],
            Value::Object(_) => vec![("an array", serde_json::json!([]))],
            _ => vec![("a string", Value::String("x".into()))],
        };
        for (what, r) in replacements {
            let mut v = value.clone();
            *get_mut(&mut v, path) = r;
            out.push((format!("{at} made {what}"), v.to_string()));
        }
        if let Value::Object(_) = node {
            let mut v = value.clone();
            if let Value::Object(o) = get_mut(&mut v, path) {
                o.insert("unexpected_field".into(), serde_json::json!(1));
            }
            out.push((format!("unknown field in {at}"), v.to_string()));
        }
    }
    if let Value::Object(_) = value {
        let mut v = value.clone();
        if let Value::Object(o) = &mut v {
            o.insert("unexpected_field".into(), serde_json::json!(1));
        }
        out.push(("unknown top-level field".into(), v.to_string()));
    }
    out
}

pub(super) fn get<'a>(v: &'a serde_json::Value, path: &[String]) -> &'a serde_json::Value {
    path.iter().fold(v, |v, k| match v {
        serde_json::Value::Array(a) => &a[k.parse::<usize>().unwrap_or(0)],
        _ => &v[k.as_str()],
    })
}

pub(super) fn get_mut<'a>(
    v: &'a mut serde_json::Value,
    path: &[String],
) -> &'a mut serde_json::Value {
    path.iter().fold(v, |v, k| match v {
        serde_json::Value::Array(a) => &mut a[k.parse::<usize>().unwrap_or(0)],
        _ => &mut v[k.as_str()],
    })
}
