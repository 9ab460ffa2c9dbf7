//! Per-block rows (stored as flat JSON objects) as CSV, shared by the HTTP stream and
//! `millsim run`.
//!
//! A row is read as (key, raw value) pairs borrowed from its JSON text: a number is written
//! as the text serde_json wrote it (the same digits a parse and re-print would give, without
//! the cost of either), a string unescaped, null empty. Only arrays (positions of interpret
//! rows) are parsed further. 10^5 rows of fifty numbers stream in a fraction of a second.

use std::borrow::Cow;
use std::fmt;

use serde::de::{self, DeserializeSeed, MapAccess, Visitor};
use serde_json::value::RawValue;

/// One CSV column: its header, the row key it reads, and the index inside an array value.
#[derive(Clone, Debug)]
pub struct Column {
    pub header: String,
    key: String,
    index: Option<usize>,
}

/// A row's (key, raw JSON value) pairs, in the row's order.
pub type Pairs<'a> = Vec<(&'a str, &'a RawValue)>;

/// Reads the pairs of the object `row` into `out` (cleared first). False when `row` is not
/// a JSON object of plain keys (such a row is not written, as before).
pub fn read_pairs<'a>(row: &'a str, out: &mut Pairs<'a>) -> bool {
    out.clear();
    let mut de = serde_json::Deserializer::from_str(row);
    PairsSeed(out).deserialize(&mut de).is_ok() && de.end().is_ok()
}

struct PairsSeed<'p, 'a>(&'p mut Pairs<'a>);

impl<'de, 'p> DeserializeSeed<'de> for PairsSeed<'p, 'de> {
    type Value = ();
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de, 'p> Visitor<'de> for PairsSeed<'p, 'de> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON object")
    }
    fn visit_map<M: MapAccess<'de>>(self, mut map: M) -> Result<(), M::Error> {
        // Keys without escapes borrow from the text; a key with one fails the row.
        while let Some(k) = map.next_key::<&'de str>()? {
            let v: &'de RawValue = map.next_value()?;
            self.0.push((k, v));
        }
        Ok(())
    }
}

/// The value of `key` in `pairs`, looked up from `*from` on (columns come in the rows' key
/// order, so the next key is nearly always the next pair) and wrapping round.
fn lookup<'a>(pairs: &Pairs<'a>, key: &str, from: &mut usize) -> Option<&'a RawValue> {
    let n = pairs.len();
    for k in 0..n {
        let i = (*from + k) % n;
        if pairs[i].0 == key {
            *from = i + 1;
            return Some(pairs[i].1);
        }
    }
    None
}

fn is_null(v: &RawValue) -> bool {
    v.get() == "null"
}

fn array(v: &RawValue) -> Option<Vec<&RawValue>> {
    if !v.get().starts_with('[') {
        return None;
    }
    serde_json::from_str(v.get()).ok()
}

/// Columns for the given row keys: a key whose value is an array becomes `name_x`,
/// `name_y`, ... columns (sized from the first sample row holding it: positions are six
/// axes, centres and normals three).
pub fn columns(keys: &[String], sample_rows: &[Pairs]) -> Vec<Column> {
    const AXES: [&str; 6] = ["x", "y", "z", "a", "b", "c"];
    let mut cols = Vec::new();
    for k in keys {
        let first = sample_rows.iter().find_map(|r| {
            r.iter()
                .find(|(key, v)| key == k && !is_null(v))
                .map(|(_, v)| *v)
        });
        match first.and_then(array) {
            Some(a) if a.len() <= 6 => {
                for (i, axis) in AXES.iter().enumerate().take(a.len()) {
                    cols.push(Column {
                        header: format!("{k}_{axis}"),
                        key: k.clone(),
                        index: Some(i),
                    });
                }
            }
            _ => cols.push(Column {
                header: k.clone(),
                key: k.clone(),
                index: None,
            }),
        }
    }
    cols
}

