//! Cutting tools as surfaces of revolution, shared by the geometry engine (what the
//! tool sweeps) and the force model (what the cutting edge looks like).
//!
//! Frame: z along the tool axis, measured up from the tool tip (z = 0), in mm.
//! The axial immersion angle κ of an edge point is the angle between the tool axis
//! and the edge's outward surface normal: 90° on a cylindrical flank, 0° at the tip
//! of a ball. Chip thickness scales with sin κ and the chip width of a slice of
//! height dz is dz / sin κ.

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ToolShape {
    /// Flat end mill: cylinder, square corner.
    Flat,
    /// Ball end mill: corner radius = diameter / 2.
    Ball,
    /// Bull-nose (torus) end mill with `corner_radius`.
    #[serde(rename = "bull", alias = "bull_nose")]
    BullNose,
    /// Chamfer/taper mill: cone from `tip_diameter` widening at `taper_half_angle_deg`
    /// from the axis until it reaches `diameter`, cylindrical above.
    Chamfer,
    /// Twist drill: a cone of its point angle (`taper_half_angle_deg` is half of it) from a
    /// sharp tip, cylindrical above. Its two lips cut as the cone's edges do; the chisel
    /// edge at the centre is not modelled (on a conventional point it adds thrust: see the
    /// force model's drilling note).
    Drill,
}

impl ToolShape {
    /// Cone-tipped shapes (chamfer mills and drills share the geometry).
    pub fn is_cone(self) -> bool {
        matches!(self, ToolShape::Chamfer | ToolShape::Drill)
    }
}

/// A drill's point angle when the tool document gives none: the common 118° of HSS and
/// general-purpose drills.
pub const DEFAULT_POINT_ANGLE_DEG: f64 = 118.0;

/// What the tool is made of: its stiffness in bending (deflection) and its strength (the
/// bending-stress guard).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ToolMaterial {
    /// Cemented carbide (WC–Co), what solid end mills are ground from.
    #[default]
    Carbide,
    /// High-speed steel (M2, M42, powder-metallurgy grades).
    Hss,
}

impl ToolMaterial {
    /// Young's modulus, GPa. Carbide: WC with 6–12 % Co grades list 550–650 GPa in their
    /// sheets, 600 taken (the usual figure of end-mill deflection calculators). HSS: M2/M42
    /// sheets list 210–230 GPa, 217 taken.
    pub fn young_modulus_gpa(self) -> f64 {
        match self {
            ToolMaterial::Carbide => 600.0,
            ToolMaterial::Hss => 217.0,
        }
    }

    /// Strength in bending, MPa: carbide's transverse rupture strength (ultrafine grades
    /// 3,500–4,500 MPa, 4,000 taken); hardened HSS (62–65 HRC) 3,000–4,000 MPa bend
    /// strength in steel-makers' sheets, the lower end taken.
    pub fn bending_strength_mpa(self) -> f64 {
        match self {
            ToolMaterial::Carbide => 4_000.0,
            ToolMaterial::Hss => 3_000.0,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ToolMaterial::Carbide => "carbide",
            ToolMaterial::Hss => "hss",
        }
    }
}

/// One piece of the holder stack, from the bottom (nearest the tool) up.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "HolderJson", into = "HolderJson")]
pub struct HolderSegment {
    /// Axial length, mm.
    pub length: f64,
    /// Diameter at the bottom of the segment, mm.
    pub bottom_diameter: f64,
    /// Diameter at the top; equal to the bottom for a cylinder.
    pub top_diameter: f64,
}

/// A holder segment as JSON: `{"length_mm":40,"diameter_mm":32}` for a cylinder, or
/// bottom and top diameters for a cone.
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct HolderJson {
    #[serde(rename = "length_mm", alias = "length")]
    length: f64,
    #[serde(
        rename = "diameter_mm",
        alias = "diameter",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    diameter: Option<f64>,
    #[serde(
        rename = "bottom_diameter_mm",
        alias = "bottom_diameter",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    bottom_diameter: Option<f64>,
    #[serde(
        rename = "top_diameter_mm",
        alias = "top_diameter",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    top_diameter: Option<f64>,
}

