//! Tool libraries: the tools a shop already has, by T number, from a Fusion 360 tool
//! library (JSON), a LinuxCNC tool table (`.tbl`), a plain CSV, or the tool comments a
//! CAM post writes in the program's header. Every import says what it did not model and
//! which values it assumed, so nothing is dropped or guessed silently.

mod csv;
mod fusion;
mod header;
mod linuxcnc;

use std::collections::BTreeMap;

use serde::Serialize;

use crate::tool::Tool;

pub use header::{add_header_diameters, tools_from_header};

/// Tools by T number, and what the import could not carry over.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ToolLibrary {
    pub format: &'static str,
    pub tools: BTreeMap<u32, Tool>,
    pub report: ImportReport,
}

/// What an import left out or assumed, tool by tool: the first [`MAX_NOTES`] of each kind and
/// how many more there were (a library of 10,000 tools with 700 unknown fields each would
/// otherwise carry 7 million notes, half a gigabyte, on every read).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ImportReport {
    /// Fields of the source that millsim does not model (the tool is used without them).
    pub unmodelled: Vec<Note>,
    /// Values the source does not give, with the value taken.
    pub assumed: Vec<Note>,
    /// Notes of each kind past the first [`MAX_NOTES`], counted only.
    #[serde(skip_serializing_if = "is_zero")]
    pub unmodelled_omitted: usize,
    #[serde(skip_serializing_if = "is_zero")]
    pub assumed_omitted: usize,
    /// Notes of each kind per field, every note counted (kept or omitted), for the first
    /// [`MAX_FIELDS`] fields named; notes on further fields are counted under
    /// [`OTHER_FIELDS`] (a file may name a million fields).
    pub unmodelled_by_field: BTreeMap<String, usize>,
    pub assumed_by_field: BTreeMap<String, usize>,
}

/// Fields counted by name in a report's `*_by_field`.
pub const MAX_FIELDS: usize = 500;

/// The `*_by_field` key of the notes on fields past the first [`MAX_FIELDS`].
pub const OTHER_FIELDS: &str = "(other fields)";

/// Counts one note on `field`, by name while fewer than [`MAX_FIELDS`] are named.
fn count_field(counts: &mut BTreeMap<String, usize>, field: &str) {
    if let Some(n) = counts.get_mut(field) {
        *n += 1;
    } else if counts.len() < MAX_FIELDS {
        counts.insert(field.to_string(), 1);
    } else {
        *counts.entry(OTHER_FIELDS.to_string()).or_default() += 1;
    }
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// Notes of each kind an import keeps.
pub const MAX_NOTES: usize = 500;

/// Longest note text kept, in characters (a source's value is quoted in it).
const MAX_NOTE_CHARS: usize = 200;

fn bounded(note: String) -> String {
    match note.char_indices().nth(MAX_NOTE_CHARS) {
        Some((at, _)) => format!("{}…", &note[..at]),
        None => note,
    }
}

/// One remark on one tool: which tool (T number, or its place in the file), which field.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Note {
    pub tool: String,
    pub field: String,
    pub note: String,
}

/// A tool the import cannot use, named by tool and field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("tool {tool}, field `{field}`: {message}")]
pub struct ToolLibraryError {
    pub tool: String,
    pub field: String,
    pub message: String,
}

impl ToolLibraryError {
    fn new(tool: impl Into<String>, field: &str, message: impl Into<String>) -> Self {
        ToolLibraryError {
            tool: tool.into(),
            field: field.into(),
            message: message.into(),
        }
    }
}

/// At most this many tools in one library (a shop's is hundreds).
pub const MAX_TOOLS: usize = 10_000;

impl ToolLibrary {
    /// Reads a library, its format from its content: a JSON object with `data` (Fusion
    /// 360), a table whose lines start with `T<n>` (LinuxCNC), or CSV with a header line.
    pub fn read(text: &str) -> Result<ToolLibrary, ToolLibraryError> {
        let t = text.trim_start_matches('\u{feff}').trim_start();
        if t.starts_with('{') {
            fusion::read(t)
        } else if t
            .lines()
            .map(str::trim)
            .find(|l| !l.is_empty() && !l.starts_with(';'))
            .is_some_and(|l| {
                l.starts_with(['T', 't']) && l[1..].starts_with(|c: char| c.is_ascii_digit())
            })
        {
            linuxcnc::read(t)
        } else {
            csv::read(t)
        }
    }

