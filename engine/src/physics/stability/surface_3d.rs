//! 3-D lobes: the lobe curve as the workpiece's modes change with the remaining allowance.

use serde::{Deserialize, Serialize};

use super::{compute_lobes_with, DepthSearch, Method, Milling, Mode, RpmRange, StabilityInput};
use crate::job::{CancelFlag, NoProgress, Progress};
use crate::physics::{finite, PhysicsError};

/// Workpiece (or tool) modes measured or computed at one remaining allowance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AllowanceModes {
    /// Remaining material thickness, mm.
    pub allowance_mm: f64,
    #[serde(default)]
    pub modes_x: Vec<Mode>,
    #[serde(default)]
    pub modes_y: Vec<Mode>,
}

/// Input of 3-D lobes: the lobe curve as the workpiece's modes change with the remaining
/// allowance. The fields of [`StabilityInput`] (its `modes_x`/`modes_y` are the tool's,
/// constant, possibly empty) plus `allowance` (the workpiece modes at several allowances;
/// every entry lists the same number of modes per direction, in the same order) and
/// `allowances_mm` (where to evaluate).
///
/// At an allowance the workpiece modes are interpolated linearly in allowance between the
/// two nearest given points, mode by mode: frequency, damping ratio and stiffness (a mode
/// given by mass is converted to stiffness first). The relative FRF of tool and workpiece
/// is the sum of both: the system has the tool's modes followed by the workpiece's.
/// Allowances outside the given points are an error (no extrapolation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stability3dInput {
    pub method: Method,
    pub teeth: u32,
    pub ktc_n_mm2: f64,
    pub krc_n_mm2: f64,
    pub radial_immersion: f64,
    pub milling: Milling,
    /// Tool modes (constant).
    #[serde(default)]
    pub modes_x: Vec<Mode>,
    #[serde(default)]
    pub modes_y: Vec<Mode>,
    pub rpm: RpmRange,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps_per_period: Option<u32>,
    #[serde(default, skip_serializing_if = "DepthSearch::is_bisection")]
    pub search: DepthSearch,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scan_step_mm: Option<f64>,
    /// Workpiece modes at given allowances (at least one).
    pub allowance: Vec<AllowanceModes>,
    /// Allowances at which to compute the lobe curve, mm.
    pub allowances_mm: Vec<f64>,
}

/// One point of a 3-D lobe surface.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LobeSurfacePoint {
    pub allowance_mm: f64,
    pub rpm: f64,
    /// Critical axial depth, mm.
    pub depth_mm: f64,
}

/// Critical depth over spindle speed × allowance: rows by allowance (in the order asked),
/// then by speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LobeSurface {
    pub method: Method,
    pub rows: Vec<LobeSurfacePoint>,
}

impl LobeSurface {
    /// `allowance_mm,rpm,depth_mm` CSV.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("allowance_mm,rpm,depth_mm\n");
        for p in &self.rows {
            s.push_str(&format!("{},{},{:.5}\n", p.allowance_mm, p.rpm, p.depth_mm));
        }
        s
    }
}

fn lerp_mode(a: &Mode, b: &Mode, t: f64) -> Mode {
    let l = |x: f64, y: f64| x + (y - x) * t;
    Mode::with_stiffness(
        l(a.freq_hz, b.freq_hz),
        l(a.damping, b.damping),
        l(a.stiffness(), b.stiffness()),
    )
}

impl Stability3dInput {
    /// Checks every field; the error names the offending one (`allowance[1].modes_x[0].freq_hz`,
    /// `allowances_mm[2]`, …).
    pub fn validate(&self) -> Result<(), PhysicsError> {
        if self.allowance.is_empty() {
            return Err(PhysicsError::invalid("allowance", "must not be empty"));
        }
        if self.allowances_mm.is_empty() {
            return Err(PhysicsError::invalid("allowances_mm", "must not be empty"));
        }
        let (nx, ny) = (
            self.allowance[0].modes_x.len(),
            self.allowance[0].modes_y.len(),
        );
        for (i, p) in self.allowance.iter().enumerate() {
            non_negative_field(&format!("allowance[{i}].allowance_mm"), p.allowance_mm)?;
            for (j, m) in p.modes_x.iter().enumerate() {
                m.validate(&format!("allowance[{i}].modes_x[{j}]"))?;
            }
            for (j, m) in p.modes_y.iter().enumerate() {
                m.validate(&format!("allowance[{i}].modes_y[{j}]"))?;
            }
            if p.modes_x.len() != nx || p.modes_y.len() != ny {
                return Err(PhysicsError::invalid(
                    format!("allowance[{i}]"),
                    format!(
                        "has {}+{} modes, allowance[0] has {nx}+{ny}: every entry needs the same modes",
                        p.modes_x.len(),
                        p.modes_y.len()
                    ),
                ));
            }
            if i > 0
                && self.allowance[..i]
                    .iter()
                    .any(|q| q.allowance_mm == p.allowance_mm)
            {
                return Err(PhysicsError::invalid(
                    format!("allowance[{i}].allowance_mm"),
                    "is given twice",
                ));
            }
        }
        for i in 0..self.allowances_mm.len() {
            self.modes_at(self.allowances_mm[i]).map_err(|_| {
                PhysicsError::invalid(
                    format!("allowances_mm[{i}]"),
                    format!(
                        "{} mm is outside the allowances the modes are given at",
                        self.allowances_mm[i]
                    ),
                )
            })?;
        }
        self.input_at(self.allowances_mm[0])?.validate()
    }

