//! Tools from the comments a CAM post writes at the top of a program, for T numbers no
//! library names: Fusion 360 / HSM `(T1 D=2.65 CR=0 - ZMIN=-12.55 - flat end mill)` (with
//! `TAPER=45deg` on chamfer tools), Mastercam's `( TOOL - 1 DIA. OFF. - 1 LEN. - 1 DIA. - 6. )`
//! and its later `( T1 |  10. FLAT ENDMILL | H1 )` (the size leads the tool's name;
//! `TOOL DIA. - .25` where the post writes it).
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
    let inch = program_is_inch(program);
    let unit = if inch { 25.4 } else { 1.0 };
    for (i, line) in program.lines().enumerate() {
        let Some(comment) = line
            .split_once('(')
            .and_then(|(_, rest)| rest.split_once(')'))
            .map(|(c, _)| c.trim())
        else {
            continue;
        };
        let Some((number, diameter, text)) = fusion(comment)
            .or_else(|| mastercam(comment))
            .or_else(|| mastercam_piped(comment, inch))
        else {
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
        let corner = value("CR=").or_else(|| piped_corner_radius(comment, inch));
        match (shape, corner, value("TAPER=")) {
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

/// Adds to the caller's tool diameters by number (cutter compensation's radii, see
/// `nc::InterpretOptions::tool_diameters`) those of the tools the program's header comments
/// describe, for numbers it lacks: the tools a simulation cuts with where the job gives
/// none. A job's one tool (number 0) serves every number and leaves the map as it is.
pub fn add_header_diameters(diameters: &mut std::collections::BTreeMap<u32, f64>, program: &str) {
    if diameters.contains_key(&0) {
        return;
    }
    for (&number, tool) in tools_from_header(program).tools.iter() {
        if number > 0 {
            diameters.entry(number).or_insert(tool.diameter);
        }
    }
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

/// Mastercam's `T<n> | <size> <name> | H<n> | ...`: (number, diameter in the program's
/// unit, the name). The diameter is `TOOL DIA. - <d>` where a field gives it, else the size
/// the name starts with: a decimal in the program's unit (`10. FLAT ENDMILL`) or an inch
/// fraction (`1/4 FLAT ENDMILL`, in inches in a metric program too). A name without a size
/// (`#7 DRILL`) describes no tool.
fn mastercam_piped(c: &str, inch: bool) -> Option<(u32, f64, &str)> {
    let mut fields = c.split('|').map(str::trim);
    let number: u32 = fields.next()?.strip_prefix(['T', 't'])?.parse().ok()?;
    let name = fields.next()?;
    let rest: Vec<&str> = fields.collect();
    // The offset field after the name marks the form (`H1`, `H0`).
    if !rest.first().is_some_and(|h| {
        h.strip_prefix(['H', 'h'])
            .is_some_and(|n| n.parse::<u32>().is_ok())
    }) {
        return None;
    }
    let given = rest.iter().find_map(|f| {
        let upper = f.to_ascii_uppercase();
        let d = upper
            .strip_prefix("TOOL DIA.")?
            .trim_start()
            .strip_prefix('-')?;
        d.trim().trim_end_matches('"').parse::<f64>().ok()
    });
    let d = given.or_else(|| size_in_unit(name.split_whitespace().next()?, inch))?;
    Some((number, d, name))
}

/// A size as a name writes it, in the program's unit: a decimal (`10.`, `.5`) as it is,
/// an inch fraction (`1/4`, `1-1/2`) converted for a metric program.
fn size_in_unit(word: &str, inch: bool) -> Option<f64> {
    let to_unit = |inches: f64| if inch { inches } else { inches * 25.4 };
    if let Some((whole, frac)) = word.split_once('-') {
        let w: f64 = whole.parse().ok()?;
        return Some(to_unit(w + fraction(frac)?));
    }
    if word.contains('/') {
        return fraction(word).map(to_unit);
    }
    word.parse::<f64>().ok().filter(|d| d.is_finite())
}

fn fraction(word: &str) -> Option<f64> {
    let (n, d) = word.split_once('/')?;
    let (n, d): (f64, f64) = (n.parse().ok()?, d.parse().ok()?);
    (d > 0.0).then(|| n / d)
}

/// A bull nose's corner radius in a Mastercam name: the size before `RAD` (`10. BULL
/// ENDMILL 1. RAD`), in the program's unit.
fn piped_corner_radius(name: &str, inch: bool) -> Option<f64> {
    let words: Vec<&str> = name.split_whitespace().collect();
    let at = words
        .iter()
        .position(|w| w.eq_ignore_ascii_case("RAD") || w.eq_ignore_ascii_case("RAD."))?;
    let r = size_in_unit(words.get(at.checked_sub(1)?)?, inch)?;
    (r > 0.0).then_some(r)
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
