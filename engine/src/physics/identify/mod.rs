//! Cutting-coefficient identification by the average-force method (Altintas,
//! *Manufacturing Automation*, §2.4): the mean force per revolution of a flat end mill is
//! linear in the feed per tooth c, F̄ = slope·c + intercept, for every axis. A straight-line
//! fit per axis over several feeds gives slopes (cutting coefficients) and intercepts (edge
//! coefficients). The usual set-up is slotting; any known immersion works as long as it
//! separates the coefficients.
//!
//! Forces are the mean forces on the tool in the Engagement frame (x feed, y = z × x, z the
//! tool axis), as in docs/reference.md. A dynamometer under the workpiece measures the
//! reaction: negate its readings.
//!
//! That closed form holds for flat end mills only. [`identify_from_cuts`] takes any cut the
//! force model can evaluate (any tool shape, helix and runout, slot or side cut, several
//! depths and feeds) and the exponential (Kienzle) law too, by least squares on the model's
//! own unit responses ([`lsq`]); [`fit_unit_forces`] is that solve for any other source of
//! unit responses (the simulated lines of a program).

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

pub mod cuts;
pub mod lsq;

pub use cuts::{
    check_cut, identify_from_cuts, steady_cut_engagement, unit_coefficients, IdentificationCut,
    Immersion, MAX_CUTS,
};
pub use lsq::{
    check_set, fit_unit_forces, t_quantile_975, AxisQuality, Estimate, ForceLaw,
    ModelIdentification, UnitForces, MAX_CONDITION, PARAMETER_NAMES,
};

use super::material::CuttingCoefficients;
use super::{finite, PhysicsError};

/// The feed per tooth of a milling test, mm: from 0.1 µm (micro-milling) to 10 mm. A feed
/// outside it is a unit or typing error, and fits to nonsense (feeds of 1e308 gave all-zero
/// coefficients).
pub const FEED_PER_TOOTH_RANGE_MM: (f64, f64) = (1e-4, 10.0);
/// The axial depth of a milling test, mm: from 1 µm to 100 mm (a depth of 1e-300 gave a
/// ktc of 2e304 N/mm²).
pub const DEPTH_RANGE_MM: (f64, f64) = (1e-3, 100.0);
/// The largest mean force component a test can measure, N (a dynamometer's range is
/// kilonewtons; 1e6 N is a unit error).
pub const MAX_FORCE_N: f64 = 1e6;

fn in_range(field: String, v: f64, (lo, hi): (f64, f64), what: &str) -> Result<f64, PhysicsError> {
    finite(field.clone(), v)?;
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(PhysicsError::invalid(
            field,
            format!("{v} mm is not {what} (from {lo} to {hi} mm)"),
        ))
    }
}

/// A test's feed per tooth, mm, within [`FEED_PER_TOOTH_RANGE_MM`].
pub fn check_feed(field: impl Into<String>, v: f64) -> Result<f64, PhysicsError> {
    in_range(
        field.into(),
        v,
        FEED_PER_TOOTH_RANGE_MM,
        "a milling test's feed per tooth",
    )
}

/// A test's axial depth, mm, within [`DEPTH_RANGE_MM`].
pub fn check_depth(field: impl Into<String>, v: f64) -> Result<f64, PhysicsError> {
    in_range(
        field.into(),
        v,
        DEPTH_RANGE_MM,
        "a milling test's axial depth",
    )
}

/// A measured mean force component, N: finite and at most [`MAX_FORCE_N`] either way.
pub fn check_force(field: impl Into<String>, v: f64) -> Result<f64, PhysicsError> {
    let field = field.into();
    finite(field.clone(), v)?;
    if v.abs() <= MAX_FORCE_N {
        Ok(v)
    } else {
        Err(PhysicsError::invalid(
            field,
            format!("{v} N is beyond any cutting test's force (at most {MAX_FORCE_N} N either way): check the unit (N)"),
        ))
    }
}

