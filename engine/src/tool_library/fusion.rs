//! Fusion 360 tool libraries: `{"data":[tool, ...]}`, each tool with `type`, `unit`,
//! `geometry` (DC, NOF, LCF, LB, OAL, RE, SFDM, TA, SIG, HAND, ...), `holder.segments`
//! (height, lower-diameter, upper-diameter), `post-process.number` (the T number) and
//! `start-values.presets[].f_z` (feed per tooth: the tool's chip ceiling in optimization).

use serde_json::Value;

use super::{ToolLibrary, ToolLibraryError};
use crate::tool::{HolderSegment, ToolShape};

/// Geometry fields that become part of the tool; the others are reported.
const MODELLED: &[&str] = &[
    "DC",
    "NOF",
    "LCF",
    "LB",
    "RE",
    "SFDM",
    "TA",
    "SIG",
    "tip-diameter",
];

pub(super) fn read(text: &str) -> Result<ToolLibrary, ToolLibraryError> {
    let mut lib = ToolLibrary {
        format: "fusion360",
        ..ToolLibrary::default()
    };
    // The tools are read one at a time as the text is parsed, never the whole document
    // as a tree: a library of 10,000 tools with 700 fields each is a 60 MB file, and its
    // tree took over 2 GB.
    let mut failed = None;
    let mut seen_data = false;
    let mut de = serde_json::Deserializer::from_str(text);
    let root = Root {
        lib: &mut lib,
        failed: &mut failed,
        seen_data: &mut seen_data,
    };
    let parsed = serde::de::DeserializeSeed::deserialize(root, &mut de).and_then(|()| de.end());
    if let Some(e) = failed {
        return Err(e);
    }
    match parsed {
        Err(e) if e.classify() == serde_json::error::Category::Data => {
            return Err(ToolLibraryError::new("-", "data", e.to_string()))
        }
        Err(e) => return Err(ToolLibraryError::new("-", "json", format!("not JSON: {e}"))),
        Ok(()) => {}
    }
    if !seen_data {
        return Err(ToolLibraryError::new(
            "-",
            "data",
            "a Fusion 360 library has a `data` array of tools",
        ));
    }
    Ok(lib)
}

/// The document's root object: its `data` array read tool by tool, the other members
/// skipped. A tool's error is kept in `failed` and stops the parse.
struct Root<'a> {
    lib: &'a mut ToolLibrary,
    failed: &'a mut Option<ToolLibraryError>,
    seen_data: &'a mut bool,
}

impl<'de> serde::de::DeserializeSeed<'de> for Root<'_> {
    type Value = ();
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> serde::de::Visitor<'de> for Root<'_> {
    type Value = ();
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a Fusion 360 library: an object with a `data` array of tools")
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(key) = map.next_key::<std::borrow::Cow<'de, str>>()? {
            if key == "data" {
                *self.seen_data = true;
                map.next_value_seed(Data {
                    lib: &mut *self.lib,
                    failed: &mut *self.failed,
                })?;
            } else {
                map.next_value::<serde::de::IgnoredAny>()?;
            }
        }
        Ok(())
    }
}

/// The `data` array: each tool parsed alone and read into the library.
struct Data<'a> {
    lib: &'a mut ToolLibrary,
    failed: &'a mut Option<ToolLibraryError>,
}

impl<'de> serde::de::DeserializeSeed<'de> for Data<'_> {
    type Value = ();
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> serde::de::Visitor<'de> for Data<'_> {
    type Value = ();
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a Fusion 360 library's `data` array of tools")
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        // Bounded: `read_tool` refuses the tool past MAX_TOOLS.
        let mut i = 0;
        while let Some(t) = seq.next_element::<Value>()? {
            if let Err(e) = read_tool(self.lib, i, &t) {
                *self.failed = Some(e);
                return Err(serde::de::Error::custom(
                    "stopped at a tool that does not read",
                ));
            }
            i += 1;
        }
        Ok(())
    }
}