/// The columns named in `wanted` (headers such as `end_x`, or keys, which bring all their
/// columns), in the order of `cols`; the first name that is none of them is the error.
pub fn select(cols: Vec<Column>, wanted: &[&str]) -> Result<Vec<Column>, String> {
    if let Some(bad) = wanted
        .iter()
        .find(|w| !cols.iter().any(|c| c.header == **w || c.key == **w))
    {
        return Err(bad.to_string());
    }
    Ok(cols
        .into_iter()
        .filter(|c| wanted.iter().any(|w| c.header == *w || c.key == *w))
        .collect())
}

/// How numbers are written: as stored, or (`digits`) the fractional ones rounded to that
/// many significant digits (integers stay whole): a plot needs six, not seventeen.
#[derive(Clone, Copy, Debug, Default)]
pub struct Numbers {
    pub digits: Option<usize>,
}

/// `raw` (a JSON number with a fraction or an exponent) to `digits` significant digits, in
/// the shortest text that reads back as the rounded value.
fn push_rounded(out: &mut String, raw: &str, digits: usize) {
    use std::fmt::Write;
    let x = match raw.parse::<f64>() {
        Ok(x) if x != 0.0 && x.is_finite() => x,
        _ => return out.push_str(raw),
    };
    // Decimals to keep: the rounded value is m / 10^p, m a whole number of `digits` digits.
    let p = digits as i32 - 1 - x.abs().log10().floor() as i32;
    if (0..=9).contains(&p) && x.abs() < 1e15 {
        // Whole-number arithmetic: fast, and the text is exactly the rounded decimal.
        let m = (x * 10f64.powi(p)).round();
        let (neg, m) = (m < 0.0, m.abs() as u64);
        let unit = 10u64.pow(p as u32);
        let (whole, frac) = (m / unit, m % unit);
        if neg && m != 0 {
            out.push('-');
        }
        let _ = write!(out, "{whole}.");
        if p == 0 || frac == 0 {
            out.push('0');
        } else {
            let f = format!("{frac:0width$}", width = p as usize);
            out.push_str(f.trim_end_matches('0'));
        }
        return;
    }
    if p < 0 && x.abs() < 1e9 {
        // Past the point: a whole number.
        let s = 10f64.powi(-p);
        let _ = write!(out, "{}.0", ((x / s).round() * s) as i64);
        return;
    }
    // Very small or very large: in decimal exponent form, without the mantissa's
    // trailing zeros.
    let t = format!("{:.*e}", digits.saturating_sub(1), x);
    let (mantissa, exp) = t.split_at(t.find('e').unwrap_or(t.len()));
    let mantissa = if mantissa.contains('.') {
        mantissa.trim_end_matches('0').trim_end_matches('.')
    } else {
        mantissa
    };
    out.push_str(mantissa);
    out.push_str(exp);
}

/// A raw value as CSV text: null empty, a string unescaped, anything else as written
/// (numbers, booleans, compact JSON); quoted where it holds a comma, quote or line break.
fn push_field(out: &mut String, v: Option<&RawValue>, numbers: Numbers) {
    let Some(v) = v.filter(|v| !is_null(v)) else {
        return;
    };
    let raw = v.get();
    let text: Cow<str> = match raw.as_bytes()[0] {
        b'"' => match serde_json::from_str::<&str>(raw) {
            Ok(s) => s.into(),
            Err(_) => serde_json::from_str::<String>(raw)
                .unwrap_or_default()
                .into(),
        },
        b'[' | b'{' => raw.into(),
        // A number or a boolean: nothing to quote.
        _ => {
            return match numbers.digits {
                Some(d) if raw.bytes().any(|b| matches!(b, b'.' | b'e' | b'E')) => {
                    push_rounded(out, raw, d)
                }
                _ => out.push_str(raw),
            }
        }
    };
    if text.bytes().any(|b| matches!(b, b',' | b'"' | b'\n')) {
        out.push('"');
        out.push_str(&text.replace('"', "\"\""));
        out.push('"');
    } else {
        out.push_str(&text);
    }
}

