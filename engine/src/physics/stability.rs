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

use std::f64::consts::PI;

use nalgebra::{Complex, DMatrix};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{finite, positive, PhysicsError};
use crate::job::{CancelFlag, NoProgress, Progress};
use std::sync::atomic::{AtomicU64, Ordering};

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
/// Iteration cap of the Schur decomposition, per matrix row.
const SCHUR_ITERATIONS_PER_ROW: usize = 200;

/// One vibration mode of the tool (or workpiece) in one direction. Give exactly one of
/// `stiffness_n_m` and `mass_kg` (modal mass; stiffness = m·(2π·f)²).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mode {
    pub freq_hz: f64,
    /// Damping ratio ζ (0 < ζ < 1).
    pub damping: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_n_m: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_kg: Option<f64>,
}

impl Mode {
    /// A mode given by frequency, damping ratio and stiffness.
    pub fn with_stiffness(freq_hz: f64, damping: f64, stiffness_n_m: f64) -> Mode {
        Mode {
            freq_hz,
            damping,
            stiffness_n_m: Some(stiffness_n_m),
            mass_kg: None,
        }
    }

    /// A mode given by frequency, damping ratio and modal mass.
    pub fn with_mass(freq_hz: f64, damping: f64, mass_kg: f64) -> Mode {
        Mode {
            freq_hz,
            damping,
            stiffness_n_m: None,
            mass_kg: Some(mass_kg),
        }
    }

    /// Natural angular frequency, rad/s.
    pub fn omega(&self) -> f64 {
        2.0 * PI * self.freq_hz
    }

    /// Modal stiffness, N/m.
    pub fn stiffness(&self) -> f64 {
        match (self.stiffness_n_m, self.mass_kg) {
            (Some(k), _) => k,
            (None, Some(m)) => m * self.omega() * self.omega(),
            (None, None) => f64::NAN,
        }
    }

    /// Modal mass, kg.
    pub fn mass(&self) -> f64 {
        self.stiffness() / (self.omega() * self.omega())
    }

    /// Receptance (m/N) at angular frequency `w` (rad/s).
    pub fn frf(&self, w: f64) -> Complex<f64> {
        let r = w / self.omega();
        Complex::new(1.0 - r * r, 2.0 * self.damping * r).inv() / self.stiffness()
    }

