//! Per-block chatter margin: the critical depth at a block's spindle speed, radial immersion
//! and milling direction, memoized so that thousands of blocks with a handful of distinct
//! cutting conditions cost a handful of lobe computations.
//!
//! ```
//! use millsim_engine::physics::chatter::ChatterModel;
//! use millsim_engine::physics::stability::{Method, Milling, Mode};
//!
//! let model = ChatterModel::new(
//!     vec![Mode::with_mass(922.0, 0.011, 0.03993)], vec![], 2, 600.0, 200.0, Method::Zoa, 40,
//! ).unwrap();
//! let m = model.margin(0.2, 10_000.0, 1.0, Milling::Down).unwrap();
//! assert!(m.critical_depth_mm > 0.29 && !m.chatter);
//! ```

use std::collections::HashMap;
use std::f64::consts::PI;
use std::sync::Mutex;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::stability::{
    Method, Milling, Mode, SearchOptions, StabilityInput, StabilitySystem, DEFAULT_STEPS_PER_PERIOD,
};
use super::{finite, PhysicsError};

/// Cache key: speed rounded to 1 rpm, immersion to 0.01 (as hundredths), direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Key {
    rpm: i64,
    immersion_pct: i64,
    down: bool,
}

/// Chatter margin of one block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ChatterMargin {
    /// Critical depth at the (rounded) conditions, mm (infinite when nothing is engaged).
    pub critical_depth_mm: f64,
    /// Axial depth / critical depth.
    pub margin: f64,
    /// margin > 1: the block chatters.
    pub chatter: bool,
}

/// Tool (and workpiece) modes, teeth and cutting coefficients with a method; answers the
/// critical depth for any (speed, immersion, direction), memoized on the speed rounded to
/// 1 rpm and the immersion rounded to 0.01. The value for a key is the lobe computation at
/// the rounded speed and immersion exactly (immersions round to at least 0.01 and at most
/// 1). Thread-safe: blocks can be evaluated in parallel; [`ChatterModel::prefetch`] computes
/// many conditions in parallel up front.
#[derive(Debug)]
pub struct ChatterModel {
    teeth: u32,
    ktc_n_mm2: f64,
    krc_n_mm2: f64,
    modes_x: Vec<Mode>,
    modes_y: Vec<Mode>,
    method: Method,
    steps: usize,
    search: SearchOptions,
    cache: Mutex<HashMap<Key, f64>>,
}

impl ChatterModel {
    /// Validates the system (as [`StabilitySystem::new`]; `steps_per_period` in 4..=400 is
    /// used by `sdm`/`fdm`, ignored by `zoa`). Depth search: the default bisection on
    /// [0, 16] mm (see [`ChatterModel::with_search`]).
    pub fn new(
        modes_x: Vec<Mode>,
        modes_y: Vec<Mode>,
        teeth: u32,
        ktc_n_mm2: f64,
        krc_n_mm2: f64,
        method: Method,
        steps_per_period: u32,
    ) -> Result<ChatterModel, PhysicsError> {
        let sys = StabilitySystem::new(
            teeth,
            ktc_n_mm2,
            krc_n_mm2,
            1.0,
            Milling::Down,
            modes_x.clone(),
            modes_y.clone(),
        )?;
        if method != Method::Zoa {
            sys.sd_model(steps_per_period as usize)?;
        }
        Ok(ChatterModel {
            teeth,
            ktc_n_mm2,
            krc_n_mm2,
            modes_x,
            modes_y,
            method,
            steps: steps_per_period as usize,
            search: SearchOptions::default(),
            cache: Mutex::new(HashMap::new()),
        })
    }

    /// The modes, teeth, coefficients, method, steps and depth search of a stability input
    /// (its immersion, direction and speed grid are not used).
    pub fn from_input(input: &StabilityInput) -> Result<ChatterModel, PhysicsError> {
        Ok(ChatterModel::new(
            input.modes_x.clone(),
            input.modes_y.clone(),
            input.teeth,
            input.ktc_n_mm2,
            input.krc_n_mm2,
            input.method,
            input.steps_per_period.unwrap_or(DEFAULT_STEPS_PER_PERIOD),
        )?
        .with_search(input.search_options()))
    }

    /// Another depth search (clears the cache).
    pub fn with_search(mut self, search: SearchOptions) -> ChatterModel {
        self.search = search;
        self.cache = Mutex::new(HashMap::new());
        self
    }

    /// Number of distinct conditions computed so far.
    pub fn cached(&self) -> usize {
        self.cache.lock().map(|c| c.len()).unwrap_or(0)
    }

    fn key(rpm: f64, immersion: f64, milling: Milling) -> Result<Option<Key>, PhysicsError> {
        finite("rpm", rpm)?;
        finite("radial_immersion", immersion)?;
        if rpm.round() < 1.0 {
            return Err(PhysicsError::invalid(
                "rpm",
                format!("must be at least 1 rpm to cut, got {rpm}"),
            ));
        }
        if immersion <= 0.0 {
            return Ok(None);
        }
        Ok(Some(Key {
            rpm: rpm.round() as i64,
            immersion_pct: (immersion * 100.0).round().clamp(1.0, 100.0) as i64,
            down: milling == Milling::Down,
        }))
    }

