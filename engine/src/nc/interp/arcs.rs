//! G2/G3 arcs: centre from I/J/K or R, turns, tolerances as LinuxCNC 2.9.

use super::words::Words;
use super::{Interp, MAX_ARC_TURNS, MM_PER_INCH, R};

impl Interp<'_> {
    pub(super) fn arc(&mut self, w: &mut Words, cw: bool) -> R<()> {
        self.check_feed()?;
        let plane = self.modal.plane;
        let [a, b, _n] = plane.axes();
        self.off_plane_centre_word(w, plane)?;
        let start = self.cur;
        let end = self.target(w, false)?;
        let turns = match w.take('P') {
            Some(p) => {
                if p.fract() != 0.0 || p < 1.0 || p > MAX_ARC_TURNS {
                    return Err(self.err_word(
                        w,
                        'P',
                        format!("arc P{p}: turns must be a whole number 1..{MAX_ARC_TURNS}"),
                    ));
                }
                p as u32
            }
            None => 1,
        };
        let (cx, cy) = self.arc_center(w, cw, &start, &end)?;
        // Sweep: LinuxCNC counts turns CCW; equal start and end angles make a full circle.
        let a0 = (start[b] - cy).atan2(start[a] - cx);
        let a1 = (end[b] - cy).atan2(end[a] - cx);
        let tau = std::f64::consts::TAU;
        let same = (end[a] - start[a]).abs() < 1e-9 && (end[b] - start[b]).abs() < 1e-9;
        let mut sweep = if same { 0.0 } else { a1 - a0 };
        if cw {
            if sweep >= 0.0 {
                sweep -= tau;
            }
            sweep -= tau * (turns - 1) as f64;
        } else {
            if sweep <= 0.0 {
                sweep += tau;
            }
            sweep += tau * (turns - 1) as f64;
        }
        if self
            .coords
            .tilt
            .is_some_and(|t| !t.keeps_axis(plane.axes()[2]))
        {
            self.tilted_arc_as_chords(plane, start, end, [cx, cy], sweep, turns)?;
            self.cur = end;
            return Ok(());
        }
        let m = self.arc_move_machine(plane, start, end, [cx, cy], sweep, turns)?;
        self.push(m)?;
        self.cur = end;
        Ok(())
    }
    /// The centre word of the axis normal to the arc's plane (K in G17, J in G18, I in G19):
    /// LinuxCNC and Fanuc alarm on it. grbl ignores it, and posts for grbl (FreeCAD's) write
    /// `K0` in every G17 arc: a zero one is ignored with a warning; any other is refused.
    pub(super) fn off_plane_centre_word(
        &mut self,
        w: &mut Words,
        plane: super::modal::Plane,
    ) -> R<()> {
        let bad = plane.forbidden_ijk();
        match w.get(bad) {
            None => Ok(()),
            Some(v) if v == 0.0 => {
                w.take(bad);
                self.out.warnings.push(self.err_block(format!(
                    "{bad}0 in a {} arc ignored (the plane's normal axis has no centre offset; grbl ignores it, LinuxCNC and Fanuc alarm)",
                    plane.name()
                )));
                Ok(())
            }
            Some(_) => Err(self.err_word(w, bad, format!("{bad} word in a {} arc", plane.name()))),
        }
    }

    /// Centre of an arc from `start` to `end` (program coordinates) in the selected plane,
    /// from the block's R or I/J/K words, as LinuxCNC 2.9 checks them.
    pub(super) fn arc_center(
        &self,
        w: &mut Words,
        cw: bool,
        start: &[f64; 6],
        end: &[f64; 6],
    ) -> R<(f64, f64)> {
        let plane = self.modal.plane;
        let [a, b, _n] = plane.axes();
        let [li, lj] = plane.ijk();
        let has_ijk = w.has(li) || w.has(lj);
        let inch = !self.modal.metric;
        let (cx, cy) = if let Some(r) = w.take('R') {
            if has_ijk {
                return Err(self.err_block("arc with both R and I/J/K"));
            }
            let (sx, sy, ex, ey) = (start[a], start[b], end[a], end[b]);
            if ex == sx && ey == sy {
                return Err(self.err_word(
                    w,
                    'R',
                    "R-format arc with the end point equal to the start point",
                ));
            }
            let tol = if inch { 0.00005 } else { 0.00005 * MM_PER_INCH };
            let abs_r = r.abs();
            let (mx, my) = ((ex + sx) / 2.0, (ey + sy) / 2.0);
            let mut half = (mx - ex).hypot(my - ey);
            if half - abs_r > tol {
                return Err(self.err_word(
                    w,
                    'R',
                    format!("arc radius {abs_r} too small to reach the end point"),
                ));
            }
            if half / abs_r > 1.0 - 1e-12 {
                half = abs_r;
            }
            let theta = if (cw && r > 0.0) || (!cw && r < 0.0) {
                (ey - sy).atan2(ex - sx) - std::f64::consts::FRAC_PI_2
            } else {
                (ey - sy).atan2(ex - sx) + std::f64::consts::FRAC_PI_2
            };
            let turn2 = (half / abs_r).asin();
            let off = abs_r * turn2.cos();
            (mx + off * theta.cos(), my + off * theta.sin())
        } else {
            if !has_ijk {
                return Err(self.err_block("arc needs I/J/K (centre) or R (radius)"));
            }
            let i = w.take(li).unwrap_or(0.0);
            let j = w.take(lj).unwrap_or(0.0);
            let c = if self.modal.arc_absolute {
                (i, j)
            } else {
                (start[a] + i, start[b] + j)
            };
            let r1 = (c.0 - start[a]).hypot(c.1 - start[b]);
            let r2 = (c.0 - end[a]).hypot(c.1 - end[b]);
            let rtol = if inch { 0.00005 } else { 0.00005 * MM_PER_INCH };
            if r1 < rtol || r2 < rtol {
                return Err(self.err_block(format!("zero-radius arc (r1={r1:.4}, r2={r2:.4})")));
            }
            let abs_err = (r1 - r2).abs();
            let rel = abs_err / r1.max(r2);
            let atol = if inch {
                2.0 * 0.001 * std::f64::consts::SQRT_2
            } else {
                2.0 * 0.01 * std::f64::consts::SQRT_2
            };
            // LinuxCNC 2.9: a small spiral is accepted; large or relatively large ones are not.
            if abs_err > atol * 100.0 || (rel > 0.001 && abs_err > atol) {
                return Err(self.err_block(format!(
                    "radius to end of arc differs from radius to start: r1={r1:.4} r2={r2:.4} (difference {abs_err:.4})"
                )));
            }
            c
        };
        Ok((cx, cy))
    }
}