/// Closed-form mean force (F̄x, F̄y, F̄z) of a flat end mill (zero or any helix: the mean over
/// a revolution does not depend on it) with `flutes` teeth, axial depth `a`, feed per tooth `c`,
/// engaged from `entry` to `exit` (radians, docs/reference.md convention).
pub fn closed_form_mean_force(
    k: &CuttingCoefficients,
    flutes: u32,
    a: f64,
    c: f64,
    entry: f64,
    exit: f64,
) -> [f64; 3] {
    let (q1, q2) = factors(flutes, a);
    let b = Brackets::new(entry, exit);
    [
        q1 * c * (k.ktc * b.cos2 - k.krc * b.two_phi_sin2) + q2 * (-k.kte * b.sin + k.kre * b.cos),
        q1 * c * (k.ktc * b.two_phi_sin2 + k.krc * b.cos2) - q2 * (k.kte * b.cos + k.kre * b.sin),
        -q2 * (-k.kac * c * b.cos + k.kae * b.phi),
    ]
}

fn factors(flutes: u32, a: f64) -> (f64, f64) {
    let n = flutes as f64;
    (n * a / (8.0 * PI), n * a / (2.0 * PI))
}

/// The bracketed terms of the closed form, evaluated from entry to exit.
struct Brackets {
    cos2: f64,
    two_phi_sin2: f64,
    sin: f64,
    cos: f64,
    phi: f64,
}

impl Brackets {
    fn new(st: f64, ex: f64) -> Brackets {
        let e = |f: &dyn Fn(f64) -> f64| f(ex) - f(st);
        Brackets {
            cos2: e(&|p| (2.0 * p).cos()),
            two_phi_sin2: e(&|p| 2.0 * p - (2.0 * p).sin()),
            sin: e(&|p| p.sin()),
            cos: e(&|p| p.cos()),
            phi: ex - st,
        }
    }
}

/// How the identification cuts were made.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct IdentificationSetup {
    pub flutes: u32,
    /// Axial depth of cut, mm.
    pub axial_depth: f64,
    /// Entry and exit immersion angles, rad (slot: 0 and π).
    pub entry: f64,
    pub exit: f64,
}

impl IdentificationSetup {
    /// Full-immersion slotting, the standard test.
    pub fn slot(flutes: u32, axial_depth: f64) -> IdentificationSetup {
        IdentificationSetup {
            flutes,
            axial_depth,
            entry: 0.0,
            exit: PI,
        }
    }

    pub fn validate(&self) -> Result<(), PhysicsError> {
        if self.flutes == 0 || self.flutes > 64 {
            return Err(PhysicsError::invalid(
                "flutes",
                format!("must be between 1 and 64, got {}", self.flutes),
            ));
        }
        check_depth("axial_depth", self.axial_depth)?;
        finite("entry", self.entry)?;
        finite("exit", self.exit)?;
        if !(self.exit > self.entry
            && self.exit - self.entry <= PI + 1e-12
            && self.entry >= -1e-12
            && self.exit <= PI + 1e-12)
        {
            return Err(PhysicsError::invalid("exit", "need 0 ≤ entry < exit ≤ π"));
        }
        Ok(())
    }
}

/// Mean forces measured at one feed per tooth, N (forces on the tool, Engagement frame).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ForceMeasurement {
    /// mm.
    pub feed_per_tooth: f64,
    pub fx: f64,
    pub fy: f64,
    pub fz: f64,
}

/// Straight-line fit F̄ = slope·c + intercept of one axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisFit {
    /// N/mm.
    pub slope: f64,
    /// N.
    pub intercept: f64,
    /// Coefficient of determination (1 when the line explains all variation, also when
    /// there is none to explain).
    pub r_squared: f64,
    /// Root-mean-square residual, N.
    pub rms_residual: f64,
    /// Measured minus fitted, per measurement in input order, N.
    pub residuals: Vec<f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Identification {
    pub coefficients: CuttingCoefficients,
    pub fit_x: AxisFit,
    pub fit_y: AxisFit,
    pub fit_z: AxisFit,
    /// Number of distinct feeds used.
    pub distinct_feeds: usize,
}