    fn validate(&self, field: &str) -> Result<(), PhysicsError> {
        positive(format!("{field}.freq_hz"), self.freq_hz)?;
        positive(format!("{field}.damping"), self.damping)?;
        if self.damping >= 1.0 {
            return Err(PhysicsError::invalid(
                format!("{field}.damping"),
                format!("must be below 1 (a damping ratio), got {}", self.damping),
            ));
        }
        match (self.stiffness_n_m, self.mass_kg) {
            (Some(k), None) => positive(format!("{field}.stiffness_n_m"), k).map(|_| ()),
            (None, Some(m)) => positive(format!("{field}.mass_kg"), m).map(|_| ()),
            (Some(_), Some(_)) => Err(PhysicsError::invalid(
                format!("{field}.stiffness_n_m"),
                "give either stiffness_n_m or mass_kg, not both",
            )),
            (None, None) => Err(PhysicsError::invalid(
                format!("{field}.stiffness_n_m"),
                "missing: give stiffness_n_m or mass_kg",
            )),
        }
    }
}

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
    fn is_bisection(&self) -> bool {
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

/// Depth search of the time-domain methods.
///
/// The default is plain bisection on [0, `max_depth_mm`] (as the reference curves of
/// REFERENCE.md were computed). Where the stable region in depth is not one interval (narrow
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

/// Teeth, cutting coefficients, immersion and modes: everything the lobes depend on.
#[derive(Debug, Clone, PartialEq)]
pub struct StabilitySystem {
    pub teeth: u32,
    /// Tangential coefficient, N/m².
    pub kt: f64,
    /// Radial (normal) coefficient, N/m².
    pub kn: f64,
    /// Entry and exit angles of the immersion, rad.
    pub phi_entry: f64,
    pub phi_exit: f64,
    pub modes_x: Vec<Mode>,
    pub modes_y: Vec<Mode>,
}

impl StabilitySystem {
    /// Validates and builds the system (coefficients in N/mm², immersion aD = ae/D).
    pub fn new(
        teeth: u32,
        ktc_n_mm2: f64,
        krc_n_mm2: f64,
        radial_immersion: f64,
        milling: Milling,
        modes_x: Vec<Mode>,
        modes_y: Vec<Mode>,
    ) -> Result<StabilitySystem, PhysicsError> {
        if !(1..=100).contains(&teeth) {
            return Err(PhysicsError::invalid(
                "teeth",
                format!("must be within 1..=100, got {teeth}"),
            ));
        }
        positive("ktc_n_mm2", ktc_n_mm2)?;
        finite("krc_n_mm2", krc_n_mm2)?;
        positive("radial_immersion", radial_immersion)?;
        if radial_immersion > 1.0 {
            return Err(PhysicsError::invalid(
                "radial_immersion",
                format!("must be at most 1 (ae/D), got {radial_immersion}"),
            ));
        }
        for (i, m) in modes_x.iter().enumerate() {
            m.validate(&format!("modes_x[{i}]"))?;
        }
        for (i, m) in modes_y.iter().enumerate() {
            m.validate(&format!("modes_y[{i}]"))?;
        }
        if modes_x.is_empty() && modes_y.is_empty() {
            return Err(PhysicsError::invalid(
                "modes_x",
                "modes_x and modes_y are both empty: a rigid tool has no lobes",
            ));
        }
        let (phi_entry, phi_exit) = match milling {
            Milling::Down => ((2.0 * radial_immersion - 1.0).clamp(-1.0, 1.0).acos(), PI),
            Milling::Up => (0.0, (1.0 - 2.0 * radial_immersion).clamp(-1.0, 1.0).acos()),
        };
        Ok(StabilitySystem {
            teeth,
            kt: ktc_n_mm2 * 1e6,
            kn: krc_n_mm2 * 1e6,
            phi_entry,
            phi_exit,
            modes_x,
            modes_y,
        })
    }

    /// ∫ H(φ) dφ over [a, b] ∩ [entry, exit] (one tooth), N/m²·rad.
    fn h_integral(&self, a: f64, b: f64) -> [[f64; 2]; 2] {
        let lo = a.max(self.phi_entry);
        let hi = b.min(self.phi_exit);
        if hi <= lo {
            return [[0.0; 2]; 2];
        }
        // Antiderivatives of sinφcosφ, sin²φ, cos²φ.
        let sc = |p: f64| 0.5 * p.sin() * p.sin();
        let ss = |p: f64| 0.5 * p - 0.25 * (2.0 * p).sin();
        let cc = |p: f64| 0.5 * p + 0.25 * (2.0 * p).sin();
        let isc = sc(hi) - sc(lo);
        let iss = ss(hi) - ss(lo);
        let icc = cc(hi) - cc(lo);
        let (kt, kn) = (self.kt, self.kn);
        [
            [kt * isc + kn * iss, kt * icc + kn * isc],
            [-kt * iss + kn * isc, -kt * isc + kn * icc],
        ]
    }

    /// Time average of H over a revolution (all teeth), N/m².
    pub fn mean_directional_matrix(&self) -> [[f64; 2]; 2] {
        let h = self.h_integral(0.0, 2.0 * PI);
        let f = self.teeth as f64 / (2.0 * PI);
        [[h[0][0] * f, h[0][1] * f], [h[1][0] * f, h[1][1] * f]]
    }

    fn frf_xy(&self, w: f64) -> (Complex<f64>, Complex<f64>) {
        let sum = |modes: &[Mode]| {
            modes
                .iter()
                .fold(Complex::new(0.0, 0.0), |acc, m| acc + m.frf(w))
        };
        (sum(&self.modes_x), sum(&self.modes_y))
    }

    fn all_modes(&self) -> impl Iterator<Item = (usize, &Mode)> {
        self.modes_x
            .iter()
            .map(|m| (0, m))
            .chain(self.modes_y.iter().map(|m| (1, m)))
    }

    /// Chatter frequency grid of the zero-order method (rad/s), fine enough for the
    /// sharpest resonance.
    fn zoa_frequencies(&self) -> Vec<f64> {
        let (mut lo, mut hi, mut bw) = (f64::INFINITY, 0.0f64, f64::INFINITY);
        for (_, m) in self.all_modes() {
            lo = lo.min(m.omega());
            hi = hi.max(m.omega());
            bw = bw.min(m.damping * m.omega());
        }
        let (lo, hi) = (0.2 * lo, 4.0 * hi);
        let n = (((hi - lo) / (bw / 40.0)) as usize).clamp(4000, 400_000);
        (0..=n)
            .map(|i| lo + (hi - lo) * i as f64 / n as f64)
            .collect()
    }

    /// Eigenvalues of G(iω)·H̄ with a negative real part: (λ, a_lim in m, phase ε in rad).
    fn zoa_eigen(&self, w: f64, hbar: &[[f64; 2]; 2]) -> [Option<(f64, f64)>; 2] {
        let (gx, gy) = self.frf_xy(w);
        // M = diag(gx, gy) · H̄
        let m00 = gx * hbar[0][0];
        let m01 = gx * hbar[0][1];
        let m10 = gy * hbar[1][0];
        let m11 = gy * hbar[1][1];
        let half_tr = (m00 + m11) * 0.5;
        let det = m00 * m11 - m01 * m10;
        let root = (half_tr * half_tr - det).sqrt();
        let mut lams = [half_tr - root, half_tr + root];
        lams.sort_by(|a, b| a.re.total_cmp(&b.re));
        lams.map(|lam| {
            if lam.re < 0.0 && lam.norm() > 0.0 {
                let a = -0.5 / lam.re;
                let p = -lam.inv();
                let psi = p.im.atan2(p.re);
                Some((a, PI - 2.0 * psi))
            } else {
                None
            }
        })
    }

    /// Zero-order absolute stability limit (the lowest depth over all speeds), mm.
    pub fn zoa_absolute_limit_mm(&self) -> f64 {
        let hbar = self.mean_directional_matrix();
        let mut best = f64::INFINITY;
        for w in self.zoa_frequencies() {
            for (a, _) in self.zoa_eigen(w, &hbar).into_iter().flatten() {
                best = best.min(a);
            }
        }
        best * 1e3
    }

    /// Zero-order lobes: the critical depth (mm, at most `max_depth_mm`) at each speed, the
    /// minimum over every lobe k = 0, 1, … of every eigenvalue branch crossing that speed.
    pub fn zoa_lobes(&self, rpms: &[f64], max_depth_mm: f64) -> Vec<f64> {
        let hbar = self.mean_directional_matrix();
        let n_teeth = self.teeth as f64;
        let ws = self.zoa_frequencies();
        let eig: Vec<[Option<(f64, f64)>; 2]> =
            ws.iter().map(|&w| self.zoa_eigen(w, &hbar)).collect();
        let rpm_min = rpms.iter().copied().fold(f64::INFINITY, f64::min);
        let mut order: Vec<usize> = (0..rpms.len()).collect();
        order.sort_by(|&a, &b| rpms[a].total_cmp(&rpms[b]));
        let sorted: Vec<f64> = order.iter().map(|&i| rpms[i]).collect();
        let mut best = vec![max_depth_mm * 1e-3; rpms.len()];
        let speed = |w: f64, eps: f64, k: usize| 60.0 * w / (n_teeth * (eps + 2.0 * PI * k as f64));
        for k in 0.. {
            let mut any = false;
            for branch in [0usize, 1] {
                for s in 1..ws.len() {
                    let (Some((a0, e0)), Some((a1, e1))) = (eig[s - 1][branch], eig[s][branch])
                    else {
                        continue;
                    };
                    let n0 = speed(ws[s - 1], e0, k);
                    let n1 = speed(ws[s], e1, k);
                    if n0.max(n1) >= rpm_min {
                        any = true;
                    }
                    let (lo, hi) = (n0.min(n1), n0.max(n1));
                    let start = sorted.partition_point(|&r| r < lo);
                    for (j, &r) in sorted.iter().enumerate().skip(start) {
                        if r > hi {
                            break;
                        }
                        let t = if hi > lo { (r - n0) / (n1 - n0) } else { 0.0 };
                        let a = a0 + (a1 - a0) * t;
                        let idx = order[j];
                        if a < best[idx] {
                            best[idx] = a;
                        }
                    }
                }
            }
            if !any {
                break;
            }
        }
        best.into_iter().map(|a| a * 1e3).collect()
    }

    /// Semi-discretization model for `steps` steps per tooth period.
    pub fn sd_model(&self, steps: usize) -> Result<SdModel, PhysicsError> {
        SdModel::new(self, steps, false)
    }

    /// Full-discretization model (Ding et al. 2010, first order) for `steps` steps per tooth
    /// period; the same interface as the semi-discretization one.
    pub fn fd_model(&self, steps: usize) -> Result<SdModel, PhysicsError> {
        SdModel::new(self, steps, true)
    }

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

    /// H at one cutter angle (sum over the teeth in the cut), N/m².
    fn h_at(&self, phi: f64) -> [[f64; 2]; 2] {
        let mut h = [[0.0; 2]; 2];
        for j in 0..self.teeth {
            let p = (phi + 2.0 * PI * j as f64 / self.teeth as f64).rem_euclid(2.0 * PI);
            if p >= self.phi_entry && p < self.phi_exit {
                let (sp, cp) = p.sin_cos();
                let t = self.kt * cp + self.kn * sp;
                let r = -self.kt * sp + self.kn * cp;
                h[0][0] += sp * t;
                h[0][1] += cp * t;
                h[1][0] += sp * r;
                h[1][1] += cp * r;
            }
        }
        h
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

/// First-order semi-discretization (Insperger–Stépán: H averaged over each step, the delayed
/// term interpolated linearly) or first-order full discretization (Ding et al. 2010: H sampled
/// at the step ends, both the present and the delayed terms interpolated linearly, one small
/// linear solve per step) of the regenerative milling model in modal coordinates.
/// State per step: modal displacements and velocities z (2·n), and the modal displacements
/// of the last `steps` sampling instants (delay τ = steps·Δt).
#[derive(Debug, Clone)]
pub struct SdModel {
    teeth: usize,
    steps: usize,
    /// Number of modes n.
    n: usize,
    /// Direction (0 = x, 1 = y), ω, ζ, 1/m of every mode.
    modes: Vec<(usize, f64, f64, f64)>,
    /// Semi-discretization: mean of H over each step; full discretization: H at the start
    /// of each step (N/m²).
    h_steps: Vec<[[f64; 2]; 2]>,
    /// Full discretization.
    full: bool,
}

/// Matrices of the uncut system for the full discretization (row-major).
struct FreeBlocks {
    phi0: Vec<f64>,
    v0: Vec<f64>,
    v1: Vec<f64>,
}

/// Per-step matrices: Φ0 (d×d), W1 and W0 (d×n) multiplying q(i−m+1) and q(i−m).
struct StepMaps {
    phi0: Vec<f64>,
    w1: Vec<f64>,
    w0: Vec<f64>,
}

impl SdModel {
    fn new(sys: &StabilitySystem, steps: usize, full: bool) -> Result<SdModel, PhysicsError> {
        if !(4..=400).contains(&steps) {
            return Err(PhysicsError::invalid(
                "steps_per_period",
                format!("must be within 4..=400, got {steps}"),
            ));
        }
        let modes: Vec<(usize, f64, f64, f64)> = sys
            .all_modes()
            .map(|(dir, m)| (dir, m.omega(), m.damping, 1.0 / m.mass()))
            .collect();
        let teeth = sys.teeth as usize;
        let dphi = 2.0 * PI / (teeth * steps) as f64;
        let h_steps = (0..steps)
            .map(|i| {
                if full {
                    return sys.h_at(i as f64 * dphi);
                }
                let mut h = [[0.0; 2]; 2];
                for j in 0..teeth {
                    let a = i as f64 * dphi + 2.0 * PI * j as f64 / teeth as f64;
                    let hj = sys.h_integral(a, a + dphi);
                    for r in 0..2 {
                        for c in 0..2 {
                            h[r][c] += hj[r][c] / dphi;
                        }
                    }
                }
                h
            })
            .collect();
        Ok(SdModel {
            teeth,
            steps,
            n: modes.len(),
            modes,
            h_steps,
            full,
        })
    }

    /// Dimension of the one-period transition matrix.
    pub fn dimension(&self) -> usize {
        2 * self.n + self.steps * self.n
    }

    /// Modal "cutting stiffness" K̃ = a·M⁻¹·Φᵀ·H·Φ (n×n, row-major), depth a in m.
    fn cutting_matrix(&self, h: &[[f64; 2]; 2], a: f64) -> Vec<f64> {
        let n = self.n;
        let mut k = vec![0.0; n * n];
        for (p, &(dp, _, _, inv_m)) in self.modes.iter().enumerate() {
            for (q, &(dq, _, _, _)) in self.modes.iter().enumerate() {
                k[p * n + q] = a * inv_m * h[dp][dq];
            }
        }
        k
    }

    /// exp(G·Δt) of the augmented generator G = [[A, I, 0], [0, 0, I], [0, 0, 0]] with
    /// A = [[0, I], [−Ω² − K̃, −2ZΩ]]: blocks Φ0, Φ1 = ∫e^{A(Δt−s)}ds, Φ2 = ∫e^{A(Δt−s)}s ds.
    fn augmented_exp(&self, kc: &[f64], dt: f64) -> DMatrix<f64> {
        let n = self.n;
        let d = 2 * n;
        // Augmented generator [[A, I, 0], [0, 0, I], [0, 0, 0]]·dt.
        let big = 3 * d;
        let mut g = DMatrix::<f64>::zeros(big, big);
        for p in 0..n {
            let (_, w, z, _) = self.modes[p];
            g[(p, n + p)] = 1.0;
            g[(n + p, p)] -= w * w;
            g[(n + p, n + p)] = -2.0 * z * w;
            for q in 0..n {
                g[(n + p, q)] -= kc[p * n + q];
            }
        }
        for i in 0..d {
            g[(i, d + i)] = 1.0;
            g[(d + i, 2 * d + i)] = 1.0;
        }
        (g * dt).exp()
    }

    fn step_maps(&self, kc: &[f64], dt: f64) -> StepMaps {
        let n = self.n;
        let d = 2 * n;
        let e = self.augmented_exp(kc, dt);
        let mut phi0 = vec![0.0; d * d];
        let mut w1 = vec![0.0; d * n];
        let mut w0 = vec![0.0; d * n];
        for r in 0..d {
            for c in 0..d {
                phi0[r * d + c] = e[(r, c)];
            }
            // B̃ = [[0], [K̃]]: only the velocity columns of Φ1, Φ2 act on it.
            for q in 0..n {
                let mut s1 = 0.0;
                let mut s0 = 0.0;
                for p in 0..n {
                    let phi1 = e[(r, d + n + p)];
                    let phi2 = e[(r, 2 * d + n + p)] / dt;
                    s1 += phi2 * kc[p * n + q];
                    s0 += (phi1 - phi2) * kc[p * n + q];
                }
                w1[r * n + q] = s1;
                w0[r * n + q] = s0;
            }
        }
        StepMaps { phi0, w1, w0 }
    }

    /// Full-discretization step from t_k to t_k+1 with cutting matrices K̃k, K̃k+1 and the free
    /// matrices: (I + V1·K̃k+1·E)·z_k+1 = (Φ0 − V0·K̃k·E)·z_k + V1·K̃k+1·q_k+1−m + V0·K̃k·q_k−m,
    /// E selecting the displacements, V0 = (Φ1 − Φ2/Δt)·[0; I], V1 = (Φ2/Δt)·[0; I].
    fn fd_step_maps(&self, free: &FreeBlocks, k0: &[f64], k1: &[f64]) -> StepMaps {
        let n = self.n;
        let d = 2 * n;
        let mut lhs = DMatrix::<f64>::identity(d, d);
        let mut rhs = DMatrix::<f64>::zeros(d, d + 2 * n);
        for r in 0..d {
            for c in 0..d {
                rhs[(r, c)] = free.phi0[r * d + c];
            }
            for q in 0..n {
                let (mut a1, mut a0) = (0.0, 0.0);
                for p in 0..n {
                    a1 += free.v1[r * n + p] * k1[p * n + q];
                    a0 += free.v0[r * n + p] * k0[p * n + q];
                }
                lhs[(r, q)] += a1;
                rhs[(r, q)] -= a0;
                rhs[(r, d + q)] = a1;
                rhs[(r, d + n + q)] = a0;
            }
        }
        let sol = lhs.lu().solve(&rhs).unwrap_or(rhs);
        let mut maps = StepMaps {
            phi0: vec![0.0; d * d],
            w1: vec![0.0; d * n],
            w0: vec![0.0; d * n],
        };
        for r in 0..d {
            for c in 0..d {
                maps.phi0[r * d + c] = sol[(r, c)];
            }
            for q in 0..n {
                maps.w1[r * n + q] = sol[(r, d + q)];
                maps.w0[r * n + q] = sol[(r, d + n + q)];
            }
        }
        maps
    }

    /// Φ0 and the velocity columns of Φ1 − Φ2/Δt and Φ2/Δt of the uncut system.
    fn free_blocks(&self, dt: f64) -> FreeBlocks {
        let n = self.n;
        let d = 2 * n;
        let zero = vec![0.0; n * n];
        let e = self.augmented_exp(&zero, dt);
        let mut phi0 = vec![0.0; d * d];
        for r in 0..d {
            for c in 0..d {
                phi0[r * d + c] = e[(r, c)];
            }
        }
        let mut v0 = vec![0.0; d * n];
        let mut v1 = vec![0.0; d * n];
        for r in 0..d {
            for p in 0..n {
                let phi1 = e[(r, d + n + p)];
                let phi2 = e[(r, 2 * d + n + p)] / dt;
                v1[r * n + p] = phi2;
                v0[r * n + p] = phi1 - phi2;
            }
        }
        FreeBlocks { phi0, v0, v1 }
    }

    /// One-period transition matrix (column-major, dimension² entries).
    pub fn transition_matrix(&self, rpm: f64, depth_mm: f64) -> DMatrix<f64> {
        let n = self.n;
        let d = 2 * n;
        let m = self.steps;
        let dim = self.dimension();
        let tau = 60.0 / (rpm * self.teeth as f64);
        let dt = tau / m as f64;
        let a = depth_mm * 1e-3;
        let zero = vec![0.0; n * n];
        let free = self.step_maps(&zero, dt);
        let blocks = if self.full {
            Some(self.free_blocks(dt))
        } else {
            None
        };
        let is_cut = |h: &[[f64; 2]; 2]| h.iter().flatten().any(|&v| v != 0.0) && a != 0.0;
        let mut x = vec![0.0; dim * dim];
        for i in 0..dim {
            x[i * dim + i] = 1.0;
        }
        let mut y = vec![0.0; dim * dim];
        let slot = |s: usize| d + (s - 1) * n;
        let (s_new, s_old) = (slot(m - 1), slot(m));
        for (i, h) in self.h_steps.iter().enumerate() {
            let owned;
            let (engaged, maps) = match &blocks {
                None if is_cut(h) => {
                    owned = self.step_maps(&self.cutting_matrix(h, a), dt);
                    (true, &owned)
                }
                Some(b) if is_cut(h) || is_cut(&self.h_steps[(i + 1) % m]) => {
                    let k0 = self.cutting_matrix(h, a);
                    let k1 = self.cutting_matrix(&self.h_steps[(i + 1) % m], a);
                    owned = self.fd_step_maps(b, &k0, &k1);
                    (true, &owned)
                }
                _ => (false, &free),
            };
            for c in 0..dim {
                let xc = &x[c * dim..(c + 1) * dim];
                let yc = &mut y[c * dim..(c + 1) * dim];
                for (r, out) in yc[..d].iter_mut().enumerate() {
                    let row = &maps.phi0[r * d..(r + 1) * d];
                    let mut v: f64 = row.iter().zip(&xc[..d]).map(|(p, q)| p * q).sum();
                    if engaged {
                        for q in 0..n {
                            v += maps.w1[r * n + q] * xc[s_new + q]
                                + maps.w0[r * n + q] * xc[s_old + q];
                        }
                    }
                    *out = v;
                }
                yc[d..d + n].copy_from_slice(&xc[..n]);
                yc[d + n..dim].copy_from_slice(&xc[d..dim - n]);
            }
            std::mem::swap(&mut x, &mut y);
        }
        DMatrix::from_vec(dim, dim, x)
    }

    /// Spectral radius of the one-period transition matrix (largest Floquet multiplier
    /// modulus); below 1 means stable. Eigenvalues by nalgebra's Schur decomposition (with an
    /// iteration cap) of the matrix with velocities scaled by 1/ω (a similarity transform);
    /// should that not converge, the Gelfand limit ‖T^(2^j)‖^(1/2^j) by repeated squaring.
    pub fn spectral_radius(&self, rpm: f64, depth_mm: f64) -> Result<f64, PhysicsError> {
        let mut t = self.transition_matrix(rpm, depth_mm);
        let dim = t.nrows();
        if t.iter().any(|v| !v.is_finite()) {
            return Err(PhysicsError::invalid(
                "rpm",
                format!("transition matrix not finite at {rpm} rpm, depth {depth_mm} mm"),
            ));
        }
        for (p, &(_, w, _, _)) in self.modes.iter().enumerate() {
            let v = self.n + p;
            t.row_mut(v).scale_mut(1.0 / w);
            t.column_mut(v).scale_mut(w);
        }
        if let Some(schur) =
            nalgebra::Schur::try_new(t.clone(), f64::EPSILON, SCHUR_ITERATIONS_PER_ROW * dim)
        {
            return Ok(schur
                .complex_eigenvalues()
                .iter()
                .map(|l| l.norm())
                .fold(0.0, f64::max));
        }
        Ok(gelfand_spectral_radius(t))
    }

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

/// ρ(T) ≈ ‖T^(2^j)‖^(1/2^j), j = 40, normalising at every squaring.
fn gelfand_spectral_radius(mut t: DMatrix<f64>) -> f64 {
    let mut log_scale = 0.0;
    let mut weight = 1.0;
    for _ in 0..40 {
        let norm = t.amax();
        if norm == 0.0 {
            return 0.0;
        }
        t /= norm;
        log_scale += weight * norm.ln();
        t = &t * &t;
        weight *= 0.5;
    }
    (log_scale + weight * t.amax().ln()).exp()
}

/// A recommended spindle speed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpeedRecommendation {
    /// Centre of the pocket, rpm.
    pub rpm: f64,
    /// Critical depth at that speed (interpolated on the curve), mm.
    pub stable_depth_mm: f64,
    /// The pocket: speeds from..to where the critical depth exceeds the requested depth.
    pub pocket_from_rpm: f64,
    pub pocket_to_rpm: f64,
}

/// The centre of the widest stable pocket near `requested_rpm`: among the maximal runs of
/// grid speeds within `requested_rpm ± window_rpm` whose critical depth exceeds `depth_mm`,
/// the widest (ties: the one whose centre is nearest the requested speed); its centre and
/// the critical depth there. `None` if no speed in the window is stable at `depth_mm`.
/// `curve` must be sorted by speed.
pub fn recommend_spindle_speed(
    curve: &[LobePoint],
    requested_rpm: f64,
    depth_mm: f64,
    window_rpm: f64,
) -> Option<SpeedRecommendation> {
    let inside: Vec<&LobePoint> = curve
        .iter()
        .filter(|p| (p.rpm - requested_rpm).abs() <= window_rpm)
        .collect();
    let mut best: Option<(f64, f64, f64)> = None; // (width, from, to)
    let mut i = 0;
    while i < inside.len() {
        if inside[i].depth_mm <= depth_mm {
            i += 1;
            continue;
        }
        let start = i;
        while i + 1 < inside.len() && inside[i + 1].depth_mm > depth_mm {
            i += 1;
        }
        let (from, to) = (inside[start].rpm, inside[i].rpm);
        let width = to - from;
        let centre = 0.5 * (from + to);
        let better = match best {
            None => true,
            Some((w, f, t)) => {
                width > w
                    || (width == w
                        && (centre - requested_rpm).abs() < (0.5 * (f + t) - requested_rpm).abs())
            }
        };
        if better {
            best = Some((width, from, to));
        }
        i += 1;
    }
    let (_, from, to) = best?;
    let rpm = 0.5 * (from + to);
    Some(SpeedRecommendation {
        rpm,
        stable_depth_mm: interpolate(curve, rpm),
        pocket_from_rpm: from,
        pocket_to_rpm: to,
    })
}

/// Critical depth at `rpm` by linear interpolation on a curve sorted by speed.
pub fn interpolate(curve: &[LobePoint], rpm: f64) -> f64 {
    let j = curve.partition_point(|p| p.rpm < rpm);
    if j == 0 {
        return curve.first().map_or(f64::NAN, |p| p.depth_mm);
    }
    if j >= curve.len() {
        return curve.last().map_or(f64::NAN, |p| p.depth_mm);
    }
    let (p0, p1) = (curve[j - 1], curve[j]);
    if p1.rpm == p0.rpm {
        return p0.depth_mm.min(p1.depth_mm);
    }
    p0.depth_mm + (p1.depth_mm - p0.depth_mm) * (rpm - p0.rpm) / (p1.rpm - p0.rpm)
}

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
    super::non_negative(field, v).map(|_| ())
}

/// The lobe curve at every requested allowance ([`compute_lobes`] of
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gelfand_fallback_agrees_with_schur() {
        // A rotation-like block (complex pair of modulus 0.9) and a real eigenvalue −0.5.
        let m = DMatrix::from_row_slice(3, 3, &[0.0, -0.9, 3.0, 0.9, 0.0, -1.0, 0.0, 0.0, -0.5]);
        let schur = nalgebra::Schur::new(m.clone())
            .complex_eigenvalues()
            .iter()
            .map(|l| l.norm())
            .fold(0.0, f64::max);
        let g = gelfand_spectral_radius(m);
        assert!(
            (schur - 0.9).abs() < 1e-12 && (g - 0.9).abs() < 1e-6,
            "{schur} {g}"
        );
    }
}