    /// The lobe computation at exactly this speed and immersion (no rounding, no cache), mm.
    pub fn direct_critical_depth(
        &self,
        rpm: f64,
        radial_immersion: f64,
        milling: Milling,
    ) -> Result<f64, PhysicsError> {
        let sys = StabilitySystem::new(
            self.teeth,
            self.ktc_n_mm2,
            self.krc_n_mm2,
            radial_immersion,
            milling,
            self.modes_x.clone(),
            self.modes_y.clone(),
        )?;
        match self.method {
            Method::Zoa => Ok(sys.zoa_lobes(&[rpm], self.search.max_depth_mm)[0]),
            Method::Sdm => sys
                .sd_model(self.steps)?
                .critical_depth_mm(rpm, &self.search),
            Method::Fdm => sys
                .fd_model(self.steps)?
                .critical_depth_mm(rpm, &self.search),
        }
    }

    fn compute(&self, k: Key) -> Result<f64, PhysicsError> {
        let milling = if k.down { Milling::Down } else { Milling::Up };
        self.direct_critical_depth(k.rpm as f64, k.immersion_pct as f64 / 100.0, milling)
    }

    /// Critical depth (mm) at the speed rounded to 1 rpm and the immersion (ae/D) rounded to
    /// 0.01 (at least 0.01, at most 1); infinite when `radial_immersion` ≤ 0 (nothing
    /// engaged). Capped at the search's maximum depth (16 mm by default).
    pub fn critical_depth(
        &self,
        rpm: f64,
        radial_immersion: f64,
        milling: Milling,
    ) -> Result<f64, PhysicsError> {
        let Some(k) = Self::key(rpm, radial_immersion, milling)? else {
            return Ok(f64::INFINITY);
        };
        if let Some(v) = self.cache.lock().ok().and_then(|c| c.get(&k).copied()) {
            return Ok(v);
        }
        let v = self.compute(k)?;
        if let Ok(mut c) = self.cache.lock() {
            c.insert(k, v);
        }
        Ok(v)
    }

    /// Margin = axial depth / critical depth; `chatter` when above 1. An axial depth of 0 or
    /// no immersion gives margin 0.
    pub fn margin(
        &self,
        axial_depth_mm: f64,
        rpm: f64,
        radial_immersion: f64,
        milling: Milling,
    ) -> Result<ChatterMargin, PhysicsError> {
        super::non_negative("axial_depth_mm", axial_depth_mm)?;
        let critical_depth_mm = self.critical_depth(rpm, radial_immersion, milling)?;
        let margin = if axial_depth_mm == 0.0 || critical_depth_mm.is_infinite() {
            0.0
        } else {
            axial_depth_mm / critical_depth_mm
        };
        Ok(ChatterMargin {
            critical_depth_mm,
            margin,
            chatter: margin > 1.0,
        })
    }

    /// Computes every distinct condition (rpm, immersion, direction) not cached yet, in
    /// parallel (rayon); later [`critical_depth`](Self::critical_depth) calls are lookups.
    pub fn prefetch(&self, conditions: &[(f64, f64, Milling)]) -> Result<(), PhysicsError> {
        let mut keys = Vec::new();
        for &(rpm, imm, m) in conditions {
            if let Some(k) = Self::key(rpm, imm, m)? {
                keys.push(k);
            }
        }
        keys.sort_by_key(|k| (k.rpm, k.immersion_pct, k.down));
        keys.dedup();
        if let Ok(c) = self.cache.lock() {
            keys.retain(|k| !c.contains_key(k));
        }
        let values: Vec<(Key, f64)> = keys
            .par_iter()
            .map(|&k| self.compute(k).map(|v| (k, v)))
            .collect::<Result<_, _>>()?;
        if let Ok(mut c) = self.cache.lock() {
            c.extend(values);
        }
        Ok(())
    }
}

