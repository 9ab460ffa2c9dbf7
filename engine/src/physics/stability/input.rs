//! The JSON input of the `stability` job: method, milling direction, speed grid, depth search.

use serde::{Deserialize, Serialize};

use super::{Mode, SearchOptions, StabilitySystem};
use crate::physics::{positive, PhysicsError};

/// Lobe computation method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Zero-order approximation (Altintas–Budak).
    Zoa,
    /// First-order semi-discretization (Insperger–Stépán).
    Sdm,
    /// First-order full discretization (Ding et al. 2010).
    Fdm,
}

/// Milling direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Milling {
    Down,
    Up,
}

/// Spindle speed grid, rpm: `from`, `from + step`, … up to `to` inclusive.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RpmRange {
    pub from: f64,
    pub to: f64,
    pub step: f64,
}

impl RpmRange {
    /// The speeds of the grid.
    pub fn speeds(&self) -> Vec<f64> {
        let n = ((self.to - self.from) / self.step + 1e-9).floor() as usize;
        (0..=n).map(|i| self.from + i as f64 * self.step).collect()
    }

    fn validate(&self) -> Result<(), PhysicsError> {
        positive("rpm.from", self.from)?;
        positive("rpm.to", self.to)?;
        positive("rpm.step", self.step)?;
        if self.to < self.from {
            return Err(PhysicsError::invalid(
                "rpm.to",
                format!(
                    "must not be below rpm.from ({}), got {}",
                    self.from, self.to
                ),
            ));
        }
        if (self.to - self.from) / self.step > 100_000.0 {
            return Err(PhysicsError::invalid(
                "rpm.step",
                "gives more than 100000 speeds",
            ));
        }
        Ok(())
    }
}

/// Input of the `stability` job and of `millsim stability INPUT.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StabilityInput {
    pub method: Method,
    pub teeth: u32,
    /// Tangential cutting coefficient, N/mm².
    pub ktc_n_mm2: f64,
    /// Radial cutting coefficient, N/mm².
    pub krc_n_mm2: f64,
    /// Radial immersion aD = ae/D, 0 < aD ≤ 1.
    pub radial_immersion: f64,
    pub milling: Milling,
    #[serde(default)]
    pub modes_x: Vec<Mode>,
    #[serde(default)]
    pub modes_y: Vec<Mode>,
    pub rpm: RpmRange,
    /// Semi-discretization steps per tooth period (default 40; ignored by `zoa`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps_per_period: Option<u32>,
    /// Depth search of `sdm`/`fdm`: `"bisection"` (default, as the reference curves) or
    /// `"first_loss"` (conservative scan to the first loss of stability); see
    /// [`SearchOptions`]. Ignored by `zoa`.
    #[serde(default, skip_serializing_if = "DepthSearch::is_bisection")]
    pub search: DepthSearch,
    /// Scan step of `"first_loss"`, mm (default [`DEFAULT_SCAN_STEP_MM`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scan_step_mm: Option<f64>,
}

/// Scan step of the `"first_loss"` depth search when the input gives none, mm.
pub const DEFAULT_SCAN_STEP_MM: f64 = 0.1;

/// The depth search as the JSON inputs name it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthSearch {
    /// Plain bisection on [0, max depth] (the reference curves' search).
    #[default]
    Bisection,
    /// Scan upwards to the first unstable depth, then bisect ([`SearchOptions::first_loss`]).
    FirstLoss,
}

impl DepthSearch {
    pub(super) fn is_bisection(&self) -> bool {
        *self == DepthSearch::Bisection
    }

    /// The search options (scan step `scan_step_mm`, default [`DEFAULT_SCAN_STEP_MM`]).
    pub fn options(self, scan_step_mm: Option<f64>) -> SearchOptions {
        match self {
            DepthSearch::Bisection => SearchOptions::default(),
            DepthSearch::FirstLoss => {
                SearchOptions::first_loss(scan_step_mm.unwrap_or(DEFAULT_SCAN_STEP_MM))
            }
        }
    }
}

impl StabilityInput {
    /// Checks every field; the error names the offending one.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        self.rpm.validate()?;
        if let Some(k) = self.steps_per_period {
            if !(4..=400).contains(&k) {
                return Err(PhysicsError::invalid(
                    "steps_per_period",
                    format!("must be within 4..=400, got {k}"),
                ));
            }
        }
        if let Some(step) = self.scan_step_mm {
            positive("scan_step_mm", step)?;
        }
        self.system().map(|_| ())
    }

    /// The depth search the input asks for.
    pub fn search_options(&self) -> SearchOptions {
        self.search.options(self.scan_step_mm)
    }

    /// The mechanical system described by the input.
    pub fn system(&self) -> Result<StabilitySystem, PhysicsError> {
        StabilitySystem::new(
            self.teeth,
            self.ktc_n_mm2,
            self.krc_n_mm2,
            self.radial_immersion,
            self.milling,
            self.modes_x.clone(),
            self.modes_y.clone(),
        )
    }
}