pub fn write_header(out: &mut String, cols: &[Column]) {
    for (i, c) in cols.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(&c.header);
    }
    out.push('\n');
}

pub fn write_row(out: &mut String, cols: &[Column], row: &Pairs, numbers: Numbers) {
    let mut from = 0;
    // The array of the last array key, parsed once for its several columns.
    let mut spread: Option<(&str, Vec<&RawValue>)> = None;
    for (i, c) in cols.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        match c.index {
            None => push_field(out, lookup(row, &c.key, &mut from), numbers),
            Some(j) => {
                if spread.as_ref().map(|(k, _)| *k) != Some(c.key.as_str()) {
                    let a = lookup(row, &c.key, &mut from)
                        .and_then(array)
                        .unwrap_or_default();
                    spread = Some((&c.key, a));
                }
                let a = &spread.as_ref().expect("set above").1;
                push_field(out, a.get(j).copied(), numbers);
            }
        }
    }
    out.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::{json, Value};

    fn csv(keys: &[&str], rows: &[String]) -> String {
        let keys: Vec<String> = keys.iter().map(|s| s.to_string()).collect();
        let parsed: Vec<Pairs> = rows
            .iter()
            .map(|r| {
                let mut p = Vec::new();
                assert!(read_pairs(r, &mut p), "{r}");
                p
            })
            .collect();
        let cols = columns(&keys, &parsed);
        let mut out = String::new();
        write_header(&mut out, &cols);
        for p in &parsed {
            write_row(&mut out, &cols, p, Numbers::default());
        }
        out
    }

    #[test]
    fn arrays_spread_over_axis_columns_and_text_is_quoted() {
        let row = json!({"line": 3, "end": [1.0, 2.0, 3.0, 0.0, 0.0, 0.0], "note": "a,\"b\""});
        let out = csv(&["line", "end", "note", "center"], &[row.to_string()]);
        assert_eq!(out, "line,end_x,end_y,end_z,end_a,end_b,end_c,note,center\n3,1.0,2.0,3.0,0.0,0.0,0.0,\"a,\"\"b\"\"\",\n");
    }

    /// A value as serde_json writes it (what a CSV reader of the old Value round trip saw,
    /// and what the stored row holds), without reading it back.
    fn written(v: &Value) -> String {
        match v {
            Value::Null => String::new(),
            Value::String(s) if s.contains([',', '"', '\n']) => {
                format!("\"{}\"", s.replace('"', "\"\""))
            }
            Value::String(s) => s.clone(),
            v => serde_json::to_string(v).unwrap(),
        }
    }

    #[test]
    fn numbers_keep_the_digits_they_were_stored_with() {
        // Awkward floats (shortest digits, exponents, negative zero, non-finite: null),
        // integers, words with escapes, nulls, a missing key and keys out of order.
        let keys = [
            "block", "force", "neg", "zero", "kind", "n", "big", "flag", "t",
        ];
        let (mut rows, mut expected) = (Vec::new(), keys.join(",") + "\n");
        let mut x = 0.1f64;
        for i in 0..2000u64 {
            x = (x * 7.31 + 0.37).fract() * 10f64.powi((i % 23) as i32 - 11);
            let mut row = json!({"block": i, "force": x, "neg": -x, "zero": if i % 2 == 0 { -0.0 } else { 0.0 },
                "kind": if i % 3 == 0 { "lin\"e,\u{e9}" } else { "arc" }, "n": if i % 5 == 0 { Value::Null } else { json!(i * 10) },
                "big": u64::MAX - i, "flag": i % 2 == 0, "t": 1e300 * x});
            if i % 7 == 0 {
                row = json!({"t": 1e300 * x, "kind": "arc", "block": i, "force": x});
            }
            let line: Vec<String> = keys
                .iter()
                .map(|k| written(row.get(*k).unwrap_or(&Value::Null)))
                .collect();
            expected += &(line.join(",") + "\n");
            rows.push(row.to_string());
        }
        assert_eq!(csv(&keys, &rows), expected);
        assert!(expected.contains("e-") && expected.contains("-0.0") && expected.contains(",,"));
    }

    #[test]
    fn a_row_that_is_not_an_object_is_not_read() {
        let mut p = Vec::new();
        assert!(!read_pairs("[1,2]", &mut p));
        assert!(!read_pairs("{\"a\":1} x", &mut p));
        assert!(read_pairs("{\"a\":1}", &mut p));
        assert_eq!(p.len(), 1);
    }

    #[test]
    fn selected_columns_keep_their_order_and_an_unknown_one_is_named() {
        let row = json!({"line": 3, "end": [1.0, 2.0, 3.0], "force": 2.5}).to_string();
        let mut p = Vec::new();
        assert!(read_pairs(&row, &mut p));
        let keys: Vec<String> = ["line", "end", "force"].map(String::from).to_vec();
        let cols = columns(&keys, std::slice::from_ref(&p));
        let picked = select(cols.clone(), &["force", "end_y", "line"]).unwrap();
        let mut out = String::new();
        write_header(&mut out, &picked);
        write_row(&mut out, &picked, &p, Numbers::default());
        assert_eq!(out, "line,end_y,force\n3,2.0,2.5\n");
        let all_end = select(cols.clone(), &["end"]).unwrap();
        assert_eq!(all_end.len(), 3);
        assert_eq!(select(cols, &["line", "forse"]).unwrap_err(), "forse");
    }

    #[test]
    fn fewer_digits_round_fractions_and_keep_integers_whole() {
        let row = json!({"block": 123456789, "t": 0.11399388365868235, "f": 2515.00883, "z": 0.0,
            "big": 1234567.0, "tiny": 1.234567e-7, "neg": -400.00004, "word": "linear", "small": 2.0e-9})
        .to_string();
        let keys = [
            "block", "t", "f", "z", "big", "tiny", "neg", "word", "small",
        ];
        let mut p = Vec::new();
        assert!(read_pairs(&row, &mut p));
        let keys: Vec<String> = keys.map(String::from).to_vec();
        let cols = columns(&keys, std::slice::from_ref(&p));
        let mut out = String::new();
        write_row(&mut out, &cols, &p, Numbers { digits: Some(6) });
        assert_eq!(
            out,
            "123456789,0.113994,2515.01,0.0,1234570.0,1.23457e-7,-400.0,linear,2e-9\n"
        );
        // Each within half a unit of the sixth digit of the stored value.
        for (got, was) in out.split(',').skip(1).take(6).zip([
            0.11399388365868235,
            2515.00883,
            0.0,
            1234567.0,
            1.234567e-7,
            -400.00004,
        ]) {
            let g: f64 = got.parse().unwrap();
            assert!((g - was).abs() <= 5e-6 * was.abs(), "{got} vs {was}");
        }
    }

    #[test]
    fn rounded_numbers_are_the_nearest_six_digit_decimals() {
        // Against the standard library's exact decimal rounding ({:.5e}), over magnitudes
        // from 1e-12 to 1e18, both signs.
        let mut x = 0.37f64;
        for i in 0..20_000 {
            x = (x * 7.31 + 0.123).fract();
            let v = (x + 0.01) * 10f64.powi(i % 31 - 12) * if i % 2 == 0 { 1.0 } else { -1.0 };
            let raw = serde_json::to_string(&v).unwrap();
            let mut out = String::new();
            push_rounded(&mut out, &raw, 6);
            let got: f64 = out.parse().unwrap();
            let exact: f64 = format!("{v:.5e}").parse().unwrap();
            // The same decimal, up to a tie decided on the other side by the scaled product.
            assert!(
                (got - exact).abs() <= 1e-6 * exact.abs(),
                "{raw} -> {out}, exact {exact}"
            );
            assert!(out.len() <= 16, "{raw} -> {out}");
        }
    }
}
