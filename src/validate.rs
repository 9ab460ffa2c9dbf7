//! Upload validation: each input is checked with the engine's own readers before it is
//! stored, and what they find becomes the resource's summary. Errors name the field,
//! or the line and column.

use std::borrow::Cow;

use serde_json::{json, Value};

use millsim_engine::tool_library::ToolLibrary;
use millsim_engine::{geometry, machine::Machine, nc, physics::Material, tool::Tool};

use crate::problem::{parse_json, Problem};

/// A validated input ready to store.
pub struct Validated {
    pub media_type: &'static str,
    pub summary: Value,
}

/// The line and column of a byte offset in `bytes` (1-based).
fn line_col(bytes: &[u8], offset: usize) -> (usize, usize) {
    let before = &bytes[..offset.min(bytes.len())];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let col = offset
        - before
            .iter()
            .rposition(|&b| b == b'\n')
            .map(|p| p + 1)
            .unwrap_or(0)
        + 1;
    (line, col)
}

/// True when the text reads as an APT/CLS cutter-location file rather than G-code.
pub fn looks_like_cls(text: &str) -> bool {
    text.lines().take(200).any(|l| {
        let l = l.trim_start().to_ascii_uppercase();
        l.starts_with("GOTO/")
            || l.starts_with("TLAXIS/")
            || l.starts_with("FEDRAT/")
            || l.starts_with("LOADTL/")
    })
}

/// An uploaded text file as UTF-8 (or plain ASCII), else a problem naming the line and
/// column of the first byte that is not.
fn utf8<'a>(
    bytes: &'a [u8],
    file: &str,
    slug: &'static str,
    title: &'static str,
) -> Result<&'a str, Problem> {
    std::str::from_utf8(bytes).map_err(|e| {
        let (line, column) = line_col(bytes, e.valid_up_to());
        Problem::new(
            axum::http::StatusCode::UNPROCESSABLE_ENTITY,
            slug,
            title,
            format!(
                "{file}:{line}:{column}: byte 0x{:02x} is not UTF-8 text",
                bytes[e.valid_up_to()]
            ),
        )
        .with("file", file.to_string())
        .with("line", line)
        .with("column", column)
    })
}

/// A program's text: UTF-8 (or plain ASCII), else ISO 8859-1 byte for character, as
/// programs written on Windows or kept by older controls carry their comments
/// (`(FR\u{c4}SER \u{d8}10)`): the NC words are ASCII either way. None for bytes that are
/// not text at all (control bytes other than tab, line ends, form feed and the DOS end of
/// file), which are refused as before.
pub fn program_text(bytes: &[u8]) -> Option<Cow<'_, str>> {
    if let Ok(text) = std::str::from_utf8(bytes) {
        return Some(Cow::Borrowed(text));
    }
    let text_like = bytes
        .iter()
        .all(|&b| (b >= 0x20 && b != 0x7f) || matches!(b, b'\t' | b'\n' | b'\r' | 0x0c | 0x1a));
    text_like.then(|| Cow::Owned(bytes.iter().map(|&b| char::from(b)).collect()))
}

/// How a program's bytes were read (`program_text`): a program rewritten from it is
/// written back the same way, every byte the rewrite does not change kept.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TextEncoding {
    #[default]
    Utf8,
    Latin1,
}

impl TextEncoding {
    /// `text` (read in this encoding, and changed only in ASCII) as bytes again.
    pub fn encode(self, text: String) -> Vec<u8> {
        match self {
            TextEncoding::Utf8 => text.into_bytes(),
            // Every character came from one byte; a rewrite adds only ASCII.
            TextEncoding::Latin1 => text
                .chars()
                .map(|c| u8::try_from(u32::from(c)).unwrap_or(b'?'))
                .collect(),
        }
    }

    /// The media type of a program written in this encoding.
    pub fn media_type(self) -> &'static str {
        match self {
            TextEncoding::Utf8 => "text/plain; charset=utf-8",
            TextEncoding::Latin1 => "text/plain; charset=iso-8859-1",
        }
    }
}

/// `program_text` of owned bytes, without a copy when they are UTF-8, and how they read.
pub fn program_string(bytes: Vec<u8>) -> Option<(String, TextEncoding)> {
    match String::from_utf8(bytes) {
        Ok(text) => Some((text, TextEncoding::Utf8)),
        Err(e) => program_text(e.as_bytes()).map(|t| (t.into_owned(), TextEncoding::Latin1)),
    }
}

/// Syntax errors a program's summary lists (the rest are counted).
const MAX_LISTED_ERRORS: usize = 100;

