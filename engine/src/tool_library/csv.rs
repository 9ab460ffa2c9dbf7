//! Tools as CSV: a header line naming the columns (`number`, `type`, `diameter`, and any of
//! `corner_radius`, `flutes`, `flute_length`, `helix`, `shank_diameter`, `stickout`,
//! `taper_half_angle`, `tip_diameter`, `feed_per_tooth` (the tool's chip ceiling in
//! optimization), `name`; lengths in mm), one tool a line.

use super::{ToolLibrary, ToolLibraryError};
use crate::tool::ToolShape;

const COLUMNS: &[&str] = &[
    "number",
    "type",
    "diameter",
    "corner_radius",
    "flutes",
    "flute_length",
    "helix",
    "shank_diameter",
    "stickout",
    "taper_half_angle",
    "tip_diameter",
    "feed_per_tooth",
    "name",
];

pub(super) fn read(text: &str) -> Result<ToolLibrary, ToolLibraryError> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines
        .next()
        .ok_or_else(|| ToolLibraryError::new("-", "header", "the file is empty"))?;
    let names: Vec<String> = header
        .split(',')
        .map(|h| h.trim().to_ascii_lowercase())
        .collect();
    for n in &names {
        if !COLUMNS.contains(&n.as_str()) {
            return Err(ToolLibraryError::new(
                "header",
                n,
                format!("not a column of a tool CSV ({})", COLUMNS.join(", ")),
            ));
        }
    }
    for required in ["number", "diameter"] {
        if !names.iter().any(|n| n == required) {
            return Err(ToolLibraryError::new(
                "header",
                required,
                "the column is missing",
            ));
        }
    }
    let mut lib = ToolLibrary {
        format: "csv",
        ..ToolLibrary::default()
    };
    for (i, line) in lines {
        let place = format!("line {}", i + 1);
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if cells.len() != names.len() {
            return Err(ToolLibraryError::new(
                &place,
                "-",
                format!("{} cells for {} columns", cells.len(), names.len()),
            ));
        }
        let get = |c: &str| {
            names
                .iter()
                .position(|n| n == c)
                .map(|k| cells[k])
                .filter(|v| !v.is_empty())
        };
        let num = |c: &str| -> Result<Option<f64>, ToolLibraryError> {
            get(c)
                .map(|v| {
                    v.parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| {
                            ToolLibraryError::new(&place, c, format!("`{v}` is not a number"))
                        })
                })
                .transpose()
        };
        let number = num("number")?
            .filter(|n| *n >= 0.0 && n.fract() == 0.0 && *n <= u32::MAX as f64)
            .ok_or_else(|| ToolLibraryError::new(&place, "number", "not a tool number"))?
            as u32;
        let name = format!("T{number} ({place})");
        let shape = match get("type").map(str::to_ascii_lowercase).as_deref() {
            None => {
                lib.assumed(&name, "type", "not given: flat assumed");
                ToolShape::Flat
            }
            Some("flat") => ToolShape::Flat,
            Some("ball") => ToolShape::Ball,
            Some("bull") | Some("bull_nose") => ToolShape::BullNose,
            Some("chamfer") => ToolShape::Chamfer,
            Some("drill") => ToolShape::Drill,
            Some(other) => {
                return Err(ToolLibraryError::new(
                    &name,
                    "type",
                    format!("`{other}` is not flat, ball, bull, chamfer or drill"),
                ))
            }
        };
        let d =
            num("diameter")?.ok_or_else(|| ToolLibraryError::new(&name, "diameter", "missing"))?;
        let mut tool = super::default_tool(shape, d);
        let mut given = Vec::new();
        if let Some(f) = num("flutes")? {
            if !(f >= 1.0 && f.fract() == 0.0 && f <= 64.0) {
                return Err(ToolLibraryError::new(
                    &name,
                    "flutes",
                    format!("{f} is not a flute count"),
                ));
            }
            tool.flutes = f as u32;
            given.push("flutes");
        }
        if let Some(l) = num("flute_length")? {
            tool.flute_length = l;
            given.push("flute_length_mm");
        }
        if let Some(h) = num("helix")? {
            tool.helix_deg = h;
            given.push("helix_deg");
        }
        if let Some(r) = num("corner_radius")? {
            tool.corner_radius = r;
        }
        if let Some(a) = num("taper_half_angle")? {
            tool.taper_half_angle_deg = a;
        }
        if let Some(t) = num("tip_diameter")? {
            tool.tip_diameter = t;
        }
        tool.shank_diameter = num("shank_diameter")?;
        tool.stick_out = num("stickout")?;
        tool.feed_per_tooth = num("feed_per_tooth")?;
        tool.name = get("name").map(str::to_string);
        super::note_defaults(&mut lib, &name, &tool, &given);
        lib.insert(number, tool, &name)?;
    }
    Ok(lib)
}