impl TryFrom<HolderJson> for HolderSegment {
    type Error = String;
    fn try_from(h: HolderJson) -> Result<Self, String> {
        let (bottom, top) = match (h.diameter, h.bottom_diameter, h.top_diameter) {
            (Some(d), None, None) => (d, d),
            (None, Some(b), Some(t)) => (b, t),
            (None, Some(b), None) => (b, b),
            _ => {
                return Err("a holder segment takes `diameter_mm`, or `bottom_diameter_mm` and `top_diameter_mm`".into())
            }
        };
        Ok(HolderSegment {
            length: h.length,
            bottom_diameter: bottom,
            top_diameter: top,
        })
    }
}

impl From<HolderSegment> for HolderJson {
    fn from(h: HolderSegment) -> Self {
        HolderJson {
            length: h.length,
            diameter: None,
            bottom_diameter: Some(h.bottom_diameter),
            top_diameter: Some(h.top_diameter),
        }
    }
}

/// Radial runout of the tool: the tool's axis of rotation is offset from the spindle
/// axis by `offset` mm in the direction `angle_deg`, measured in the tool's rotating
/// frame from tooth 1, so that each tooth sweeps a slightly different radius.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Runout {
    pub offset: f64,
    pub angle_deg: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "ToolJson", into = "ToolJson")]
pub struct Tool {
    pub name: Option<String>,
    pub shape: ToolShape,
    /// Cutting diameter, mm.
    pub diameter: f64,
    /// Corner radius for bull-nose tools, mm (ignored for the others: flat 0, ball D/2).
    pub corner_radius: f64,
    /// Chamfer tools: diameter at the tip, mm.
    pub tip_diameter: f64,
    /// Chamfer tools: angle between the conical edge and the tool axis, degrees.
    pub taper_half_angle_deg: f64,
    pub flutes: u32,
    /// Helix angle of the flutes, degrees.
    pub helix_deg: f64,
    /// Length of the cutting part from the tip, mm.
    pub flute_length: f64,
    /// Shank diameter, mm (defaults to the cutting diameter).
    pub shank_diameter: Option<f64>,
    /// Length from the tip to the holder's face, mm (defaults to flute length + 2·D).
    pub stick_out: Option<f64>,
    pub holder: Vec<HolderSegment>,
    pub runout: Runout,
    /// Whether the end teeth reach the centre (a plunge into material can be cut). A tool
    /// without (`center_cutting: false`) that descends into material along its axis is a
    /// collision: there is nothing to cut the core under its centre.
    pub center_cutting: bool,
    /// Feed per tooth the tool's library presets (a Fusion 360 library's
    /// `start-values.presets[].f_z`), mm: the optimizer's default chip ceiling for the
    /// tool instead of the rule (see `optimize::guards`).
    pub feed_per_tooth: Option<f64>,
    /// What the tool is made of (carbide unless said).
    pub tool_material: ToolMaterial,
    /// Young's modulus, GPa, overriding the tool material's.
    pub young_modulus: Option<f64>,
    /// A measured static stiffness at the tip (holder and spindle included), N/µm: the
    /// beam's compliance is scaled to it (see `physics::deflection`).
    pub static_stiffness: Option<f64>,
}

