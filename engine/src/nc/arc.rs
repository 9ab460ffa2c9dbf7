//! Exact arc geometry of a G2/G3 move and a sampler for when geometry needs points.

/// An arc (possibly helical, possibly with several turns) in the machine frame, mm/degrees.
#[derive(Clone, Debug, PartialEq)]
pub struct ArcGeometry {
    pub start: [f64; 6],
    pub end: [f64; 6],
    /// Centre; its coordinate along the normal is the start's.
    pub center: [f64; 3],
    /// Plane normal: +Z (G17), +Y (G18), +X (G19).
    pub normal: [f64; 3],
    /// Indices (0=X,1=Y,2=Z) of the plane's first and second axis and of the normal axis:
    /// G17 (X,Y,Z), G18 (Z,X,Y), G19 (Y,Z,X).
    pub axes: [usize; 3],
    /// Signed sweep in radians, positive counterclockwise seen from the normal's tip.
    pub sweep: f64,
    pub start_radius: f64,
    /// Differs slightly from `start_radius` when the program's end point is not exactly on the
    /// circle; the path is then a spiral (as on LinuxCNC).
    pub end_radius: f64,
    pub clockwise: bool,
    /// Full turns requested (P word), at least 1.
    pub turns: u32,
}

impl ArcGeometry {
    fn start_angle(&self) -> f64 {
        let [a, b, _] = self.axes;
        (self.start[b] - self.center[b]).atan2(self.start[a] - self.center[a])
    }

    /// Point at parameter `t` in [0, 1]; rotary axes and the normal axis move linearly.
    pub fn point_at(&self, t: f64) -> [f64; 6] {
        if t >= 1.0 {
            return self.end;
        }
        if t <= 0.0 {
            return self.start;
        }
        let [a, b, n] = self.axes;
        let th = self.start_angle() + self.sweep * t;
        let r = self.start_radius + (self.end_radius - self.start_radius) * t;
        let mut p = [0.0; 6];
        for i in 0..6 {
            p[i] = self.start[i] + (self.end[i] - self.start[i]) * t;
        }
        p[a] = self.center[a] + r * th.cos();
        p[b] = self.center[b] + r * th.sin();
        p[n] = self.start[n] + (self.end[n] - self.start[n]) * t;
        p
    }

    /// Path length in mm (in-plane spiral length approximated by the mean radius).
    pub fn length(&self) -> f64 {
        let r = 0.5 * (self.start_radius + self.end_radius);
        let planar = r * self.sweep.abs();
        let h = self.end[self.axes[2]] - self.start[self.axes[2]];
        (planar * planar + h * h).sqrt()
    }
}

/// Points along the arc, start and end included, such that no chord is farther than
/// `chord_tolerance` (mm) from the arc. At most 1,000,000 segments.
pub fn sample_arc(arc: &ArcGeometry, chord_tolerance: f64) -> Vec<[f64; 6]> {
    let r = arc.start_radius.max(arc.end_radius);
    let tol = if chord_tolerance.is_finite() && chord_tolerance > 0.0 {
        chord_tolerance
    } else {
        1e-3
    };
    let step = if tol >= r {
        std::f64::consts::FRAC_PI_2
    } else {
        (2.0 * (1.0 - tol / r).acos()).min(std::f64::consts::FRAC_PI_2)
    };
    let n = if step > 0.0 && arc.sweep.is_finite() {
        ((arc.sweep.abs() / step).ceil() as usize).clamp(1, 1_000_000)
    } else {
        1
    };
    (0..=n).map(|i| arc.point_at(i as f64 / n as f64)).collect()
}
