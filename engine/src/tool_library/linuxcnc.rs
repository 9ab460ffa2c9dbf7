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
        let shape = super::shape_named_in(comment);
        if shape.is_none() {
            lib.assumed(
                &name,
                "type",
                "the comment does not name the shape: flat end mill assumed",
            );
        }
        let mut tool = super::default_tool(shape.unwrap_or(ToolShape::Flat), d);
        tool.name = Some(comment.trim())
            .filter(|s| !s.is_empty())
            .map(str::to_string);
        super::assume_shape_details(&mut lib, &name, &mut tool);
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