/// The tool's JSON document: `{"type":"flat|ball|bull|chamfer|drill","diameter_mm":..,
/// "corner_radius_mm":..,"flutes":..,"helix_deg":..,"flute_length_mm":..,
/// "shank_diameter_mm":..,"stickout_mm":..,"holder":[..],"runout_um":..,
/// "center_cutting":true,"feed_per_tooth_mm":..,"tool_material":"carbide|hss",
/// "young_modulus_gpa":..,"static_stiffness_n_per_um":..}`, a drill's `"point_angle_deg"` (118 when not
/// given). The names
/// without units (`shape`, `diameter`, `flute_length`, ...) are accepted too.
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ToolJson {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(rename = "type", alias = "shape")]
    shape: ToolShape,
    #[serde(rename = "diameter_mm", alias = "diameter")]
    diameter: f64,
    #[serde(rename = "corner_radius_mm", alias = "corner_radius", default)]
    corner_radius: f64,
    #[serde(rename = "tip_diameter_mm", alias = "tip_diameter", default)]
    tip_diameter: f64,
    #[serde(default)]
    taper_half_angle_deg: f64,
    /// Drills: the included angle of the point, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    point_angle_deg: Option<f64>,
    flutes: u32,
    #[serde(default)]
    helix_deg: f64,
    #[serde(rename = "flute_length_mm", alias = "flute_length")]
    flute_length: f64,
    #[serde(
        rename = "shank_diameter_mm",
        alias = "shank_diameter",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    shank_diameter: Option<f64>,
    #[serde(
        rename = "stickout_mm",
        alias = "stick_out",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    stick_out: Option<f64>,
    #[serde(default)]
    holder: Vec<HolderSegment>,
    /// Radial runout, µm, and its direction from tooth 1, degrees.
    #[serde(default)]
    runout_um: f64,
    #[serde(default)]
    runout_angle_deg: f64,
    /// The older form `{"offset": mm, "angle_deg": deg}`.
    #[serde(default, skip_serializing)]
    runout: Option<Runout>,
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    center_cutting: bool,
    #[serde(
        rename = "feed_per_tooth_mm",
        alias = "feed_per_tooth",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    feed_per_tooth: Option<f64>,
    #[serde(default, skip_serializing_if = "is_carbide")]
    tool_material: ToolMaterial,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    young_modulus_gpa: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    static_stiffness_n_per_um: Option<f64>,
}

fn is_carbide(m: &ToolMaterial) -> bool {
    *m == ToolMaterial::Carbide
}

fn yes() -> bool {
    true
}

fn is_true(b: &bool) -> bool {
    *b
}

impl TryFrom<ToolJson> for Tool {
    type Error = String;
    fn try_from(t: ToolJson) -> Result<Self, String> {
        let runout = match t.runout {
            Some(_) if t.runout_um != 0.0 || t.runout_angle_deg != 0.0 => {
                return Err(
                    "give `runout_um` (and `runout_angle_deg`) or `runout`, not both".into(),
                );
            }
            Some(r) => r,
            None => Runout {
                offset: t.runout_um / 1000.0,
                angle_deg: t.runout_angle_deg,
            },
        };
        let taper_half_angle_deg = match (t.shape, t.point_angle_deg) {
            (ToolShape::Drill, Some(_)) if t.taper_half_angle_deg != 0.0 => return Err(
                "a drill takes `point_angle_deg` (or `taper_half_angle_deg`, half of it), not both"
                    .into(),
            ),
            (ToolShape::Drill, Some(p)) => p / 2.0,
            (ToolShape::Drill, None) if t.taper_half_angle_deg == 0.0 => {
                DEFAULT_POINT_ANGLE_DEG / 2.0
            }
            (_, Some(_)) if t.shape != ToolShape::Drill => {
                return Err("`point_angle_deg` is a drill's field (\"type\": \"drill\")".into())
            }
            _ => t.taper_half_angle_deg,
        };
        Ok(Tool {
            name: t.name,
            shape: t.shape,
            diameter: t.diameter,
            corner_radius: t.corner_radius,
            tip_diameter: t.tip_diameter,
            taper_half_angle_deg,
            flutes: t.flutes,
            helix_deg: t.helix_deg,
            flute_length: t.flute_length,
            shank_diameter: t.shank_diameter,
            stick_out: t.stick_out,
            holder: t.holder,
            runout,
            center_cutting: t.center_cutting,
            feed_per_tooth: t.feed_per_tooth,
            tool_material: t.tool_material,
            young_modulus: t.young_modulus_gpa,
            static_stiffness: t.static_stiffness_n_per_um,
        })
    }
}

