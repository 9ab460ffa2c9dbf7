//! Per-block rows (JSON objects) as CSV, shared by the HTTP stream and `millsim run`.

use serde_json::{Map, Value};

/// One CSV column: its header, the row key it reads, and the index inside an array value.
pub struct Column {
    pub header: String,
    key: String,
    index: Option<usize>,
}

/// Columns for the given row keys: a key whose value is an array becomes `name_x`,
/// `name_y`, ... columns (sized from the first sample row holding it: positions are six
/// axes, centres and normals three).
pub fn columns(keys: &[String], sample_rows: &[Map<String, Value>]) -> Vec<Column> {
    const AXES: [&str; 6] = ["x", "y", "z", "a", "b", "c"];
    let mut cols = Vec::new();
    for k in keys {
        match sample_rows
            .iter()
            .find_map(|r| r.get(k).filter(|v| !v.is_null()))
        {
            Some(Value::Array(a)) if a.len() <= 6 => {
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

fn field(v: Option<&Value>) -> String {
    let s = match v {
        None | Some(Value::Null) => return String::new(),
        Some(Value::String(s)) => s.clone(),
        Some(other) => other.to_string(),
    };
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s
    }
}

pub fn write_header(out: &mut String, cols: &[Column]) {
    out.push_str(
        &cols
            .iter()
            .map(|c| c.header.as_str())
            .collect::<Vec<_>>()
            .join(","),
    );
    out.push('\n');
}

pub fn write_row(out: &mut String, cols: &[Column], row: &Map<String, Value>) {
    for (i, c) in cols.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        let v = row.get(&c.key);
        out.push_str(&field(match c.index {
            Some(j) => v.and_then(|a| a.get(j)),
            None => v,
        }));
    }
    out.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn arrays_spread_over_axis_columns_and_text_is_quoted() {
        let row = json!({"line": 3, "end": [1.0, 2.0, 3.0, 0.0, 0.0, 0.0], "note": "a,\"b\""});
        let Value::Object(row) = row else {
            unreachable!()
        };
        let keys: Vec<String> = ["line", "end", "note", "center"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let cols = columns(&keys, std::slice::from_ref(&row));
        let mut out = String::new();
        write_header(&mut out, &cols);
        write_row(&mut out, &cols, &row);
        assert_eq!(out, "line,end_x,end_y,end_z,end_a,end_b,end_c,note,center\n3,1.0,2.0,3.0,0.0,0.0,0.0,\"a,\"\"b\"\"\",\n");
    }
}
