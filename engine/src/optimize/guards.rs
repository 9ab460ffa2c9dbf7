//! Default guards: the ceilings a tool itself sets on the feed optimization, on unless the
//! limits switch them off (`"tool_guards": false`, also per tool). They keep the optimizer
//! from driving a small tool to chip loads and forces that break it when the user's limits
//! were written for the largest tool of the job. They are per-tool limits like any other:
//! the effective limit is the smaller of the user's and the guard's.
//!
//! Two ceilings per tool:
//!
//! - **Chip** (the thickest chip actually cut, the engine's `max_chip_thickness`, mm): the
//!   tool's feed-per-tooth preset where its library gives one (a Fusion 360 library's
//!   `start-values.presets[].f_z`, see [`Tool::feed_per_tooth`]); otherwise the rule
//!   h_max = s · min(c · D, h_cap), with c and h_cap by material class and s by shape
//!   ([`chip_rule`]).
//! - **Force** (peak |F|, N): what the tool's own section carries in bending at the clamp,
//!   σ = F·L / (π·d_e³/32) ≤ σ_allow ([`force_rule`]). A later refinement may bound the
//!   deflection as well.

use serde::Serialize;

use crate::physics::Material;
use crate::tool::{Tool, ToolShape};

/// Work-material classes for the chip rule, told apart by the tangential cutting
/// coefficient Ktc (N/mm²): the force per chip area is what the edge must carry, so it
/// orders materials as catalogues' ISO groups do (N: aluminium ≈ 500–900 N/mm²; P/K:
/// steels and cast irons ≈ 1,200–2,200, titanium alloys in the same band, e.g. the
/// built-in TC6 at 1,785; M/S/H: stainless, heat-resistant and hardened ≥ 2,200).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MaterialClass {
    /// Ktc < 1,200 N/mm²: aluminium, magnesium and other light alloys (ISO N).
    LightAlloy,
    /// 1,200 ≤ Ktc < 2,200 N/mm²: steels, cast irons, titanium alloys (ISO P, K, S-Ti).
    Steel,
    /// Ktc ≥ 2,200 N/mm²: stainless, heat-resistant and hardened (ISO M, S, H).
    Hard,
}

/// Ktc bounds between the classes, N/mm².
pub const LIGHT_ALLOY_MAX_KTC: f64 = 1_200.0;
pub const STEEL_MAX_KTC: f64 = 2_200.0;

impl MaterialClass {
    pub fn of(material: &Material) -> MaterialClass {
        let ktc = material.coefficients.ktc;
        if ktc < LIGHT_ALLOY_MAX_KTC {
            MaterialClass::LightAlloy
        } else if ktc < STEEL_MAX_KTC {
            MaterialClass::Steel
        } else {
            MaterialClass::Hard
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            MaterialClass::LightAlloy => "light alloy",
            MaterialClass::Steel => "steel, cast iron, titanium",
            MaterialClass::Hard => "stainless, heat-resistant, hardened",
        }
    }

    /// The chip ceiling per mm of diameter, and its cap, mm.
    ///
    /// Catalogue starting values of solid carbide end mills (fz at full slot, where the
    /// thickest chip equals fz) grow about linearly with the diameter: aluminium ≈ 0.008·D
    /// (Ø3 0.025, Ø6 0.05, Ø12 0.09, Ø20 0.13 mm), steel ≈ 0.005·D (Ø6 0.025, Ø12 0.064,
    /// Ø20 0.10), stainless ≈ 0.004·D (Ø12 0.05, Ø20 0.08), levelling off above Ø20 (Ø25:
    /// 0.15, 0.115, 0.09) — machinecalcs.com "Chip Load Chart (End Mill Feed per Tooth)";
    /// the inch charts agree (1/2" in 6061/7075 0.004–0.008 in/tooth). A guard is a ceiling,
    /// not a starting value: 1.5 times the start value, the headroom catalogues leave to
    /// their ranges' upper ends, so that a machinist's usual chip loads never bind it while
    /// a chip several times a tool's rating does.
    pub fn chip_per_diameter(self) -> (f64, f64) {
        match self {
            MaterialClass::LightAlloy => (1.5 * 0.008, 1.5 * 0.15),
            MaterialClass::Steel => (1.5 * 0.005, 1.5 * 0.115),
            MaterialClass::Hard => (1.5 * 0.004, 1.5 * 0.09),
        }
    }
}