/// Tool `i` of the `data` array into the library.
fn read_tool(lib: &mut ToolLibrary, i: usize, t: &Value) -> Result<(), ToolLibraryError> {
    {
        let place = format!("data[{i}]");
        let number = t
            .pointer("/post-process/number")
            .and_then(Value::as_u64)
            .and_then(|n| u32::try_from(n).ok())
            .ok_or_else(|| {
                ToolLibraryError::new(&place, "post-process.number", "the tool has no T number")
            })?;
        let name = format!("T{number} ({place})");
        let kind = t
            .get("type")
            .and_then(Value::as_str)
            .ok_or_else(|| ToolLibraryError::new(&name, "type", "missing"))?;
        let unit = match t
            .get("unit")
            .and_then(Value::as_str)
            .unwrap_or("millimeters")
        {
            "millimeters" => 1.0,
            "inches" => 25.4,
            other => {
                return Err(ToolLibraryError::new(
                    &name,
                    "unit",
                    format!("`{other}` is neither millimeters nor inches"),
                ))
            }
        };
        let g = t
            .get("geometry")
            .ok_or_else(|| ToolLibraryError::new(&name, "geometry", "missing"))?;
        let num = |field: &str| g.get(field).and_then(Value::as_f64);
        let length = |field: &str| num(field).map(|v| v * unit);
        let dc = length("DC").ok_or_else(|| {
            ToolLibraryError::new(&name, "geometry.DC", "the cutting diameter is missing")
        })?;
        let shape = match kind {
            "flat end mill" | "face mill" => ToolShape::Flat,
            "ball end mill" => ToolShape::Ball,
            "bull nose end mill" => ToolShape::BullNose,
            "chamfer mill" => ToolShape::Chamfer,
            "drill" | "spot drill" => ToolShape::Drill,
            other => {
                return Err(ToolLibraryError::new(
                    &name,
                    "type",
                    format!("`{other}` is not a tool millsim models (flat, ball, bull nose, face or chamfer mill, drill)"),
                ))
            }
        };
        let mut tool = super::default_tool(shape, dc);
        let mut given = Vec::new();
        if let Some(n) = num("NOF") {
            if !(n >= 1.0 && n.fract() == 0.0 && n <= 64.0) {
                return Err(ToolLibraryError::new(
                    &name,
                    "geometry.NOF",
                    format!("{n} is not a flute count"),
                ));
            }
            tool.flutes = n as u32;
            given.push("flutes");
        }
        if let Some(l) = length("LCF") {
            tool.flute_length = l;
            given.push("flute_length_mm");
        }
        tool.stick_out = length("LB");
        tool.shank_diameter = length("SFDM");
        tool.name = t
            .get("description")
            .and_then(Value::as_str)
            .map(str::to_string);
        match shape {
            ToolShape::BullNose => {
                tool.corner_radius = length("RE").ok_or_else(|| {
                    ToolLibraryError::new(
                        &name,
                        "geometry.RE",
                        "a bull nose end mill needs its corner radius",
                    )
                })?
            }
            ToolShape::Chamfer | ToolShape::Drill => {
                // A drill's point is a cone of the point angle SIG (its half from the axis);
                // a chamfer mill's taper angle TA is already measured from the axis.
                let half = if kind.ends_with("drill") {
                    num("SIG").map(|s| s / 2.0)
                } else {
                    num("TA")
                }
                .ok_or_else(|| {
                    ToolLibraryError::new(
                        &name,
                        "geometry.TA",
                        "the cone's angle is missing (TA, or SIG for a drill)",
                    )
                })?;
                tool.taper_half_angle_deg = half;
                if shape == ToolShape::Chamfer {
                    tool.tip_diameter = length("tip-diameter").unwrap_or(0.0);
                }
            }
            _ => {}
        }
        if let Some(helix) = g.get("helix-angle").and_then(Value::as_f64) {
            tool.helix_deg = helix;
            given.push("helix_deg");
        }
        if let Some(segments) = t.pointer("/holder/segments").and_then(Value::as_array) {
            for (k, s) in segments.iter().enumerate() {
                let f = |field: &str| {
                    s.get(field)
                        .and_then(Value::as_f64)
                        .map(|v| v * unit)
                        .ok_or_else(|| {
                            ToolLibraryError::new(
                                &name,
                                &format!("holder.segments[{k}].{field}"),
                                "missing",
                            )
                        })
                };
                tool.holder.push(HolderSegment {
                    length: f("height")?,
                    bottom_diameter: f("lower-diameter")?,
                    top_diameter: f("upper-diameter")?,
                });
            }
        }
        if let Some(obj) = g.as_object() {
            for (field, v) in obj {
                if !MODELLED.contains(&field.as_str()) && field != "helix-angle" {
                    lib.unmodelled(
                        &name,
                        &format!("geometry.{field}"),
                        format!("{v} (not modelled)"),
                    );
                }
            }
        }
        if kind.ends_with("drill") {
            lib.unmodelled(
                &name,
                "type",
                "a drill is cut as a cone of its point angle; its chisel edge is not modelled",
            );
        }
        tool.feed_per_tooth = preset_feed_per_tooth(lib, &name, t, unit)?;
        super::note_defaults(lib, &name, &tool, &given);
        lib.insert(number, tool, &name)?;
    }
    Ok(())
}

