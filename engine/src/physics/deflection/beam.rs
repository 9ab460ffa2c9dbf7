//! The tool as a stepped cantilever: clamped at the holder's face, free at the tip, Euler–
//! Bernoulli bending with a section per length (shank, fluted part).
//!
//! Coordinates: s is the distance from the clamp along the axis (s = 0 at the holder's face,
//! s = L at the tip, L the stick-out); the tool frame's z (up from the tip) is L − s.
//!
//! A unit load at s_q bends the beam by (Maxwell–Mohr, integrating the curvature M/EI twice)
//!
//!   C(s_p, s_q) = ∫₀^min(s_p, s_q) (s_p − t)(s_q − t) / EI(t) dt,
//!
//! symmetric in p and q (Maxwell's reciprocity), exact for a piecewise-constant EI. For a
//! point below the load (s_p ≥ s_q) it is affine in s_p: C = a(s_q) + b(s_q)·s_p with
//! b(s_q) the slope at the load and a(s_q) = C(s_q, s_q) − s_q·b(s_q), which is what lets the
//! force model carry the deflection of the lowest cutting point in two weighted sums.

use std::f64::consts::PI;

use crate::tool::Tool;

/// The fluted part's equivalent round section for bending, as a fraction of the cutting
/// diameter: the flutes remove material, the core and the lands still carry the load; 0.8·D
/// is the usual equivalent diameter of 2- to 4-flute end mills (Kops & Vo 1990, the value
/// CutPro-style deflection estimates use).
pub const EFFECTIVE_CORE_RATIO: f64 = 0.8;

/// One length of constant section.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Section {
    from: f64,
    to: f64,
    /// Bending stiffness E·I, N·mm².
    ei: f64,
}

/// A cantilever of sections from the clamp to the tip.
#[derive(Clone, Debug, PartialEq)]
pub struct ToolBeam {
    length: f64,
    sections: Vec<Section>,
    /// Factor on every compliance: 1, or what makes the tip's stiffness a measured one.
    scale: f64,
    /// Where the flutes end (s of the flute root), and the diameters of the section at the
    /// clamp and at the flute root (for the bending stress).
    flute_root: f64,
    clamp_diameter: f64,
    root_diameter: f64,
}

/// What a slice's load contributes, per newton: its distance from the clamp (the moment
/// arm), and (a, b) of the deflection at any point below it (a + b·s), each averaged over the
/// slice's height (the load spread evenly along it).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SliceWeights {
    pub arm: f64,
    pub a: f64,
    pub b: f64,
}

impl ToolBeam {
    /// The tool's beam: a shank of `shank_diameter` from the holder's face to the flutes, the
    /// fluted length at 0.8·D (or the shank, if thinner), E of the tool's material or its own
    /// `young_modulus_gpa`; scaled to `static_stiffness_n_per_um` where measured.
    pub fn of(tool: &Tool) -> ToolBeam {
        let length = tool.stick_out();
        let flutes = tool.flute_length.min(length);
        let core = (EFFECTIVE_CORE_RATIO * tool.diameter).min(tool.shank_diameter());
        let e = tool.young_modulus_mpa();
        let mut steps = Vec::new();
        if length > flutes {
            steps.push((length - flutes, tool.shank_diameter()));
        }
        steps.push((flutes, core));
        let mut beam = ToolBeam::stepped(&steps, e);
        if let Some(k) = tool.static_stiffness {
            beam = beam.with_tip_stiffness(k * 1000.0);
        }
        beam
    }

    /// A beam of lengths (mm) and diameters (mm) from the clamp to the tip, modulus `e`
    /// (N/mm²). The last length is the fluted one (its section is the flute root's).
    pub fn stepped(lengths_and_diameters: &[(f64, f64)], e: f64) -> ToolBeam {
        let mut from = 0.0;
        let mut sections = Vec::with_capacity(lengths_and_diameters.len());
        for &(len, d) in lengths_and_diameters {
            sections.push(Section {
                from,
                to: from + len,
                ei: e * PI * d.powi(4) / 64.0,
            });
            from += len;
        }
        let last = lengths_and_diameters.last().copied().unwrap_or((0.0, 1.0));
        ToolBeam {
            length: from,
            flute_root: from - last.0,
            clamp_diameter: lengths_and_diameters.first().map_or(1.0, |s| s.1),
            root_diameter: last.1,
            sections,
            scale: 1.0,
        }
    }

