//! LinuxCNC tool tables (`.tbl`): one tool a line, `T<n> P<pocket> D<diameter> Z<offset>
//! ... ;comment`. The table gives the diameter only: the shape comes from the comment
//! (ball, bull, chamfer, drill; flat otherwise) and the rest is assumed, and reported.

use super::{ToolLibrary, ToolLibraryError};
use crate::tool::ToolShape;

pub(super) fn read(text: &str) -> Result<ToolLibrary, ToolLibraryError> {
    let mut lib = ToolLibrary {
        format: "linuxcnc",
        ..ToolLibrary::default()
    };
    for (i, line) in text.lines().enumerate() {
        let (words, comment) = line.split_once(';').unwrap_or((line, ""));
        if words.trim().is_empty() {
            continue;
        }
        let place = format!("line {}", i + 1);
        let mut number = None;
        let mut diameter = None;
        for w in words.split_whitespace() {
            let (letter, value) = w.split_at(w.chars().next().map_or(0, char::len_utf8));
            let v: f64 = value.parse().map_err(|_| {
                ToolLibraryError::new(
                    &place,
                    letter,
                    format!("`{w}` is not a letter and a number"),
                )
            })?;
            match letter.to_ascii_uppercase().as_str() {
                "T" if v >= 0.0 && v.fract() == 0.0 && v <= u32::MAX as f64 => {
                    number = Some(v as u32)
                }
                "T" => {
                    return Err(ToolLibraryError::new(
                        &place,
                        "T",
                        format!("{v} is not a tool number"),
                    ))
                }
                "D" => diameter = Some(v),
                _ => {} // pocket, offsets, lathe fields: not part of the cutter
            }
        }
        let number = number
            .ok_or_else(|| ToolLibraryError::new(&place, "T", "the line has no tool number"))?;
        let name = format!("T{number} ({place})");
        let d = diameter.filter(|d| *d > 0.0).ok_or_else(|| {
            ToolLibraryError::new(
                &name,
                "D",
                "the cutting diameter is missing or not positive",
            )
        })?;
        let c = comment.to_ascii_lowercase();
        let (shape, said) = if c.contains("ball") {
            (ToolShape::Ball, true)
        } else if c.contains("bull") {
            (ToolShape::BullNose, true)
        } else if c.contains("chamfer") || c.contains("drill") || c.contains("spot") {
            (ToolShape::Chamfer, true)
        } else {
            (
                ToolShape::Flat,
                c.contains("flat") || c.contains("end mill") || c.contains("endmill"),
            )
        };
        let mut tool = super::default_tool(shape, d);
        tool.name = Some(comment.trim())
            .filter(|s| !s.is_empty())
            .map(str::to_string);
        if !said {
            lib.assumed(
                &name,
                "type",
                "the comment does not name the shape: flat end mill assumed",
            );
        }
        match shape {
            ToolShape::BullNose => {
                tool.corner_radius = d / 10.0;
                lib.assumed(
                    &name,
                    "corner_radius_mm",
                    format!("not in a tool table: {} (D/10) assumed", tool.corner_radius),
                );
            }
            ToolShape::Chamfer => {
                tool.taper_half_angle_deg = if c.contains("drill") { 59.0 } else { 45.0 };
                lib.assumed(
                    &name,
                    "taper_half_angle_deg",
                    format!(
                        "not in a tool table: {}° assumed",
                        tool.taper_half_angle_deg
                    ),
                );
            }
            _ => {}
        }
        lib.assumed(
            &name,
            "unit",
            "a tool table is in machine units: mm assumed",
        );
        super::note_defaults(&mut lib, &name, &tool, &[]);
        lib.insert(number, tool, &name)?;
    }
    Ok(lib)
}
