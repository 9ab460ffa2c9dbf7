//! The critical depth per speed: bisection, or a scan to the first loss of stability.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::{SdModel, StabilitySystem, DEFAULT_DEPTH_TOLERANCE_MM, DEFAULT_MAX_DEPTH_MM};
use crate::job::{CancelFlag, NoProgress, Progress};
use crate::physics::{positive, PhysicsError};

/// Depth search of the time-domain methods.
///
/// The default is plain bisection on [0, `max_depth_mm`] (as the reference curves of
/// docs/reference.md were computed). Where the stable region in depth is not one interval (narrow
/// flip-lobe bands below a wider stable zone, found at low immersion and near lobe
/// intersections), bisection can return a boundary above such a band; `scan_step_mm` makes the
/// search scan upwards first and return the first loss of stability (conservative).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchOptions {
    /// Upper end of the search, mm.
    pub max_depth_mm: f64,
    /// `Some(step)`: scan from 0 in steps (mm) to the first unstable depth, then bisect.
    pub scan_step_mm: Option<f64>,
    /// Bisection tolerance, mm.
    pub tolerance_mm: f64,
}

impl Default for SearchOptions {
    fn default() -> Self {
        SearchOptions {
            max_depth_mm: DEFAULT_MAX_DEPTH_MM,
            scan_step_mm: None,
            tolerance_mm: DEFAULT_DEPTH_TOLERANCE_MM,
        }
    }
}

impl SearchOptions {
    /// Scan in `step_mm` steps to the first loss of stability, then bisect.
    pub fn first_loss(step_mm: f64) -> SearchOptions {
        SearchOptions {
            scan_step_mm: Some(step_mm),
            ..SearchOptions::default()
        }
    }
}

impl StabilitySystem {
    /// Full-discretization lobes: the critical depth (mm) at each speed, parallel over speeds.
    pub fn fd_lobes(
        &self,
        rpms: &[f64],
        steps: usize,
        opts: &SearchOptions,
    ) -> Result<Vec<f64>, PhysicsError> {
        self.fd_model(steps)?
            .lobes(rpms, opts, &CancelFlag::new(), &NoProgress)
    }

    /// Semi-discretization lobes: the critical depth (mm) at each speed, parallel over speeds.
    pub fn sd_lobes(
        &self,
        rpms: &[f64],
        steps: usize,
        opts: &SearchOptions,
    ) -> Result<Vec<f64>, PhysicsError> {
        self.sd_model(steps)?
            .lobes(rpms, opts, &CancelFlag::new(), &NoProgress)
    }
}

impl SdModel {
    /// Critical depth (mm) at one speed by bisection to `tolerance_mm` (see [`SearchOptions`]
    /// for the plain and the scanning search); `max_depth_mm` if stable there.
    pub fn critical_depth_mm(&self, rpm: f64, opts: &SearchOptions) -> Result<f64, PhysicsError> {
        self.critical_depth_until(rpm, opts, None)
    }

    /// The critical depth at each speed, parallel over speeds, reporting speeds done and
    /// stopping with [`PhysicsError::Cancelled`] once `cancel` is set.
    pub fn lobes(
        &self,
        rpms: &[f64],
        opts: &SearchOptions,
        cancel: &CancelFlag,
        progress: &dyn Progress,
    ) -> Result<Vec<f64>, PhysicsError> {
        let done = AtomicU64::new(0);
        let total = rpms.len() as u64;
        rpms.par_iter()
            .map(|&rpm| {
                let depth = self.critical_depth_until(rpm, opts, Some(cancel))?;
                progress.report(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                Ok(depth)
            })
            .collect()
    }

    fn critical_depth_until(
        &self,
        rpm: f64,
        opts: &SearchOptions,
        cancel: Option<&CancelFlag>,
    ) -> Result<f64, PhysicsError> {
        positive("rpm", rpm)?;
        positive("max_depth_mm", opts.max_depth_mm)?;
        positive("tolerance_mm", opts.tolerance_mm)?;
        // One depth is one Floquet analysis, the unit of work: cancel is looked at before each.
        let stable = |a: f64| {
            if cancel.is_some_and(CancelFlag::is_cancelled) {
                return Err(PhysicsError::Cancelled);
            }
            self.spectral_radius(rpm, a).map(|r| r < 1.0)
        };
        let (mut lo, mut hi) = match opts.scan_step_mm {
            None => {
                if stable(opts.max_depth_mm)? {
                    return Ok(opts.max_depth_mm);
                }
                (0.0, opts.max_depth_mm)
            }
            Some(step) => {
                positive("scan_step_mm", step)?;
                let mut lo = 0.0;
                let mut hi = None;
                let n_scan = (opts.max_depth_mm / step).ceil().max(1.0) as usize;
                for i in 1..=n_scan {
                    let a = (i as f64 * step).min(opts.max_depth_mm);
                    if stable(a)? {
                        lo = a;
                    } else {
                        hi = Some(a);
                        break;
                    }
                }
                match hi {
                    Some(hi) => (lo, hi),
                    None => return Ok(opts.max_depth_mm),
                }
            }
        };
        while hi - lo > opts.tolerance_mm {
            let mid = 0.5 * (lo + hi);
            if stable(mid)? {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Ok(0.5 * (lo + hi))
    }
}