    /// A uniform beam of `length` and `diameter` (mm), modulus `e` (N/mm²).
    pub fn uniform(length: f64, diameter: f64, e: f64) -> ToolBeam {
        ToolBeam::stepped(&[(length, diameter)], e)
    }

    /// The same beam with its compliances scaled so that the tip's static stiffness is `k`
    /// (N/mm).
    pub fn with_tip_stiffness(mut self, k: f64) -> ToolBeam {
        self.scale = 1.0;
        let c = self.compliance(self.length, self.length);
        if c > 0.0 && k > 0.0 {
            self.scale = 1.0 / (k * c);
        }
        self
    }

    /// The stick-out L, mm.
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Distance from the clamp of the point `z` mm above the tip.
    pub fn s_of(&self, z: f64) -> f64 {
        self.length - z
    }

    /// Deflection at s_p under a unit load at s_q, mm/N.
    pub fn compliance(&self, s_p: f64, s_q: f64) -> f64 {
        let top = s_p.min(s_q).clamp(0.0, self.length);
        let mut c = 0.0;
        for sec in &self.sections {
            if sec.from >= top {
                break;
            }
            let (t0, t1) = (sec.from, sec.to.min(top));
            // ∫ (s_p − t)(s_q − t) dt = s_p·s_q·Δ1 − (s_p + s_q)·Δ2/2 + Δ3/3.
            let d1 = t1 - t0;
            let d2 = t1 * t1 - t0 * t0;
            let d3 = t1.powi(3) - t0.powi(3);
            c += (s_p * s_q * d1 - (s_p + s_q) * d2 / 2.0 + d3 / 3.0) / sec.ei;
        }
        self.scale * c
    }

    /// (a, b) of a unit load at s: the deflection of any point s_p ≥ s is a + b·s_p.
    pub fn below_terms(&self, s: f64) -> (f64, f64) {
        let b = self.compliance(s + 1.0, s) - self.compliance(s, s);
        (self.compliance(s, s) - s * b, b)
    }

    /// The weights of a slice `dz` high centred `z` above the tip, its load spread evenly
    /// along it: Simpson's rule, exact within one section (a is cubic in s, b quadratic).
    pub fn slice_weights(&self, z: f64, dz: f64) -> SliceWeights {
        let s = self.s_of(z);
        let h = 0.5 * dz;
        let (lo, hi) = ((s - h).max(0.0), (s + h).min(self.length));
        let mid = 0.5 * (lo + hi);
        let [w0, w1, w2] = [lo, mid, hi].map(|x| self.below_terms(x));
        SliceWeights {
            arm: mid,
            a: (w0.0 + 4.0 * w1.0 + w2.0) / 6.0,
            b: (w0.1 + 4.0 * w1.1 + w2.1) / 6.0,
        }
    }

    /// Where the flutes end, as s.
    pub fn flute_root(&self) -> f64 {
        self.flute_root
    }

    /// The bending stress σ = M·c/I = 32·M/(π·d³), MPa, of a moment M (N·mm) at the clamp
    /// and at the flute root.
    pub fn clamp_stress(&self, moment: f64) -> f64 {
        32.0 * moment / (PI * self.clamp_diameter.powi(3))
    }

    pub fn root_stress(&self, moment: f64) -> f64 {
        32.0 * moment / (PI * self.root_diameter.powi(3))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tip_load_on_a_uniform_cantilever_is_fl3_over_3ei() {
        let (l, d, e) = (80.0, 10.0, 600_000.0);
        let beam = ToolBeam::uniform(l, d, e);
        let ei = e * PI * d.powi(4) / 64.0;
        let exact = l.powi(3) / (3.0 * ei);
        assert!((beam.compliance(l, l) / exact - 1.0).abs() < 1e-12);
        // Below the load the line is straight: a + b·s.
        let (a, b) = beam.below_terms(50.0);
        let at_tip = 50.0f64.powi(2) * (3.0 * l - 50.0) / (6.0 * ei);
        assert!(((a + b * l) / at_tip - 1.0).abs() < 1e-12);
        // Reciprocity.
        assert_eq!(beam.compliance(30.0, 70.0), beam.compliance(70.0, 30.0));
    }

    #[test]
    fn measured_stiffness_rescales_the_tip() {
        let beam = ToolBeam::uniform(60.0, 8.0, 600_000.0).with_tip_stiffness(2_000.0);
        assert!((beam.compliance(60.0, 60.0) * 2_000.0 - 1.0).abs() < 1e-12);
    }
}