/// NC program text: UTF-8 (or plain ASCII), then the syntax of G-code or CLS.
pub fn program(bytes: &[u8], file: &str) -> Result<Validated, Problem> {
    let text = match program_text(bytes) {
        Some(text) => text,
        None => Cow::Borrowed(utf8(bytes, file, "invalid-program", "Program is not text")?),
    };
    // Decoded into a string of its own only when it was not UTF-8.
    let latin1 = matches!(text, Cow::Owned(_));
    let text = text.as_ref();
    if text.trim().is_empty() {
        return Err(Problem::invalid_field(
            "content",
            format!("{file}: the program is empty"),
        ));
    }
    let lines = text.lines().count();
    if looks_like_cls(text) {
        let cls = millsim_engine::cl::read_cls(text)
            .map_err(|d| Problem::program_unreadable(file, "CLS file does not read", &d))?;
        return Ok(Validated {
            media_type: "text/plain",
            summary: json!({ "format": "cls", "lines": lines, "moves": cls.moves.len() }),
        });
    }
    let parsed = nc::Program::parse(text)
        .map_err(|d| Problem::program_unreadable(file, "G-code does not parse", &d))?;
    // A line's syntax error stops the program only if the line runs (as in LinuxCNC). Without
    // control flow every line runs, so the upload is refused; with it, the errors are listed
    // and the interpretation decides.
    let deferred: Vec<nc::Diagnostic> = parsed.deferred_errors().cloned().collect();
    if !deferred.is_empty() && !parsed.has_control_flow() {
        return Err(Problem::program_unreadable(
            file,
            "G-code does not parse",
            &nc::Diagnostics(deferred),
        ));
    }
    // The summary is read with every GET and listing of the program: its first errors
    // and how many there are, not one entry per line of a 64 MB file.
    let if_executed: Vec<Value> = deferred
        .iter()
        .take(MAX_LISTED_ERRORS)
        .map(|d| json!({ "line": d.line, "column": d.col, "message": d.message }))
        .collect();
    Ok(Validated {
        media_type: "text/plain",
        summary: json!({
            "format": "gcode",
            "encoding": if latin1 { "iso-8859-1" } else { "utf-8" },
            "lines": lines,
            "blocks": parsed.blocks().len(),
            "syntax_errors_if_executed": if_executed,
            "syntax_errors_if_executed_count": deferred.len(),
        }),
    })
}

/// The problem of an STL `file` the engine's reader refused for `e`.
fn invalid_stl(file: &str, e: impl std::fmt::Display) -> Problem {
    Problem::new(
        axum::http::StatusCode::UNPROCESSABLE_ENTITY,
        "invalid-stl",
        "STL is not usable",
        format!("{file}: {e}"),
    )
    .with("file", file.to_string())
}

/// An STL's summary: what a job reads from it, and what reading it repaired (a job reads
/// the same repaired mesh: `Mesh::from_stl_reader_repaired`).
fn stl_summary(
    triangles: usize,
    (min, max): ([f64; 3], [f64; 3]),
    volume: f64,
    repairs: geometry::StlRepairs,
) -> Value {
    json!({
        "format": "stl",
        "triangles": triangles,
        "bounds": { "min": min, "max": max },
        "volume_mm3": volume,
        "repairs": {
            "duplicate_triangles_dropped": repairs.duplicates,
            "triangles_turned_to_match": repairs.reoriented,
            "vertices_merged": repairs.welded,
            "t_junctions_split": repairs.t_junctions,
            "turned_right_way_out": repairs.flipped,
        },
        "warnings": repairs.warnings(),
    })
}

/// STL stock or part: read and checked (closed, finite, sane size) by the engine.
pub fn stl(bytes: &[u8], file: &str) -> Result<Validated, Problem> {
    let (mesh, repairs) = geometry::Mesh::from_stl_reader_repaired(bytes, bytes.len() as u64)
        .map_err(|e| invalid_stl(file, e))?;
    Ok(Validated {
        media_type: "model/stl",
        summary: stl_summary(mesh.triangles.len(), mesh.bounds(), mesh.volume(), repairs),
    })
}

/// [`stl`] on a file of `len` bytes that `open` reads from its start, without building a
/// mesh: the format, the count against the length, finite vertices, duplicates,
/// closedness (see `stl_read::EdgeSum`), orientation; 8 bytes of memory a triangle.
pub fn stl_stream<R: std::io::Read>(
    mut open: impl FnMut() -> std::io::Result<R>,
    len: u64,
    file: &str,
) -> Result<Validated, Problem> {
    let scan = geometry::stl_read::scan(
        || open().map_err(|e| geometry::StlError::Parse(format!("reading: {e}"))),
        len,
    )
    .map_err(|e| invalid_stl(file, e))?;
    Ok(Validated {
        media_type: "model/stl",
        summary: stl_summary(scan.triangles, scan.bounds, scan.volume, scan.repairs),
    })
}

/// A parametric stock (block or cylinder) as JSON.
pub fn stock_json(bytes: &[u8]) -> Result<Validated, Problem> {
    let shape: geometry::StockShape = parse_json(bytes)?;
    let (min, max) = shape
        .bounds()
        .map_err(|e| Problem::invalid_field("", e.to_string()))?;
    Ok(Validated {
        media_type: "application/json",
        summary: json!({ "format": "parametric", "bounds": { "min": min, "max": max } }),
    })
}