impl From<Tool> for ToolJson {
    fn from(t: Tool) -> Self {
        let drill = t.shape == ToolShape::Drill;
        ToolJson {
            name: t.name,
            shape: t.shape,
            diameter: t.diameter,
            corner_radius: t.corner_radius,
            tip_diameter: t.tip_diameter,
            taper_half_angle_deg: if drill { 0.0 } else { t.taper_half_angle_deg },
            point_angle_deg: drill.then_some(2.0 * t.taper_half_angle_deg),
            flutes: t.flutes,
            helix_deg: t.helix_deg,
            flute_length: t.flute_length,
            shank_diameter: t.shank_diameter,
            stick_out: t.stick_out,
            holder: t.holder,
            runout_um: t.runout.offset * 1000.0,
            runout_angle_deg: t.runout.angle_deg,
            runout: None,
            center_cutting: t.center_cutting,
            feed_per_tooth: t.feed_per_tooth,
            tool_material: t.tool_material,
            young_modulus_gpa: t.young_modulus,
            static_stiffness_n_per_um: t.static_stiffness,
        }
    }
}

/// A point of the cutting edge at height z above the tip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgePoint {
    /// Distance from the tool axis, mm.
    pub radius: f64,
    /// Axial immersion angle κ, radians, in (0, π/2].
    pub kappa: f64,
}

/// The cutting edge at a height as a point test needs it: [`EdgePoint`]'s radius with the
/// sine and cosine of κ (the components of the edge normal across and along the axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeNormal {
    pub radius: f64,
    pub sin_kappa: f64,
    pub cos_kappa: f64,
}

#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("tool field `{field}`: {message}")]
pub struct ToolError {
    pub field: &'static str,
    pub message: String,
}

fn bad(field: &'static str, message: impl Into<String>) -> ToolError {
    ToolError {
        field,
        message: message.into(),
    }
}

impl Tool {
    /// A flat end mill with the given diameter and flute count, 30° helix, flute length 3·D.
    pub fn flat(diameter: f64, flutes: u32) -> Tool {
        Tool {
            name: None,
            shape: ToolShape::Flat,
            diameter,
            corner_radius: 0.0,
            tip_diameter: 0.0,
            taper_half_angle_deg: 0.0,
            flutes,
            helix_deg: 30.0,
            flute_length: 3.0 * diameter,
            shank_diameter: None,
            stick_out: None,
            holder: Vec::new(),
            runout: Runout::default(),
            center_cutting: true,
            feed_per_tooth: None,
            tool_material: ToolMaterial::Carbide,
            young_modulus: None,
            static_stiffness: None,
        }
    }

    /// A ball end mill.
    pub fn ball(diameter: f64, flutes: u32) -> Tool {
        Tool {
            shape: ToolShape::Ball,
            corner_radius: diameter / 2.0,
            ..Tool::flat(diameter, flutes)
        }
    }

    /// A twist drill of the given diameter and point angle (degrees), two flutes, 30° helix,
    /// flute length 5·D.
    pub fn drill(diameter: f64, point_angle_deg: f64) -> Tool {
        Tool {
            shape: ToolShape::Drill,
            taper_half_angle_deg: point_angle_deg / 2.0,
            flute_length: 5.0 * diameter,
            ..Tool::flat(diameter, 2)
        }
    }

    /// A bull-nose end mill with corner radius `corner_radius`.
    pub fn bull_nose(diameter: f64, corner_radius: f64, flutes: u32) -> Tool {
        Tool {
            shape: ToolShape::BullNose,
            corner_radius,
            ..Tool::flat(diameter, flutes)
        }
    }

    pub fn radius(&self) -> f64 {
        self.diameter / 2.0
    }

    /// The corner radius that the shape implies (0 flat, R ball, given for bull-nose).
    pub fn effective_corner_radius(&self) -> f64 {
        match self.shape {
            ToolShape::Flat | ToolShape::Chamfer | ToolShape::Drill => 0.0,
            ToolShape::Ball => self.radius(),
            ToolShape::BullNose => self.corner_radius,
        }
    }

    pub fn shank_diameter(&self) -> f64 {
        self.shank_diameter.unwrap_or(self.diameter)
    }

    /// Young's modulus in force, N/mm² (MPa).
    pub fn young_modulus_mpa(&self) -> f64 {
        1000.0
            * self
                .young_modulus
                .unwrap_or_else(|| self.tool_material.young_modulus_gpa())
    }

    pub fn stick_out(&self) -> f64 {
        self.stick_out
            .unwrap_or(self.flute_length + 2.0 * self.diameter)
    }

