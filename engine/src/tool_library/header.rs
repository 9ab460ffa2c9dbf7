//! Tools from the comments a CAM post writes at the top of a program, for T numbers no
//! library names: Fusion 360 / HSM `(T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end mill)` (with
//! `TAPER=45deg` on chamfer tools) and Mastercam `( TOOL - 1 DIA. OFF. - 1 LEN. - 1 DIA. - 6. )`.
//! Whatever the comment does not say (flutes, lengths, helix) is assumed and reported with
//! the line it came from.

use super::{default_tool, note_defaults, ToolLibrary};
use crate::tool::ToolShape;

/// Tools described by the program's comments, by T number (the first comment for a number
/// wins), with a note for every assumed value naming the comment's line. Sizes are in the
/// program's units (G20 converted).
pub fn tools_from_header(program: &str) -> ToolLibrary {
    let mut lib = ToolLibrary {
        format: "program header",
        ..ToolLibrary::default()
    };
    let unit = if program_is_inch(program) { 25.4 } else { 1.0 };
    for (i, line) in program.lines().enumerate() {
        let Some(comment) = line
            .split_once('(')
            .and_then(|(_, rest)| rest.split_once(')'))
            .map(|(c, _)| c.trim())
        else {
            continue;
        };
        let Some((number, diameter, text)) = fusion(comment).or_else(|| mastercam(comment)) else {
            continue;
        };
        if lib.tools.contains_key(&number) || !(diameter > 0.0) {
            continue;
        }
        let name = format!("T{number} (line {})", i + 1);
        let shape = super::shape_named_in(text).unwrap_or_else(|| {
            lib.assumed(
                &name,
                "type",
                format!("`{comment}` does not name the shape: flat end mill assumed"),
            );
            ToolShape::Flat
        });
        let mut tool = default_tool(shape, diameter * unit);
        tool.name = Some(comment.to_string());
        let value = |key: &str| {
            comment
                .split_whitespace()
                .find_map(|w| w.strip_prefix(key))
                .and_then(|v| v.trim_end_matches("deg").parse::<f64>().ok())
        };
        match (shape, value("CR="), value("TAPER=")) {
            (ToolShape::BullNose, Some(r), _) if r > 0.0 => tool.corner_radius = r * unit,
            (ToolShape::Chamfer | ToolShape::Drill, _, Some(a)) if a > 0.0 && a < 90.0 => {
                tool.taper_half_angle_deg = a
            }
            _ => super::assume_shape_details(&mut lib, &name, &mut tool),
        }
        // Fusion's ZMIN is the lowest Z the tool reaches. With the program zero on the stock's
        // top, as Fusion's setups usually have it, the flutes must reach that deep: a default
        // 3·D would read every deeper cut as past the flutes (and its force as the flutes'
        // only). Taken to the next whole millimetre (in the program's unit), noted as assumed.
        let mut given: Vec<&str> = Vec::new();
        if let Some(zmin) = value("ZMIN=").filter(|z| z.is_finite() && *z < 0.0) {
            let depth = (-zmin).ceil() * unit;
            if depth > tool.flute_length {
                tool.flute_length = depth;
                given.push("flute_length_mm");
                lib.assumed(
                    &name,
                    "flute_length_mm",
                    format!(
                        "not given: {depth} mm assumed, to reach ZMIN={zmin} below a program zero on the stock's top (3·D would be {})",
                        3.0 * tool.diameter
                    ),
                );
            }
        }
        note_defaults(&mut lib, &name, &tool, &given);
        if tool.validate().is_ok() {
            lib.tools.insert(number, tool);
        }
    }
    lib
}

/// `T<n> D=<d> ... - <type>`: (number, diameter, the whole comment).
fn fusion(c: &str) -> Option<(u32, f64, &str)> {
    let mut words = c.split_whitespace();
    let number: u32 = words.next()?.strip_prefix(['T', 't'])?.parse().ok()?;
    let d: f64 = words.find_map(|w| w.strip_prefix("D="))?.parse().ok()?;
    Some((number, d, c))
}

/// `TOOL - <n> ... DIA. - <d>`: (number, diameter, the whole comment).
fn mastercam(c: &str) -> Option<(u32, f64, &str)> {
    let upper = c.to_ascii_uppercase();
    let after_tool = upper.split_once("TOOL -")?.1;
    let number: u32 = after_tool.split_whitespace().next()?.parse().ok()?;
    let after_dia = upper.rsplit_once("DIA. -")?.1;
    let d: f64 = after_dia
        .split_whitespace()
        .next()?
        .trim_end_matches('"')
        .parse()
        .ok()?;
    Some((number, d, c))
}

/// Whether the program selects inches (G20) before it selects mm (G21), outside comments.
fn program_is_inch(program: &str) -> bool {
    for line in program.lines() {
        let code: String = {
            let mut depth = 0;
            line.chars()
                .take_while(|&c| c != ';')
                .filter(|&c| {
                    match c {
                        '(' => depth += 1,
                        ')' => depth -= 1,
                        _ => {}
                    }
                    depth == 0 && c != ')'
                })
                .collect()
        };
        let upper = code.to_ascii_uppercase();
        for w in upper.split(|c: char| !c.is_ascii_alphanumeric() && c != '.') {
            match w {
                "G20" => return true,
                "G21" => return false,
                _ => {}
            }
        }
    }
    false
}