/// The straight-cut equivalent of an engaged arc (φ_entry, φ_exit) in the Engagement
/// convention (φ clockwise from +y, 0 ≤ entry < exit ≤ π for the front half): the radial
/// immersion is the radial width the arc spans, (cos φ_entry − cos φ_exit)/2 (in units of
/// the diameter), and the direction is down milling when the arc's middle lies past π/2
/// (the tooth leaves the material at the exit side, as in down milling), up milling
/// otherwise. A slot (0, π) gives (1, down).
pub fn arc_immersion(entry_rad: f64, exit_rad: f64) -> (f64, Milling) {
    let (a, b) = (entry_rad.clamp(0.0, PI), exit_rad.clamp(0.0, PI));
    if b <= a {
        return (0.0, Milling::Down);
    }
    let imm = ((a.cos() - b.cos()) / 2.0).clamp(0.0, 1.0);
    let milling = if 0.5 * (a + b) >= PI / 2.0 {
        Milling::Down
    } else {
        Milling::Up
    };
    (imm, milling)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::stability::{compute_lobes, DepthSearch, RpmRange};

    /// The 1-DOF benchmark of docs/reference.md.
    fn benchmark(method: Method) -> ChatterModel {
        ChatterModel::new(
            vec![Mode::with_mass(922.0, 0.011, 0.03993)],
            vec![],
            2,
            600.0,
            200.0,
            method,
            20,
        )
        .unwrap()
    }

    fn lobes_at(method: Method, rpm: f64, immersion: f64, milling: Milling) -> f64 {
        let input = StabilityInput {
            method,
            teeth: 2,
            ktc_n_mm2: 600.0,
            krc_n_mm2: 200.0,
            radial_immersion: immersion,
            milling,
            modes_x: vec![Mode::with_mass(922.0, 0.011, 0.03993)],
            modes_y: vec![],
            rpm: RpmRange {
                from: rpm,
                to: rpm,
                step: 1.0,
            },
            steps_per_period: Some(20),
            search: DepthSearch::Bisection,
            scan_step_mm: None,
        };
        compute_lobes(&input).unwrap().points[0].depth_mm
    }

    #[test]
    fn cached_value_is_the_direct_lobe_computation_at_the_rounded_conditions() {
        let m = benchmark(Method::Sdm);
        let a = m.critical_depth(10_000.4, 0.504, Milling::Down).unwrap();
        assert_eq!(a, lobes_at(Method::Sdm, 10_000.0, 0.5, Milling::Down));
        assert_eq!(m.cached(), 1);
        // Same key: a lookup.
        let b = m.critical_depth(9_999.6, 0.496, Milling::Down).unwrap();
        assert_eq!(a, b);
        assert_eq!(m.cached(), 1);
        // Up milling is another key and another value.
        let up = m.critical_depth(10_000.0, 0.5, Milling::Up).unwrap();
        assert_eq!(up, lobes_at(Method::Sdm, 10_000.0, 0.5, Milling::Up));
        assert_eq!(m.cached(), 2);
        // Margin: axial depth / critical depth; above 1 flags chatter.
        let over = m.margin(2.0 * a, 10_000.0, 0.5, Milling::Down).unwrap();
        assert!((over.margin - 2.0).abs() < 1e-12 && over.chatter);
        let under = m.margin(0.5 * a, 10_000.0, 0.5, Milling::Down).unwrap();
        assert!((under.margin - 0.5).abs() < 1e-12 && !under.chatter);
        assert_eq!(
            m.margin(1.0, 10_000.0, 0.0, Milling::Down).unwrap().margin,
            0.0
        );
        assert_eq!(
            m.critical_depth(0.0, 0.5, Milling::Down)
                .unwrap_err()
                .field(),
            "rpm"
        );
    }

    #[test]
    fn many_blocks_few_conditions_cost_few_computations() {
        let m = benchmark(Method::Zoa);
        let conds = [
            (8000.0, 1.0, Milling::Down),
            (12000.0, 0.25, Milling::Down),
            (12000.0, 0.25, Milling::Up),
        ];
        let blocks: Vec<(f64, f64, Milling)> = (0..3000)
            .map(|i| {
                let (n, a, d) = conds[i % 3];
                // Jitter below the rounding: same keys.
                (
                    n + 0.3 * ((i % 7) as f64 / 7.0 - 0.5),
                    a + 0.004 * ((i % 5) as f64 / 5.0 - 0.5),
                    d,
                )
            })
            .collect();
        m.prefetch(&blocks).unwrap();
        assert_eq!(m.cached(), 3);
        for &(n, a, d) in &blocks {
            let c = m.critical_depth(n, a, d).unwrap();
            assert!(c > 0.0);
        }
        assert_eq!(m.cached(), 3);
        for (n, a, d) in conds {
            assert_eq!(
                m.critical_depth(n, a, d).unwrap(),
                lobes_at(Method::Zoa, n, a, d)
            );
        }
        // Slot at 8000 rpm, zero-order: at least the absolute limit 0.298 mm of docs/reference.md.
        assert!(m.critical_depth(8000.0, 1.0, Milling::Down).unwrap() >= 0.298 * 0.99);
    }

    #[test]
    fn arcs_map_to_straight_cut_immersions() {
        let (i, d) = arc_immersion(PI / 2.0, PI);
        assert!((i - 0.5).abs() < 1e-12 && d == Milling::Down);
        let (i, d) = arc_immersion(0.0, PI / 2.0);
        assert!((i - 0.5).abs() < 1e-12 && d == Milling::Up);
        let (i, d) = arc_immersion(0.0, PI);
        assert!((i - 1.0).abs() < 1e-12 && d == Milling::Down);
        // Down milling at aD = 0.05: entry acos(2·0.05 − 1).
        let (i, d) = arc_immersion((2.0f64 * 0.05 - 1.0).acos(), PI);
        assert!((i - 0.05).abs() < 1e-12 && d == Milling::Down);
    }
}