/// The feed per tooth of the tool's presets (`start-values.presets[].f_z`, in the tool's
/// unit), mm: the smallest where presets differ (they are for different materials or
/// operations, and the guard must hold for any of them), with a note saying so.
fn preset_feed_per_tooth(
    lib: &mut ToolLibrary,
    name: &str,
    tool: &Value,
    unit: f64,
) -> Result<Option<f64>, ToolLibraryError> {
    let Some(presets) = tool
        .pointer("/start-values/presets")
        .and_then(Value::as_array)
    else {
        return Ok(None);
    };
    // The presets' other values (spindle speed n, cutting speed v_c, feeds v_f, ...) are
    // the CAM's starting values: the program's own S and F words are what is simulated.
    // One note per tool naming them, so that a user sees they were read and not used.
    let mut others: Vec<&str> = presets
        .iter()
        .filter_map(Value::as_object)
        .flat_map(|p| p.keys().map(String::as_str))
        .filter(|k| !matches!(*k, "f_z" | "name" | "guid" | "description"))
        .collect();
    others.sort_unstable();
    others.dedup();
    if !others.is_empty() {
        const SHOWN: usize = 12;
        let more = others.len().saturating_sub(SHOWN);
        lib.unmodelled(
            name,
            "start-values.presets",
            format!(
                "{}{} not used: the program's S and F words are simulated (f_z is the tool's chip ceiling)",
                others[..others.len().min(SHOWN)].join(", "),
                if more > 0 { format!(" and {more} more") } else { String::new() }
            ),
        );
    }
    let mut values = Vec::new();
    for (k, p) in presets.iter().enumerate() {
        let Some(v) = p.get("f_z") else { continue };
        let fz = v
            .as_f64()
            .filter(|f| f.is_finite() && *f > 0.0)
            .ok_or_else(|| {
                ToolLibraryError::new(
                    name,
                    &format!("start-values.presets[{k}].f_z"),
                    format!("{v} is not a feed per tooth"),
                )
            })?;
        values.push(fz * unit);
    }
    let Some(min) = values.iter().copied().reduce(f64::min) else {
        return Ok(None);
    };
    let max = values.iter().copied().fold(min, f64::max);
    if max > min {
        lib.assumed(
            name,
            "start-values.presets.f_z",
            format!(
                "{} presets give {min}–{max} mm per tooth: the smallest, {min} mm, is the tool's chip ceiling",
                values.len()
            ),
        );
    }
    Ok(Some(min))
}
