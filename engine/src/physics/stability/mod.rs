//! Chatter stability of milling: stability lobes (critical axial depth per spindle speed).
//!
//! Conventions follow the rest of [`crate::physics`]: x is the feed direction, φ is measured
//! clockwise from +y, a tooth at angle φ cuts the chip h = (fz + Δx)·sin φ + Δy·cos φ, and the
//! tangential/radial forces are Ft = Ktc·a·h, Fr = Krc·a·h. The regenerative force on the tool is
//! F(t) = −a·H(t)·(r(t) − r(t − τ)) with τ the tooth period and
//!
//! ```text
//! H(φ) = [ sinφ(Kt cosφ + Kn sinφ)    cosφ(Kt cosφ + Kn sinφ) ]
//!        [ sinφ(−Kt sinφ + Kn cosφ)   cosφ(−Kt sinφ + Kn cosφ) ]
//! ```
//!
//! summed over the teeth inside the immersion (down milling: φ from acos(2·aD − 1) to π; up
//! milling: φ from 0 to acos(1 − 2·aD)).
//!
//! The tool's flexibility is a sum of modes in x and y ([`Mode`]: natural frequency, damping
//! ratio, stiffness or mass); an empty list makes that direction rigid.
//!
//! Methods:
//! - [`StabilitySystem::zoa_lobes`]: zero-order approximation (Altintas–Budak 1995) with the
//!   time-averaged H, multi-mode FRFs, lobes k = 0, 1, … and the critical depth per speed as the
//!   minimum over all lobes crossing that speed; [`StabilitySystem::zoa_absolute_limit_mm`].
//! - [`StabilitySystem::sd_lobes`]: first-order semi-discretization (Insperger & Stépán) in modal
//!   coordinates (any number of x and y modes), Floquet multipliers of the one-period transition
//!   matrix by nalgebra's Schur decomposition (iteration cap), critical depth by a scan and
//!   bisection on depth, parallel over speeds (rayon; results do not depend on the scheduling).
//! - [`StabilitySystem::fd_lobes`]: first-order full discretization (Ding et al. 2010), same
//!   state, Floquet analysis and depth search.
//! - [`recommend_spindle_speed`]: the centre of the widest stable pocket near a requested speed.
//!
//! The JSON input of the `stability` job and of `millsim stability` is [`StabilityInput`];
//! [`compute_lobes`] runs it.
//!
//! Files, one per computation: `mode` (a mode's FRF), `input` (the job's JSON), `system`
//! (teeth, coefficients, immersion, H(φ)), `zoa`, `discretization` (semi and full, the
//! transition matrix), `floquet` (its spectral radius), `depth_search` (critical depth per
//! speed), `recommend` (speed pockets), `surface_3d` (lobes over the remaining allowance).

mod depth_search;
mod discretization;
mod floquet;
mod input;
mod mode;
mod recommend;
mod surface_3d;
mod system;
mod zoa;

pub use depth_search::SearchOptions;
pub use discretization::SdModel;
pub use input::{DepthSearch, Method, Milling, RpmRange, StabilityInput, DEFAULT_SCAN_STEP_MM};
pub use mode::Mode;
pub use recommend::{interpolate, recommend_spindle_speed, SpeedRecommendation};
pub use surface_3d::{
    compute_lobes_3d, compute_lobes_3d_with, AllowanceModes, LobeSurface, LobeSurfacePoint,
    Stability3dInput,
};
pub use system::StabilitySystem;

use serde::{Deserialize, Serialize};

use super::PhysicsError;
use crate::job::{CancelFlag, NoProgress, Progress};

/// Depth up to which lobes are searched (mm); speeds stable at this depth report it. The
/// reference curves of the benchmark reach 12.9 mm at low immersion, so 10 mm is too low; the
/// bracket [0, 16] mm also decides which stability boundary plain bisection lands on where the
/// stable depths are not one interval (see [`SearchOptions`]), and with it the bisection
/// reproduces every reference point from 10,000 to 25,000 rpm.
pub const DEFAULT_MAX_DEPTH_MM: f64 = 16.0;
/// Bisection tolerance on the critical depth (mm).
pub const DEFAULT_DEPTH_TOLERANCE_MM: f64 = 1e-4;
/// Default number of semi-discretization steps per tooth period.
pub const DEFAULT_STEPS_PER_PERIOD: u32 = 40;

/// One point of a lobe diagram.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LobePoint {
    pub rpm: f64,
    /// Critical axial depth, mm (capped at the search limit).
    pub depth_mm: f64,
}

/// A lobe diagram: critical depth per spindle speed, speeds increasing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LobeCurve {
    pub method: Method,
    pub points: Vec<LobePoint>,
}

impl LobeCurve {
    /// `rpm,depth_mm` CSV, one line per speed.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("rpm,depth_mm\n");
        for p in &self.points {
            s.push_str(&format!("{},{:.5}\n", p.rpm, p.depth_mm));
        }
        s
    }

    /// The lowest critical depth and its speed.
    pub fn minimum(&self) -> Option<LobePoint> {
        self.points
            .iter()
            .copied()
            .min_by(|a, b| a.depth_mm.total_cmp(&b.depth_mm))
    }
}

/// Runs the input: validation, then the chosen method over the speed grid.
pub fn compute_lobes(input: &StabilityInput) -> Result<LobeCurve, PhysicsError> {
    compute_lobes_with(input, &CancelFlag::new(), &NoProgress)
}

/// [`compute_lobes`] for a job: reports speeds done, and stops with
/// [`PhysicsError::Cancelled`] soon after `cancel` is set (the time-domain methods look at it
/// before every depth they test; the zero-order method is closed-form and short).
pub fn compute_lobes_with(
    input: &StabilityInput,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<LobeCurve, PhysicsError> {
    input.validate()?;
    let sys = input.system()?;
    let rpms = input.rpm.speeds();
    let steps = input.steps_per_period.unwrap_or(DEFAULT_STEPS_PER_PERIOD) as usize;
    let depths = match input.method {
        Method::Zoa => sys.zoa_lobes(&rpms, DEFAULT_MAX_DEPTH_MM),
        Method::Sdm => {
            sys.sd_model(steps)?
                .lobes(&rpms, &input.search_options(), cancel, progress)?
        }
        Method::Fdm => {
            sys.fd_model(steps)?
                .lobes(&rpms, &input.search_options(), cancel, progress)?
        }
    };
    if cancel.is_cancelled() {
        return Err(PhysicsError::Cancelled);
    }
    progress.report(rpms.len() as u64, rpms.len() as u64);
    Ok(LobeCurve {
        method: input.method,
        points: rpms
            .into_iter()
            .zip(depths)
            .map(|(rpm, depth_mm)| LobePoint { rpm, depth_mm })
            .collect(),
    })
}