    /// Checks that the numbers describe a tool that can exist; names the field that is wrong.
    pub fn validate(&self) -> Result<(), ToolError> {
        let finite_pos = |field: &'static str, v: f64| {
            if !v.is_finite() || v <= 0.0 {
                Err(bad(field, format!("must be a positive number, got {v}")))
            } else {
                Ok(())
            }
        };
        finite_pos("diameter_mm", self.diameter)?;
        // Below 0.01 mm or above 1 m the number is a unit mistake, not a milling tool.
        if !(0.01..=1000.0).contains(&self.diameter) {
            return Err(bad(
                "diameter_mm",
                format!(
                    "{} mm is not a milling tool diameter (0.01 to 1000 mm)",
                    self.diameter
                ),
            ));
        }
        finite_pos("flute_length_mm", self.flute_length)?;
        if !(0.01..=2000.0).contains(&self.flute_length) {
            return Err(bad(
                "flute_length_mm",
                format!(
                    "{} mm is not a flute length (0.01 to 2000 mm)",
                    self.flute_length
                ),
            ));
        }
        if self.flutes == 0 || self.flutes > 64 {
            return Err(bad(
                "flutes",
                format!("must be between 1 and 64, got {}", self.flutes),
            ));
        }
        if !self.helix_deg.is_finite() || !(0.0..80.0).contains(&self.helix_deg.abs()) {
            return Err(bad(
                "helix_deg",
                format!("must be in [0, 80) degrees, got {}", self.helix_deg),
            ));
        }
        // Numbers a shape ignores must still be numbers a tool could have.
        for (field, v) in [
            ("corner_radius_mm", self.corner_radius),
            ("tip_diameter_mm", self.tip_diameter),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(field, format!("must be 0 or more, got {v}")));
            }
        }
        if !self.taper_half_angle_deg.is_finite() {
            return Err(bad("taper_half_angle_deg", "must be a number"));
        }
        match self.shape {
            ToolShape::BullNose => {
                finite_pos("corner_radius_mm", self.corner_radius)?;
                if self.corner_radius > self.radius() {
                    return Err(bad("corner_radius_mm", "must not exceed half the diameter"));
                }
            }
            ToolShape::Chamfer => {
                if !self.tip_diameter.is_finite()
                    || self.tip_diameter < 0.0
                    || self.tip_diameter >= self.diameter
                {
                    return Err(bad("tip_diameter_mm", "must be in [0, diameter)"));
                }
                if !(self.taper_half_angle_deg > 0.0 && self.taper_half_angle_deg < 89.0) {
                    return Err(bad("taper_half_angle_deg", "must be in (0, 89) degrees"));
                }
            }
            ToolShape::Drill => {
                if self.tip_diameter != 0.0 {
                    return Err(bad(
                        "tip_diameter_mm",
                        "a drill's point is sharp: give 0 or leave it out",
                    ));
                }
                // 60° (centre drills) to 178°: a flat-bottom drill is a flat end mill here.
                if !(self.taper_half_angle_deg >= 30.0 && self.taper_half_angle_deg < 89.0) {
                    return Err(bad(
                        "point_angle_deg",
                        format!(
                            "must be in [60, 178) degrees, got {}",
                            2.0 * self.taper_half_angle_deg
                        ),
                    ));
                }
            }
            ToolShape::Flat | ToolShape::Ball => {}
        }
        if let Some(d) = self.shank_diameter {
            finite_pos("shank_diameter_mm", d)?;
        }
        if let Some(s) = self.stick_out {
            finite_pos("stickout_mm", s)?;
            if s < self.flute_length {
                return Err(bad("stickout_mm", "must be at least the flute length"));
            }
        }
        for seg in &self.holder {
            finite_pos("holder.length_mm", seg.length)?;
            finite_pos("holder.bottom_diameter_mm", seg.bottom_diameter)?;
            finite_pos("holder.top_diameter_mm", seg.top_diameter)?;
        }
        if !self.runout.offset.is_finite()
            || self.runout.offset < 0.0
            || self.runout.offset > 0.1 * self.diameter
        {
            return Err(bad("runout_um", "must be in [0, D/10] (in µm: 0 to 100·D)"));
        }
        if !self.runout.angle_deg.is_finite() {
            return Err(bad("runout_angle_deg", "must be a number"));
        }
        if let Some(e) = self.young_modulus {
            // Polymers to diamond: outside, a unit mistake (MPa or psi given as GPa).
            if !(e.is_finite() && (1.0..=1500.0).contains(&e)) {
                return Err(bad(
                    "young_modulus_gpa",
                    format!("must be in [1, 1500] GPa, got {e}"),
                ));
            }
        }
        if let Some(k) = self.static_stiffness {
            if !(k.is_finite() && k > 0.0 && k <= 1.0e6) {
                return Err(bad(
                    "static_stiffness_n_per_um",
                    format!("must be in (0, 1e6] N/µm, got {k}"),
                ));
            }
        }
        if let Some(fz) = self.feed_per_tooth {
            finite_pos("feed_per_tooth_mm", fz)?;
            // A tooth's bite is a fraction of the diameter; past D/2 it is a unit mistake
            // (inches per tooth given as mm, or a feed per minute).
            if fz > self.diameter / 2.0 {
                return Err(bad(
                    "feed_per_tooth_mm",
                    format!(
                        "{fz} mm per tooth is more than half the diameter: not a feed per tooth"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Height above the tip where the profile becomes the full-diameter cylinder.
    pub fn profile_top(&self) -> f64 {
        match self.shape {
            ToolShape::Flat => 0.0,
            ToolShape::Ball | ToolShape::BullNose => self.effective_corner_radius(),
            ToolShape::Chamfer | ToolShape::Drill => {
                (self.radius() - self.tip_diameter / 2.0)
                    / self.taper_half_angle_deg.to_radians().tan()
            }
        }
    }

    /// Radius of the tool's envelope at height z above the tip (0 below the tip).
    /// Valid for the whole cutting part; above the flutes see `shank_diameter`/`holder`.
    pub fn profile_radius(&self, z: f64) -> f64 {
        if z < 0.0 {
            return 0.0;
        }
        let r = self.radius();
        match self.shape {
            ToolShape::Flat => r,
            ToolShape::Ball | ToolShape::BullNose => {
                let rc = self.effective_corner_radius();
                if z >= rc {
                    r
                } else {
                    let dz = rc - z;
                    r - rc + (rc * rc - dz * dz).max(0.0).sqrt()
                }
            }
            ToolShape::Chamfer | ToolShape::Drill => {
                let top = self.profile_top();
                if z >= top {
                    r
                } else {
                    self.tip_diameter / 2.0 + z * self.taper_half_angle_deg.to_radians().tan()
                }
            }
        }
    }

    /// [`edge_point`](Self::edge_point) with sin κ and cos κ instead of κ, taken from the
    /// profile directly (the engagement tests millions of points: no inverse sine, no sine).
    pub fn edge_normal(&self, z: f64) -> Option<EdgeNormal> {
        if !(z > 0.0 && z <= self.flute_length) {
            return None;
        }
        let (sin_kappa, cos_kappa) = match self.shape {
            ToolShape::Flat => (1.0, 0.0),
            ToolShape::Ball | ToolShape::BullNose => {
                let rc = self.effective_corner_radius();
                if z >= rc {
                    (1.0, 0.0)
                } else {
                    let dz = rc - z;
                    ((rc * rc - dz * dz).max(0.0).sqrt() / rc, dz / rc)
                }
            }
            ToolShape::Chamfer | ToolShape::Drill => {
                if z >= self.profile_top() {
                    (1.0, 0.0)
                } else {
                    let (s, c) = self.taper_half_angle_deg.to_radians().sin_cos();
                    (c, s)
                }
            }
        };
        let radius = self.profile_radius(z);
        if radius <= 0.0 || sin_kappa <= 0.0 {
            return None;
        }
        Some(EdgeNormal {
            radius,
            sin_kappa,
            cos_kappa,
        })
    }

    /// The cutting edge at height z above the tip, or None outside the flutes or at
    /// the very tip where the edge has no radial extent.
    pub fn edge_point(&self, z: f64) -> Option<EdgePoint> {
        if !(z > 0.0 && z <= self.flute_length) {
            return None;
        }
        let half_pi = std::f64::consts::FRAC_PI_2;
        let kappa = match self.shape {
            ToolShape::Flat => half_pi,
            ToolShape::Ball | ToolShape::BullNose => {
                let rc = self.effective_corner_radius();
                if z >= rc {
                    half_pi
                } else {
                    // On the corner arc: the normal points from the arc centre (height rc)
                    // to the edge point; sin κ = horizontal part of that unit normal.
                    let dz = rc - z;
                    ((rc * rc - dz * dz).max(0.0).sqrt() / rc).asin()
                }
            }
            ToolShape::Chamfer | ToolShape::Drill => {
                if z >= self.profile_top() {
                    half_pi
                } else {
                    half_pi - self.taper_half_angle_deg.to_radians()
                }
            }
        };
        let radius = self.profile_radius(z);
        if radius <= 0.0 || kappa <= 0.0 {
            return None;
        }
        Some(EdgePoint { radius, kappa })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn ball_profile_is_a_sphere() {
        let t = Tool::ball(10.0, 2);
        for &z in &[0.5, 1.0, 2.5, 4.9] {
            let r = t.profile_radius(z);
            // (r, z) lies on the sphere centred at (0, 5) with radius 5.
            assert!((r * r + (z - 5.0) * (z - 5.0) - 25.0).abs() < 1e-9);
            let e = t.edge_point(z).unwrap();
            assert!((e.kappa.sin() - r / 5.0).abs() < 1e-12);
        }
        assert_eq!(t.edge_point(6.0).unwrap().kappa, FRAC_PI_2);
        assert!(t.edge_point(0.0).is_none());
    }

    #[test]
    fn edge_normal_is_edge_point_with_the_sine_and_cosine_of_kappa() {
        let mut chamfer = Tool::flat(8.0, 2);
        chamfer.shape = ToolShape::Chamfer;
        chamfer.tip_diameter = 1.0;
        chamfer.taper_half_angle_deg = 30.0;
        for t in [
            Tool::ball(10.0, 2),
            Tool::bull_nose(8.0, 1.5, 4),
            Tool::flat(6.0, 3),
            chamfer,
        ] {
            for i in 0..=120 {
                let z = i as f64 * 0.05;
                let (p, n) = (t.edge_point(z), t.edge_normal(z));
                assert_eq!(p.is_some(), n.is_some(), "{:?} z {z}", t.shape);
                if let (Some(p), Some(n)) = (p, n) {
                    assert_eq!(p.radius, n.radius);
                    assert!((p.kappa.sin() - n.sin_kappa).abs() < 1e-12, "z {z}");
                    assert!((p.kappa.cos() - n.cos_kappa).abs() < 1e-9, "z {z}");
                }
            }
        }
    }

    #[test]
    fn bull_nose_profile_meets_the_flank() {
        let t = Tool::bull_nose(8.0, 1.0, 4);
        assert!((t.profile_radius(0.0) - 3.0).abs() < 1e-12);
        assert!((t.profile_radius(1.0) - 4.0).abs() < 1e-12);
        assert!((t.profile_radius(3.0) - 4.0).abs() < 1e-12);
    }

    #[test]
    fn validation_names_the_field() {
        let mut t = Tool::flat(10.0, 4);
        t.flutes = 0;
        assert_eq!(t.validate().unwrap_err().field, "flutes");
        let mut t = Tool::bull_nose(8.0, 5.0, 4);
        assert_eq!(t.validate().unwrap_err().field, "corner_radius_mm");
        t.corner_radius = f64::NAN;
        assert_eq!(t.validate().unwrap_err().field, "corner_radius_mm");
        assert!(Tool::ball(6.0, 2).validate().is_ok());
        // Numbers the shape ignores are still checked.
        let mut t = Tool::flat(6.0, 2);
        t.corner_radius = -1.0;
        assert_eq!(t.validate().unwrap_err().field, "corner_radius_mm");
        t.corner_radius = 0.0;
        t.tip_diameter = f64::NAN;
        assert_eq!(t.validate().unwrap_err().field, "tip_diameter_mm");
    }
}