/// Identifies the six coefficients from mean forces at several feeds per tooth.
pub fn identify_coefficients(
    setup: &IdentificationSetup,
    measurements: &[ForceMeasurement],
) -> Result<Identification, PhysicsError> {
    setup.validate()?;
    for (i, m) in measurements.iter().enumerate() {
        check_feed(
            format!("measurements[{i}].feed_per_tooth"),
            m.feed_per_tooth,
        )?;
        check_force(format!("measurements[{i}].fx"), m.fx)?;
        check_force(format!("measurements[{i}].fy"), m.fy)?;
        check_force(format!("measurements[{i}].fz"), m.fz)?;
    }
    let mut feeds: Vec<f64> = measurements.iter().map(|m| m.feed_per_tooth).collect();
    feeds.sort_by(f64::total_cmp);
    feeds.dedup_by(|a, b| (*a - *b).abs() <= 1e-12 * b.abs().max(1e-9));
    if feeds.len() < 2 {
        return Err(PhysicsError::TooFewFeeds {
            distinct: feeds.len(),
        });
    }
    let c: Vec<f64> = measurements.iter().map(|m| m.feed_per_tooth).collect();
    let fit = |f: Vec<f64>| fit_line(&c, &f);
    let fit_x = fit(measurements.iter().map(|m| m.fx).collect());
    let fit_y = fit(measurements.iter().map(|m| m.fy).collect());
    let fit_z = fit(measurements.iter().map(|m| m.fz).collect());

    let (q1, q2) = factors(setup.flutes, setup.axial_depth);
    let b = Brackets::new(setup.entry, setup.exit);
    let unident = |what| PhysicsError::Unidentifiable {
        what,
        entry_rad: setup.entry,
        exit_rad: setup.exit,
    };
    // Slopes: q1·(Ktc·A − Krc·B) and q1·(Ktc·B + Krc·A), with A = [cos 2φ], B = [2φ − sin 2φ].
    let d1 = b.cos2 * b.cos2 + b.two_phi_sin2 * b.two_phi_sin2;
    // Intercepts: q2·(−Kte·S + Kre·C) and −q2·(Kte·C + Kre·S), with S = [sin φ], C = [cos φ].
    let d2 = b.sin * b.sin + b.cos * b.cos;
    if d1 < 1e-12 {
        return Err(unident("tangential/radial cutting"));
    }
    if d2 < 1e-12 {
        return Err(unident("tangential/radial edge"));
    }
    if b.cos.abs() < 1e-9 {
        return Err(unident("axial cutting"));
    }
    let (x, y) = (fit_x.slope / q1, fit_y.slope / q1);
    let (p, q) = (fit_x.intercept / q2, -fit_y.intercept / q2);
    let coefficients = CuttingCoefficients {
        mtc: 0.0,
        mrc: 0.0,
        mac: 0.0,
        ktc: (x * b.cos2 + y * b.two_phi_sin2) / d1,
        krc: (y * b.cos2 - x * b.two_phi_sin2) / d1,
        kac: fit_z.slope / (q2 * b.cos),
        kte: (q * b.cos - p * b.sin) / d2,
        kre: (p * b.cos + q * b.sin) / d2,
        kae: -fit_z.intercept / (q2 * b.phi),
    };
    coefficients.validate()?;
    Ok(Identification {
        coefficients,
        fit_x,
        fit_y,
        fit_z,
        distinct_feeds: feeds.len(),
    })
}

/// Ordinary least squares with intercept. Needs at least two distinct x (checked above).
fn fit_line(x: &[f64], y: &[f64]) -> AxisFit {
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let sxx: f64 = x.iter().map(|v| (v - mx) * (v - mx)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let residuals: Vec<f64> = x
        .iter()
        .zip(y)
        .map(|(a, b)| b - (slope * a + intercept))
        .collect();
    let ss_res: f64 = residuals.iter().map(|r| r * r).sum();
    let ss_tot: f64 = y.iter().map(|v| (v - my) * (v - my)).sum();
    AxisFit {
        slope,
        intercept,
        r_squared: if ss_tot > 0.0 {
            1.0 - ss_res / ss_tot
        } else {
            1.0
        },
        rms_residual: (ss_res / n).sqrt(),
        residuals,
    }
}
