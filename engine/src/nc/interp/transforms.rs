//! Coordinate transforms between the program's coordinates and the machine frame, beyond the
//! plain offsets: LinuxCNC's rotation of a coordinate system (G10 L2 R), local offsets (G52),
//! and Fanuc's programmable mirror image (G51.1/G50.1), scaling (G51/G50) and coordinate
//! rotation (G68/G69).
//!
//! The order is the controls': a programmed point (mm) goes through Fanuc's mirror, scaling
//! and rotation (in that order, each about its own centre in program coordinates), then gets
//! the G92/G52 offsets, then LinuxCNC's rotation of the coordinate system about its origin
//! (rs274's canon adds G92 before it rotates), then the G5x offset. Every transform is
//! affine, so arcs stay arcs where the transform is a similarity in the arc's plane (anything
//! else is refused), and turning a transform on or off keeps the tool where it is (the
//! current position is recomputed, as for an offset change).

use super::modal::Plane;
use super::words::{Words, AXES};
use super::{Interp, R};
use crate::nc::arc::ArcGeometry;
use crate::nc::{Move, MoveKind};

/// Fanuc G68: rotation in one plane about a centre.
#[derive(Clone, Copy, Debug)]
pub(super) struct Rotation {
    /// The plane's first and second axis.
    pub(super) axes: [usize; 2],
    /// Centre in those axes, mm (program coordinates).
    pub(super) center: [f64; 2],
    pub(super) cos: f64,
    pub(super) sin: f64,
}

/// Fanuc's program transforms (all off at power-up).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ProgramTransforms {
    /// G51.1: the mirror line per axis X, Y, Z (mm), None where not mirrored.
    pub(super) mirror: [Option<f64>; 3],
    /// G51: centre (mm) and factor per axis X, Y, Z.
    pub(super) scale: Option<([f64; 3], [f64; 3])>,
    pub(super) rotation: Option<Rotation>,
}

impl ProgramTransforms {
    pub(super) fn is_identity(&self) -> bool {
        self.mirror.iter().all(Option::is_none) && self.scale.is_none() && self.rotation.is_none()
    }

    /// Program point (mm) -> transformed point (mm).
    fn apply(&self, q: &mut [f64; 6]) {
        for (i, m) in self.mirror.iter().enumerate() {
            if let Some(c) = m {
                q[i] = 2.0 * c - q[i];
            }
        }
        if let Some((c, k)) = self.scale {
            for i in 0..3 {
                q[i] = c[i] + k[i] * (q[i] - c[i]);
            }
        }
        if let Some(r) = self.rotation {
            let [a, b] = r.axes;
            let (da, db) = (q[a] - r.center[0], q[b] - r.center[1]);
            q[a] = r.center[0] + r.cos * da - r.sin * db;
            q[b] = r.center[1] + r.sin * da + r.cos * db;
        }
    }

    /// The inverse of `apply` (scale factors are never zero).
    fn invert(&self, q: &mut [f64; 6]) {
        if let Some(r) = self.rotation {
            let [a, b] = r.axes;
            let (da, db) = (q[a] - r.center[0], q[b] - r.center[1]);
            q[a] = r.center[0] + r.cos * da + r.sin * db;
            q[b] = r.center[1] - r.sin * da + r.cos * db;
        }
        if let Some((c, k)) = self.scale {
            for i in 0..3 {
                q[i] = c[i] + (q[i] - c[i]) / k[i];
            }
        }
        for (i, m) in self.mirror.iter().enumerate() {
            if let Some(c) = m {
                q[i] = 2.0 * c - q[i];
            }
        }
    }
}

fn rotate_xy(q: &mut [f64; 6], deg: f64) {
    let (s, c) = deg.to_radians().sin_cos();
    let (x, y) = (q[0], q[1]);
    q[0] = c * x - s * y;
    q[1] = s * x + c * y;
}