/// The chip ceiling's factor by shape. A ball (and the cone of a chamfer mill or spot
/// drill) meets the chip near its tip, where the edge runs on a small radius and its wedge
/// is thinnest: no catalogue gives such a tool more chip than a flat end mill of the same
/// diameter, and several give less; 0.8 of the flat end mill's. A bull nose's corner radius
/// makes its corner stronger than a flat end mill's, not weaker: 1.
pub fn shape_factor(shape: ToolShape) -> f64 {
    match shape {
        ToolShape::Flat | ToolShape::BullNose => 1.0,
        ToolShape::Ball | ToolShape::Chamfer => 0.8,
        // A drill's lip takes half its feed per revolution; catalogues' per-revolution feeds
        // (≈ 0.01–0.02·D in aluminium, about half in steel) put the lip's chip at the flat
        // end mill's rule.
        ToolShape::Drill => 1.0,
    }
}

/// Allowed bending stress of the tool's section: its material's bending strength
/// ([`ToolMaterial::bending_strength_mpa`](crate::tool::ToolMaterial::bending_strength_mpa):
/// carbide's transverse rupture strength 4,000 MPa, hardened HSS 3,000 MPa) over a safety
/// factor of 2. The factor covers the bending being reversed once a revolution (fatigue) and
/// each tooth entry being an impact; the notch the flutes cut is in the effective core
/// diameter already, and the core's section is taken over the whole stick-out although a
/// shank thicker than the core runs from the flutes to the holder. The simulation reports
/// the real stress at the clamp and the flute root from each slice's load
/// (`bending_stress_mpa`, see `physics::deflection`).
pub const BENDING_SAFETY_FACTOR: f64 = 2.0;

pub use crate::physics::deflection::EFFECTIVE_CORE_RATIO;

/// Where a ceiling comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GuardSource {
    /// The documented rule of this module.
    Rule,
    /// The feed-per-tooth preset of the tool's library (or of its own document).
    LibraryPreset,
}

/// The ceilings one tool sets, with how each was found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ToolGuards {
    /// Thickest chip, mm.
    pub max_chip_thickness: f64,
    pub chip_source: GuardSource,
    /// The rule or preset with its numbers, for the summary.
    pub chip_rule: String,
    /// Peak |F|, N.
    pub max_force: f64,
    pub force_source: GuardSource,
    pub force_rule: String,
    pub material_class: MaterialClass,
}

/// The chip ceiling by rule, mm: shape factor · min(c·D, cap).
pub fn chip_rule(tool: &Tool, class: MaterialClass) -> f64 {
    let (per_d, cap) = class.chip_per_diameter();
    shape_factor(tool.shape) * (per_d * tool.diameter).min(cap)
}

/// The effective diameter of the section in bending, mm: 0.8·D, or the shank where it is
/// thinner still (a reduced shank is then the weakest section).
pub fn effective_diameter(tool: &Tool) -> f64 {
    (EFFECTIVE_CORE_RATIO * tool.diameter).min(tool.shank_diameter())
}

/// The force ceiling, N: F = σ_allow · π·d_e³ / (32·L), the force at the tip whose moment
/// at the clamp, over the whole stick-out L, stresses the fluted core to σ_allow. Taking the
/// core's section over the whole stick-out is conservative where a shank thicker than the
/// core runs from the flutes to the holder. It bounds peak |F| (the 3-D force, axial part
/// included), which is at least the bending part.
pub fn force_rule(tool: &Tool) -> f64 {
    let sigma = tool.tool_material.bending_strength_mpa() / BENDING_SAFETY_FACTOR;
    let d = effective_diameter(tool);
    sigma * std::f64::consts::PI * d.powi(3) / (32.0 * tool.stick_out())
}

/// The guards of `tool` cutting `material`.
pub fn tool_guards(tool: &Tool, material: &Material) -> ToolGuards {
    let class = MaterialClass::of(material);
    let (chip, chip_source, chip_rule_text) = match tool.feed_per_tooth {
        Some(fz) => (
            fz,
            GuardSource::LibraryPreset,
            format!("the tool's feed-per-tooth preset, {fz} mm"),
        ),
        None => {
            let (per_d, cap) = class.chip_per_diameter();
            let h = chip_rule(tool, class);
            (
                h,
                GuardSource::Rule,
                format!(
                    "{} (Ktc {:.0} N/mm²): {} × min({per_d:.4}·D, {cap:.4} mm) with D = {} mm: {h:.4} mm",
                    class.name(),
                    material.coefficients.ktc,
                    shape_factor(tool.shape),
                    tool.diameter
                ),
            )
        }
    };
    let force = force_rule(tool);
    ToolGuards {
        max_chip_thickness: chip,
        chip_source,
        chip_rule: chip_rule_text,
        max_force: force,
        force_source: GuardSource::Rule,
        force_rule: format!(
            "{}, σ_allow = {} MPa / {}: F = σ_allow·π·d_e³/(32·L) with d_e = {:.3} mm, L = {} mm (stick-out): {force:.1} N",
            tool.tool_material.name(),
            tool.tool_material.bending_strength_mpa(),
            BENDING_SAFETY_FACTOR,
            effective_diameter(tool),
            tool.stick_out()
        ),
        material_class: class,
    }
}