    /// The workpiece modes (x, y) at `allowance_mm`, interpolated.
    pub fn modes_at(&self, allowance_mm: f64) -> Result<(Vec<Mode>, Vec<Mode>), PhysicsError> {
        finite("allowance_mm", allowance_mm)?;
        let mut pts: Vec<&AllowanceModes> = self.allowance.iter().collect();
        pts.sort_by(|a, b| a.allowance_mm.total_cmp(&b.allowance_mm));
        let (first, last) = (pts[0], pts[pts.len() - 1]);
        if allowance_mm < first.allowance_mm || allowance_mm > last.allowance_mm {
            return Err(PhysicsError::invalid(
                "allowance_mm",
                format!(
                    "{allowance_mm} mm is outside [{}, {}] mm",
                    first.allowance_mm, last.allowance_mm
                ),
            ));
        }
        if let Some(p) = pts.iter().find(|p| p.allowance_mm == allowance_mm) {
            return Ok((p.modes_x.clone(), p.modes_y.clone()));
        }
        let j = pts.partition_point(|p| p.allowance_mm < allowance_mm);
        let (a, b) = (pts[j - 1], pts[j]);
        let t = (allowance_mm - a.allowance_mm) / (b.allowance_mm - a.allowance_mm);
        let mix = |ma: &[Mode], mb: &[Mode]| -> Vec<Mode> {
            ma.iter().zip(mb).map(|(x, y)| lerp_mode(x, y, t)).collect()
        };
        Ok((mix(&a.modes_x, &b.modes_x), mix(&a.modes_y, &b.modes_y)))
    }

    /// The 2-D input at one allowance: tool modes followed by the interpolated workpiece ones.
    pub fn input_at(&self, allowance_mm: f64) -> Result<StabilityInput, PhysicsError> {
        let (wx, wy) = self.modes_at(allowance_mm)?;
        let mut modes_x = self.modes_x.clone();
        modes_x.extend(wx);
        let mut modes_y = self.modes_y.clone();
        modes_y.extend(wy);
        Ok(StabilityInput {
            method: self.method,
            teeth: self.teeth,
            ktc_n_mm2: self.ktc_n_mm2,
            krc_n_mm2: self.krc_n_mm2,
            radial_immersion: self.radial_immersion,
            milling: self.milling,
            modes_x,
            modes_y,
            rpm: self.rpm,
            steps_per_period: self.steps_per_period,
            search: self.search,
            scan_step_mm: self.scan_step_mm,
        })
    }
}

fn non_negative_field(field: &str, v: f64) -> Result<(), PhysicsError> {
    crate::physics::non_negative(field, v).map(|_| ())
}

/// The lobe curve at every requested allowance ([`compute_lobes`](super::compute_lobes) of
/// [`Stability3dInput::input_at`]): a surface rpm × allowance → critical depth.
pub fn compute_lobes_3d(input: &Stability3dInput) -> Result<LobeSurface, PhysicsError> {
    compute_lobes_3d_with(input, &CancelFlag::new(), &NoProgress)
}

/// [`compute_lobes_3d`] for a job: reports allowances done and stops once `cancel` is set.
pub fn compute_lobes_3d_with(
    input: &Stability3dInput,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<LobeSurface, PhysicsError> {
    input.validate()?;
    let mut rows = Vec::new();
    let total = input.allowances_mm.len() as u64;
    for (i, &a) in input.allowances_mm.iter().enumerate() {
        progress.report(i as u64, total);
        let curve = compute_lobes_with(&input.input_at(a)?, cancel, &NoProgress)?;
        rows.extend(curve.points.iter().map(|p| LobeSurfacePoint {
            allowance_mm: a,
            rpm: p.rpm,
            depth_mm: p.depth_mm,
        }));
    }
    Ok(LobeSurface {
        method: input.method,
        rows,
    })
}
