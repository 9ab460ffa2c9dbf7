//! The CSV text the identify job's options take in place of a JSON array (measurements, cuts,
//! line forces): a header naming the columns, then one row a line; each reader checks its own
//! columns and turns cells into its rows with these pieces, so the three agree on the errors.

use serde_json::Value;

use crate::problem::Problem;

/// The rows of option `field`, given as an array of objects or as CSV text (read by
/// `csv`): anything else is refused naming `shape`, the fields a row has, and more than
/// `max` rows naming `what` they are.
pub(super) fn array_or_csv(
    value: &Value,
    field: &str,
    shape: &str,
    max: usize,
    what: &str,
    csv: impl FnOnce(&str) -> Result<Vec<Value>, Problem>,
) -> Result<Vec<Value>, Problem> {
    let rows: Vec<Value> = match value {
        Value::Array(rows) => rows.clone(),
        Value::String(text) => csv(text)?,
        _ => {
            return Err(Problem::invalid_field(
                field,
                format!("give an array of {shape} or CSV text with those columns"),
            ))
        }
    };
    if rows.len() > max {
        return Err(Problem::invalid_field(
            field,
            format!("at most {max} {what}, got {}", rows.len()),
        ));
    }
    Ok(rows)
}

/// Row `i` of option `field` (`options.cuts`) read as a `T`; a value that does not read
/// is named by its path in the row (`options.cuts[2].fx_n`).
pub(super) fn json_row<T: serde::de::DeserializeOwned>(
    field: &str,
    i: usize,
    row: &Value,
) -> Result<T, Problem> {
    serde_path_to_error::deserialize(row).map_err(|e| {
        let path = e.path().to_string();
        let sub = if path == "." {
            String::new()
        } else {
            format!(".{path}")
        };
        Problem::invalid_field(format!("{field}[{i}]{sub}"), e.inner().to_string())
    })
}

/// The header's column names and the data lines that follow it (blank lines skipped), each
/// with its 0-based line number in the text; `field` names the option in the problem.
pub(super) fn header_and_lines<'a>(
    text: &'a str,
    field: &str,
) -> Result<(Vec<&'a str>, impl Iterator<Item = (usize, &'a str)>), Problem> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines
        .next()
        .ok_or_else(|| Problem::invalid_field(field, "the CSV text is empty"))?;
    let names = header
        .split(',')
        .map(|c| c.trim().trim_matches('"'))
        .collect();
    Ok((names, lines))
}

/// The cells of data line `n` (0-based), as many as the header has columns.
pub(super) fn cells<'a>(
    field: &str,
    n: usize,
    line: &'a str,
    columns: usize,
) -> Result<Vec<&'a str>, Problem> {
    let cells: Vec<&str> = line.split(',').map(str::trim).collect();
    if cells.len() != columns {
        return Err(Problem::invalid_field(
            field,
            format!(
                "CSV line {}: {} values for {} columns",
                n + 1,
                cells.len(),
                columns
            ),
        ));
    }
    Ok(cells)
}

/// Column `name`'s cell on data line `n` as a number, as Rust reads numbers (so `NaN` and
/// `inf` parse; callers that need a finite one use [`finite_number`]).
pub(super) fn number(field: &str, n: usize, name: &str, cell: &str) -> Result<f64, Problem> {
    cell.parse().map_err(|_| {
        Problem::invalid_field(
            field,
            format!("CSV line {}: {name} `{cell}` is not a number", n + 1),
        )
        .with("line", n + 1)
    })
}

/// As [`number`], refusing a non-finite one (JSON has no NaN) naming row `row`'s field.
pub(super) fn finite_number(
    field: &str,
    n: usize,
    row: usize,
    name: &str,
    cell: &str,
) -> Result<f64, Problem> {
    let v = number(field, n, name, cell)?;
    if !v.is_finite() {
        return Err(Problem::invalid_field(
            format!("{field}[{row}].{name}"),
            format!("must be a finite number, got {cell} (CSV line {})", n + 1),
        ));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_the_field_and_the_csv_line() {
        let f = "options.cuts";
        let Err(e) = header_and_lines("\n  \n", f) else {
            panic!("an empty text read")
        };
        assert!(e.detail.contains("empty"), "{}", e.detail);
        let (names, lines) = header_and_lines("a, \"b\"\n\n1,2\n3\n", f).unwrap();
        assert_eq!(names, ["a", "b"]);
        let lines: Vec<(usize, &str)> = lines.collect();
        assert_eq!(lines, [(2, "1,2"), (3, "3")]);
        let e = cells(f, 3, "3", 2).unwrap_err();
        assert_eq!(e.detail, "CSV line 4: 1 values for 2 columns");
        let e = number(f, 2, "a", "x").unwrap_err();
        assert_eq!(e.detail, "CSV line 3: a `x` is not a number");
        assert!(number(f, 2, "a", "NaN").unwrap().is_nan());
        let e = finite_number(f, 2, 0, "a", "inf").unwrap_err();
        assert_eq!(e.to_json()["field"], "options.cuts[0].a");
        assert_eq!(finite_number(f, 2, 0, "a", "1.5").unwrap(), 1.5);
    }
}