    fn insert(&mut self, number: u32, tool: Tool, name: &str) -> Result<(), ToolLibraryError> {
        tool.validate()
            .map_err(|e| ToolLibraryError::new(name, "geometry", e.to_string()))?;
        if self.tools.len() >= MAX_TOOLS {
            return Err(ToolLibraryError::new(
                name,
                "number",
                format!("more than {MAX_TOOLS} tools in one library"),
            ));
        }
        if self.tools.insert(number, tool).is_some() {
            return Err(ToolLibraryError::new(
                name,
                "number",
                format!("T{number} is defined twice"),
            ));
        }
        Ok(())
    }

    fn unmodelled(&mut self, tool: &str, field: &str, note: impl Into<String>) {
        count_field(&mut self.report.unmodelled_by_field, field);
        if self.report.unmodelled.len() >= MAX_NOTES {
            self.report.unmodelled_omitted += 1;
            return;
        }
        self.report.unmodelled.push(Note {
            tool: tool.into(),
            field: field.into(),
            note: bounded(note.into()),
        });
    }

    fn assumed(&mut self, tool: &str, field: &str, note: impl Into<String>) {
        count_field(&mut self.report.assumed_by_field, field);
        if self.report.assumed.len() >= MAX_NOTES {
            self.report.assumed_omitted += 1;
            return;
        }
        self.report.assumed.push(Note {
            tool: tool.into(),
            field: field.into(),
            note: bounded(note.into()),
        });
    }
}

/// Flutes and lengths a source that gives only the shape and diameter leaves open: the
/// usual end mill (2 flutes up to 6 mm, 3 up to 12, 4 above; flutes 3·D; helix 30°).
fn default_tool(shape: crate::tool::ToolShape, diameter: f64) -> Tool {
    let flutes = if diameter <= 6.0 {
        2
    } else if diameter <= 12.0 {
        3
    } else {
        4
    };
    let mut t = Tool::flat(diameter, flutes);
    t.shape = shape;
    match shape {
        crate::tool::ToolShape::Ball => t.corner_radius = diameter / 2.0,
        // Twist drills have two flutes whatever their size; a source's angle replaces this.
        crate::tool::ToolShape::Drill => {
            t = Tool::drill(diameter, crate::tool::DEFAULT_POINT_ANGLE_DEG);
        }
        _ => {}
    }
    t
}

/// The shape a free text names (a tool table's comment, a CAM post's tool comment): None
/// when it names none.
fn shape_named_in(text: &str) -> Option<crate::tool::ToolShape> {
    use crate::tool::ToolShape;
    let t = text.to_ascii_lowercase();
    if t.contains("ball") {
        Some(ToolShape::Ball)
    } else if t.contains("bull") {
        Some(ToolShape::BullNose)
    } else if t.contains("drill") || t.contains("spot") {
        Some(ToolShape::Drill)
    } else if t.contains("chamfer") {
        Some(ToolShape::Chamfer)
    } else if t.contains("flat")
        || t.contains("end mill")
        || t.contains("endmill")
        || t.contains("face")
    {
        Some(ToolShape::Flat)
    } else {
        None
    }
}

/// A corner radius or cone angle a source does not give: D/10 for a bull nose, 59° for a
/// drill's point and 45° for other cones, reported as assumed.
fn assume_shape_details(lib: &mut ToolLibrary, name: &str, tool: &mut Tool) {
    use crate::tool::ToolShape;
    match tool.shape {
        ToolShape::BullNose => {
            tool.corner_radius = tool.diameter / 10.0;
            lib.assumed(
                name,
                "corner_radius_mm",
                format!("not given: {} (D/10) assumed", tool.corner_radius),
            );
        }
        ToolShape::Chamfer | ToolShape::Drill => {
            tool.taper_half_angle_deg = if tool.shape == ToolShape::Drill {
                crate::tool::DEFAULT_POINT_ANGLE_DEG / 2.0
            } else {
                45.0
            };
            lib.assumed(
                name,
                "taper_half_angle_deg",
                format!("not given: {}° assumed", tool.taper_half_angle_deg),
            );
        }
        _ => {}
    }
}

/// The assumed values of [`default_tool`] as report notes.
fn note_defaults(lib: &mut ToolLibrary, name: &str, t: &Tool, given: &[&str]) {
    for (field, value) in [
        ("flutes", t.flutes.to_string()),
        ("flute_length_mm", format!("{}", t.flute_length)),
        ("helix_deg", format!("{}", t.helix_deg)),
    ] {
        if !given.contains(&field) {
            lib.assumed(name, field, format!("not given: {value} assumed"));
        }
    }
}