impl Interp<'_> {
    /// No rotation, mirror or scaling, no G52 and G92 not suspended: the machine position is
    /// the G5x and G92 offsets added, axis by axis (the common case, kept fast).
    pub(super) fn update_plain(&mut self) {
        self.coords.plain =
            self.only_offsets() && self.coords.g92_applied && self.coords.g52 == [0.0; 6];
    }

    /// No rotation, mirror or scaling: the transform is a translation (per-axis offsets).
    pub(super) fn only_offsets(&self) -> bool {
        self.coords.prog_xf.is_identity()
            && self.coords.rot_xy[self.modal.cs] == 0.0
            && self.coords.tilt.is_none()
    }

    /// The G92 offset as applied, plus the Fanuc G52 local offset (mm/deg).
    pub(super) fn local_offset(&self) -> [f64; 6] {
        let mut o = self.g92_eff();
        for (o, l) in o.iter_mut().zip(self.coords.g52) {
            *o += l;
        }
        o
    }

    /// Program coordinates -> machine frame, mm/deg.
    #[inline(always)]
    pub(super) fn to_machine(&self, p: [f64; 6]) -> [f64; 6] {
        if !self.coords.plain {
            return self.to_machine_transformed(p);
        }
        let u = self.unit();
        let g5x = &self.coords.g5x[self.modal.cs];
        let mut m = [0.0; 6];
        for i in 0..6 {
            let s = if i < 3 { u } else { 1.0 };
            m[i] = p[i] * s + g5x[i] + self.coords.g92[i];
        }
        m
    }

    /// `to_machine` when not `plain` (kept out of line: the common case stays small enough
    /// to inline).
    #[inline(never)]
    fn to_machine_transformed(&self, p: [f64; 6]) -> [f64; 6] {
        let u = self.unit();
        let g5x = &self.coords.g5x[self.modal.cs];
        let mut m = [0.0; 6];
        let local = self.local_offset();
        if self.only_offsets() {
            for i in 0..6 {
                let s = if i < 3 { u } else { 1.0 };
                m[i] = p[i] * s + g5x[i] + local[i];
            }
            return m;
        }
        for i in 0..6 {
            m[i] = if i < 3 { p[i] * u } else { p[i] };
        }
        if let Some(t) = &self.coords.tilt {
            t.apply(&mut m);
        }
        self.coords.prog_xf.apply(&mut m);
        for i in 0..6 {
            m[i] += local[i];
        }
        rotate_xy(&mut m, self.coords.rot_xy[self.modal.cs]);
        for i in 0..6 {
            m[i] += g5x[i];
        }
        m
    }

    /// Machine frame -> program coordinates (the inverse of `to_machine`).
    pub(super) fn from_machine(&self, m: [f64; 6]) -> [f64; 6] {
        let u = self.unit();
        let local = self.local_offset();
        let g5x = &self.coords.g5x[self.modal.cs];
        let mut p = [0.0; 6];
        if self.only_offsets() {
            for i in 0..6 {
                let s = if i < 3 { u } else { 1.0 };
                p[i] = (m[i] - g5x[i] - local[i]) / s;
            }
            return p;
        }
        for i in 0..6 {
            p[i] = m[i] - g5x[i];
        }
        rotate_xy(&mut p, -self.coords.rot_xy[self.modal.cs]);
        for i in 0..6 {
            p[i] -= local[i];
        }
        self.coords.prog_xf.invert(&mut p);
        if let Some(t) = &self.coords.tilt {
            t.invert(&mut p);
        }
        for v in &mut p[..3] {
            *v /= u;
        }
        p
    }

    /// The move of an arc given in program coordinates (centre in the plane's two axes,
    /// sweep signed counterclockwise), in the machine frame. Under a rotation, mirror or
    /// uniform scaling in the arc's plane the arc maps to an arc (a mirror reverses it); a
    /// transform that tilts the plane or scales its axes differently would make an ellipse
    /// or a tilted circle, which is refused.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn arc_move_machine(
        &self,
        plane: Plane,
        start: [f64; 6],
        end: [f64; 6],
        center: [f64; 2],
        sweep: f64,
        turns: u32,
    ) -> R<Move> {
        let [a, b, n] = plane.axes();
        let ms = self.to_machine(start);
        let me = self.to_machine(end);
        let mut cprog = start;
        cprog[a] = center[0];
        cprog[b] = center[1];
        let mc = self.to_machine(cprog);
        let c = [mc[0], mc[1], mc[2]];
        let u = self.unit();
        let r0 = (start[a] - center[0]).hypot(start[b] - center[1]);
        let r1 = (end[a] - center[0]).hypot(end[b] - center[1]);
        let (mut sweep, mut k) = (sweep, u);
        if !self.only_offsets() {
            // The transform's linear part on the plane's unit vectors.
            let mut ea = cprog;
            ea[a] += 1.0;
            let mut eb = cprog;
            eb[b] += 1.0;
            let (ma, mb) = (self.to_machine(ea), self.to_machine(eb));
            let va = [ma[a] - mc[a], ma[b] - mc[b], ma[n] - mc[n]];
            let vb = [mb[a] - mc[a], mb[b] - mc[b], mb[n] - mc[n]];
            let (la, lb) = (va[0].hypot(va[1]), vb[0].hypot(vb[1]));
            let tol = 1e-9 * la.max(lb);
            let dot = va[0] * vb[0] + va[1] * vb[1];
            if va[2].abs() > tol || vb[2].abs() > tol {
                let hint = if self.coords.tilt.is_some() {
                    " (a tilted G68.2 plane: its G2/G3 are cut as chords, but not with cutter compensation or corner rounding)"
                } else {
                    ""
                };
                return Err(self.err_block(format!(
                    "arc in {} with a coordinate rotation in another plane: the arc would leave its plane (not supported){hint}",
                    plane.name()
                )));
            }
            if (la - lb).abs() > tol || dot.abs() > tol {
                return Err(self.err_block(
                    "arc under scaling with different factors on its plane's axes: the path would be an ellipse (not supported)",
                ));
            }
            let det = va[0] * vb[1] - va[1] * vb[0];
            if det < 0.0 {
                sweep = -sweep;
            }
            k = la;
        }
        let cw = sweep < 0.0;
        let geom = ArcGeometry {
            start: ms,
            end: me,
            center: c,
            normal: plane.normal(),
            axes: plane.axes(),
            sweep,
            start_radius: r0 * k,
            end_radius: r1 * k,
            clockwise: cw,
            turns: turns.max(1),
        };
        let mut m = self.base_move(MoveKind::Arc, ms, me);
        m.center = Some(c);
        m.normal = Some(plane.normal());
        m.clockwise = Some(cw);
        m.arc = Some(Box::new(geom));
        Ok(m)
    }

    /// Whether one of Fanuc's program transforms is on (offset setting refuses then).
    pub(super) fn program_transform_on(&self) -> bool {
        !self.coords.prog_xf.is_identity() || self.coords.tilt.is_some()
    }

    /// LinuxCNC G10 L2 R: the rotation (degrees, about the coordinate system's origin in XY)
    /// of coordinate system `k`.
    pub(super) fn set_cs_rotation(&mut self, k: usize, deg: f64) {
        self.change_offsets(|s| s.coords.rot_xy[k] = deg);
    }

    /// G52: LinuxCNC sets the G92 offsets to the given values (axes not given keep theirs);
    /// Fanuc keeps a local offset of its own, added to the G92 shift. Both absolute (G91
    /// makes no difference on either control).
    pub(super) fn g52(&mut self, w: &mut Words, at: usize) -> R<()> {
        if self.program_transform_on() {
            return Err(self.err_at(
                at,
                "G52 with scaling, mirror image or rotation on (G50/G50.1/G69 first)",
            ));
        }
        let u = self.unit();
        let mut vals = [None; 6];
        for (ai, &c) in AXES.iter().enumerate() {
            if let Some(v) = w.take(c) {
                vals[ai] = Some(if ai < 3 { v * u } else { v });
            }
        }
        let fanuc = self.fanuc;
        self.change_offsets(|s| {
            for (ai, v) in vals.iter().enumerate() {
                if let Some(v) = v {
                    if fanuc {
                        s.coords.g52[ai] = *v;
                    } else {
                        s.coords.g92[ai] = *v;
                    }
                }
            }
            if !fanuc {
                s.coords.g92_applied = true;
            }
        });
        Ok(())
    }

    /// A whole number word used as a Fanuc magnification (P, I, J, K of G51): with a decimal
    /// point as written, without one in 0.001 units (the default magnification increment).
    fn magnification(&self, w: &Words, letter: char) -> Option<f64> {
        let (v, i) = w.vals[super::words::letter_index(letter)]?;
        let word = &self.prog.block(self.cur_block).words[i];
        match super::words::strip_neg(&word.value) {
            crate::nc::Expr::Number {
                has_point: false, ..
            } => Some(v / 1000.0),
            _ => Some(v),
        }
    }

    /// The transform-setting codes of group 0 and 16/22: G51/G50, G51.1/G50.1, G68/G69.
    pub(super) fn exec_transform(&mut self, w: &mut Words, code: u16, at: usize) -> R<()> {
        if self.comp.active.is_some() {
            return Err(self.err_at(
                at,
                format!(
                    "{} with cutter radius compensation on (G40 first)",
                    super::modal::g_name(code)
                ),
            ));
        }
        let u = self.unit();
        // Centre coordinates: absolute, or from the current position in G91; omitted axes
        // are the current position (Fanuc).
        let centre = |s: &Self, w: &mut Words, ai: usize| -> f64 {
            let cur = s.cur[ai];
            match w.take(AXES[ai]) {
                Some(v) if s.modal.absolute => v * u,
                Some(v) => (cur + v) * u,
                None => cur * u,
            }
        };
        match code {
            510 => {
                let mut c = [0.0; 3];
                for (ai, v) in c.iter_mut().enumerate() {
                    *v = centre(self, w, ai);
                }
                let p = self.magnification(w, 'P');
                let ijk = ['I', 'J', 'K'].map(|l| self.magnification(w, l));
                let k = match (p, ijk.iter().any(Option::is_some)) {
                    (Some(_), true) => {
                        return Err(self.err_at(at, "G51 with both P and I/J/K magnifications"))
                    }
                    (Some(p), false) => {
                        w.take('P');
                        [p; 3]
                    }
                    (None, true) => {
                        for l in ['I', 'J', 'K'] {
                            w.take(l);
                        }
                        ijk.map(|v| v.unwrap_or(1.0))
                    }
                    (None, false) => {
                        return Err(self.err_at(
                            at,
                            "G51 needs P (one magnification) or I/J/K (per axis); the control's default magnification is not known here",
                        ))
                    }
                };
                if k.iter()
                    .any(|&f| f == 0.0 || !f.is_finite() || f.abs() > 1e6)
                {
                    return Err(self.err_at(at, format!("G51 magnification {k:?} out of range")));
                }
                self.change_offsets(|s| s.coords.prog_xf.scale = Some((c, k)));
            }
            500 => self.change_offsets(|s| s.coords.prog_xf.scale = None),
            511 | 501 => {
                if !(0..3).any(|ai| w.has(AXES[ai])) {
                    return Err(self.err_at(
                        at,
                        format!(
                            "{} needs the axes to mirror (X, Y and/or Z)",
                            super::modal::g_name(code)
                        ),
                    ));
                }
                let mut m = self.coords.prog_xf.mirror;
                for (ai, slot) in m.iter_mut().enumerate() {
                    if !w.has(AXES[ai]) {
                        continue;
                    }
                    let c = centre(self, w, ai);
                    *slot = if code == 511 { Some(c) } else { None };
                }
                self.change_offsets(|s| s.coords.prog_xf.mirror = m);
            }
            680 => {
                let plane = self.modal.plane;
                let [a, b, _] = plane.axes();
                let c = [centre(self, w, a), centre(self, w, b)];
                let Some(r) = w.take('R') else {
                    return Err(self.err_at(
                        at,
                        "G68 needs R (the angle); the control's default angle is not known here",
                    ));
                };
                let (sin, cos) = r.to_radians().sin_cos();
                let rot = Rotation {
                    axes: [a, b],
                    center: c,
                    cos,
                    sin,
                };
                self.change_offsets(|s| s.coords.prog_xf.rotation = Some(rot));
            }
            690 => self.change_offsets(|s| s.coords.prog_xf.rotation = None),
            _ => unreachable!("not a transform code"),
        }
        Ok(())
    }
}