/// A tool library (Fusion 360 JSON, LinuxCNC tool table or CSV, told apart by content)
/// read by the engine; errors name the file, the tool or line, and the field.
pub fn read_tool_library(bytes: &[u8], file: &str) -> Result<ToolLibrary, Problem> {
    let text = utf8(
        bytes,
        file,
        "invalid-tool-library",
        "Tool library is not text",
    )?;
    ToolLibrary::read(text).map_err(|e| {
        let mut err = Problem::from(e);
        err.detail = format!("{file}: {}", err.detail);
        err.with("file", file.to_string())
    })
}

/// A tool library to store: its media type follows the format read; and its view, the
/// members its GET adds to the record (see [`library_view`]).
pub fn tool_library(bytes: &[u8], file: &str) -> Result<(Validated, String), Problem> {
    let lib = read_tool_library(bytes, file)?;
    let checked = Validated {
        media_type: match lib.format {
            "fusion360" => "application/json",
            "csv" => "text/csv",
            _ => "text/plain",
        },
        summary: json!({
            "format": lib.format,
            "tools": lib.tools.len(),
            "unmodelled": lib.report.unmodelled.len() + lib.report.unmodelled_omitted,
            "assumed": lib.report.assumed.len() + lib.report.assumed_omitted,
        }),
    };
    Ok((checked, library_view(lib)?))
}

/// What a tool library's GET adds to its record, as a JSON object: its format, its tools
/// by T number (`"T1"`, each as POST /v1/tools takes a tool) and the import report (at most
/// 500 notes of each kind and the counts per field). At most 10,000 tools: a few MB
/// whatever the file's size.
pub fn library_view(lib: ToolLibrary) -> Result<String, Problem> {
    #[derive(serde::Serialize)]
    struct View {
        format: &'static str,
        tools: std::collections::BTreeMap<String, Tool>,
        report: millsim_engine::tool_library::ImportReport,
    }
    let view = View {
        format: lib.format,
        tools: lib
            .tools
            .into_iter()
            .map(|(n, t)| (format!("T{n}"), t))
            .collect(),
        report: lib.report,
    };
    serde_json::to_string(&view).map_err(|e| Problem::internal(format!("the library's view: {e}")))
}

pub fn tool(bytes: &[u8]) -> Result<Validated, Problem> {
    let tool: Tool = parse_json(bytes)?;
    tool.validate()
        .map_err(|e| Problem::invalid_field(e.field, e.to_string()))?;
    Ok(Validated {
        media_type: "application/json",
        summary: json!({ "shape": tool.shape, "diameter": tool.diameter, "flutes": tool.flutes }),
    })
}

pub fn material(bytes: &[u8]) -> Result<Validated, Problem> {
    let m: Material = parse_json(bytes)?;
    m.validate()
        .map_err(|e| Problem::invalid_field(e.field().to_string(), e.to_string()))?;
    Ok(Validated {
        media_type: "application/json",
        summary: json!({ "name": m.name, "source": m.source }),
    })
}

pub fn machine(bytes: &[u8]) -> Result<Validated, Problem> {
    let m: Machine = parse_json(bytes)?;
    m.validate()
        .map_err(|e| Problem::invalid_field(e.field.clone(), e.to_string()))?;
    Ok(Validated {
        media_type: "application/json",
        summary: json!({ "name": m.name, "kinematics": m.kinematics }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_from_one() {
        assert_eq!(line_col(b"ab\ncd", 0), (1, 1));
        assert_eq!(line_col(b"ab\ncd", 4), (2, 2));
    }

    #[test]
    fn a_latin1_program_reads_and_binary_data_does_not() {
        // `(FRÄSER Ø10)` as a Windows editor saves it: 0xC4 and 0xD8, not UTF-8.
        let bytes = b"O0001 (FR\xc4SER \xd810)\r\nG21 G90\r\nG1 X10 F100\r\nM30\r\n\x1a";
        let (text, encoding) = program_string(bytes.to_vec()).unwrap();
        assert_eq!(encoding, TextEncoding::Latin1);
        // Written back byte for byte.
        assert_eq!(encoding.encode(text.clone()), bytes.to_vec());
        assert!(text.starts_with("O0001 (FR\u{c4}SER \u{d8}10)"), "{text}");
        let v = program(bytes, "p.nc").unwrap();
        assert_eq!(v.summary["encoding"], "iso-8859-1");
        // The DOS end-of-file byte after M30 is a line never run, not a refusal.
        assert_eq!(v.summary["blocks"], 5);
        // UTF-8 stays as it is, and says so.
        let utf8 = program("G1 X1 F1 (Ø)\n".as_bytes(), "p.nc").unwrap();
        assert_eq!(utf8.summary["encoding"], "utf-8");
        // Binary data (a NUL, other control bytes) is not a program in either encoding.
        assert!(program_text(b"G1 X1\n\x00\xff\x10").is_none());
        let Err(p) = program(b"G1 X1\n\x00\xff", "p.nc") else {
            panic!("binary data was taken as a program");
        };
        assert_eq!(p.status, axum::http::StatusCode::UNPROCESSABLE_ENTITY);
    }

    #[test]
    fn cls_is_told_from_gcode() {
        assert!(looks_like_cls("TLAXIS/0,0,1\nGOTO/1,2,3\n"));
        assert!(!looks_like_cls("G0 X1 Y2\nG1 Z-1 F100\n"));
    }
}
