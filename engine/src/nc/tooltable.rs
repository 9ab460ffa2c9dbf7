//! LinuxCNC tool table (`tool.tbl`): `T1 P1 D6.0 Z+50.0 ;comment`. Values in mm.

use super::{Diagnostic, Diagnostics};
use std::collections::BTreeMap;

#[derive(Clone, Debug, PartialEq, Default)]
pub struct ToolEntry {
    pub number: u32,
    pub pocket: Option<u32>,
    /// Tool length offset (Z), mm: what G43 applies.
    pub z_offset: f64,
    pub x_offset: f64,
    pub diameter: Option<f64>,
    pub comment: String,
}

#[derive(Clone, Debug, PartialEq, Default)]
pub struct ToolTable {
    pub tools: BTreeMap<u32, ToolEntry>,
}

impl ToolTable {
    pub fn get(&self, number: u32) -> Option<&ToolEntry> {
        self.tools.get(&number)
    }

    pub fn insert(&mut self, entry: ToolEntry) {
        self.tools.insert(entry.number, entry);
    }
}

/// Parse a tool table; every bad line is reported.
pub fn parse_tool_table(text: &str) -> Result<ToolTable, Diagnostics> {
    let mut table = ToolTable::default();
    let mut errors = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i as u32 + 1;
        let (body, comment) = match raw.find(';') {
            Some(p) => (&raw[..p], raw[p + 1..].trim().to_string()),
            None => (raw, String::new()),
        };
        if body.trim().is_empty() {
            continue;
        }
        let mut entry = ToolEntry {
            comment,
            ..ToolEntry::default()
        };
        let mut have_t = false;
        let mut col = 1u32;
        let mut ok = true;
        for field in body.split_whitespace() {
            // Column of this field (1-based, characters).
            if let Some(off) = body.find(field) {
                col = body[..off].chars().count() as u32 + 1;
            }
            let mut chars = field.chars();
            let letter = chars.next().unwrap_or(' ').to_ascii_uppercase();
            let rest = chars.as_str();
            let num: Result<f64, _> = rest.parse::<f64>();
            let Ok(v) = num
                .map_err(|_| ())
                .and_then(|v| if v.is_finite() { Ok(v) } else { Err(()) })
            else {
                errors.push(Diagnostic::new(
                    line,
                    col,
                    format!("bad tool table field '{field}'"),
                ));
                ok = false;
                break;
            };
            match letter {
                'T' | 'P' if v < 0.0 || v.fract() != 0.0 || v > u32::MAX as f64 => {
                    errors.push(Diagnostic::new(
                        line,
                        col,
                        format!("'{field}' must be a whole number"),
                    ));
                    ok = false;
                    break;
                }
                'T' => {
                    entry.number = v as u32;
                    have_t = true;
                }
                'P' => entry.pocket = Some(v as u32),
                'Z' => entry.z_offset = v,
                'X' => entry.x_offset = v,
                'D' => entry.diameter = Some(v),
                // Other axes, lathe orientation and angles do not change a milling tool's tip.
                'Y' | 'A' | 'B' | 'C' | 'U' | 'V' | 'W' | 'I' | 'J' | 'Q' => {}
                _ => {
                    errors.push(Diagnostic::new(
                        line,
                        col,
                        format!("unknown tool table field '{field}'"),
                    ));
                    ok = false;
                    break;
                }
            }
        }
        if ok && !have_t {
            errors.push(Diagnostic::new(line, 1, "tool table line has no T word"));
            ok = false;
        }
        if ok {
            if table.tools.contains_key(&entry.number) {
                errors.push(Diagnostic::new(
                    line,
                    1,
                    format!("tool T{} listed twice", entry.number),
                ));
            } else {
                table.insert(entry);
            }
        }
    }
    if errors.is_empty() {
        Ok(table)
    } else {
        Err(Diagnostics(errors))
    }
}
