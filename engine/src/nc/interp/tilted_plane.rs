//! The tilted working plane, the 3+2 setup 5-axis posts write (Fanuc G68.2 / G53.1 / G69;
//! LinuxCNC configurations remap the same codes):
//!
//! * `G68.2 X Y Z I J K` defines a feature coordinate system: its origin X Y Z in the work
//!   coordinates (always absolute, an omitted one is 0), its orientation by the Euler angles
//!   I J K in degrees, Z-X'-Z'' as Fanuc's G68.2 P0 and Heidenhain's PLANE EULER define
//!   them: turned I about Z, then J about the new X, then K about the new Z. From there on,
//!   X Y Z (and arc centres, cycle planes) are in the feature frame.
//! * `G53.1` turns the rotary axes so that the tool is normal to the plane (along the
//!   feature frame's +Z): the machine's inverse kinematics, the solution within the axis
//!   limits nearest the current angles. The tip holds its place on the part.
//! * `G69` ends it; the tool stays where it is.
//!
//! Moves under G68.2 are tool-tip moves (`Move::tool_tip`): X Y Z the tip on the part, A B C
//! only orienting the tool, as under G43.4. That is what the control does: it places the tip
//! in the feature frame whatever angle the table stands at.
//! Where the job reads plain moves as machine axes, G68.2 and G69 with the table turned hand
//! the position over between the two readings (machine axes <-> tip on the part), so the
//! path stays connected.

use super::modal::Plane;
use super::words::{Words, AXES};
use super::{Interp, R};
use crate::machine::{Pose, PoseIssueKind};
use crate::nc::arc::{sample_arc, ArcGeometry};
use crate::nc::FeedMode;

type M3 = [[f64; 3]; 3];

fn mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| a[r][k] * b[k][c]).sum()))
}

fn rot_z(deg: f64) -> M3 {
    let (s, c) = deg.to_radians().sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

fn rot_x(deg: f64) -> M3 {
    let (s, c) = deg.to_radians().sin_cos();
    [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
}

/// A G68.2 feature coordinate system, in mm of the work coordinates.
#[derive(Clone, Copy, Debug)]
pub(super) struct TiltedPlane {
    origin: [f64; 3],
    /// Rz(I)·Rx(J)·Rz(K): its columns are the feature frame's axes in work coordinates.
    rot: M3,
}

impl TiltedPlane {
    pub(super) fn from_euler(origin: [f64; 3], [i, j, k]: [f64; 3]) -> Self {
        TiltedPlane {
            origin,
            rot: mul(&mul(&rot_z(i), &rot_x(j)), &rot_z(k)),
        }
    }

    /// Feature frame point (mm) -> work coordinates (mm); rotary axes untouched.
    pub(super) fn apply(&self, q: &mut [f64; 6]) {
        let p = [q[0], q[1], q[2]];
        for (r, row) in self.rot.iter().enumerate() {
            q[r] = self.origin[r] + row[0] * p[0] + row[1] * p[1] + row[2] * p[2];
        }
    }

    /// Whether work axis `k` is (±) the feature frame's axis `k`: arcs about it stay arcs
    /// about a machine axis.
    pub(super) fn keeps_axis(&self, k: usize) -> bool {
        self.rot[k][k].abs() > 1.0 - 1e-12
    }

    /// The inverse of `apply` (the rotation's transpose).
    pub(super) fn invert(&self, q: &mut [f64; 6]) {
        let d = [
            q[0] - self.origin[0],
            q[1] - self.origin[1],
            q[2] - self.origin[2],
        ];
        for (c, v) in q.iter_mut().take(3).enumerate() {
            *v = (0..3).map(|r| self.rot[r][c] * d[r]).sum();
        }
    }
}

impl Interp<'_> {
    /// The tilted-plane codes of group 16: G68.2 sets the feature frame, G69 ends it. Whether
    /// the code was one of them (G68/G69 of Fanuc's plain rotation are not).
    pub(super) fn tilted_plane_code(&mut self, w: &mut Words, code: u16, at: usize) -> R<bool> {
        match code {
            682 => {
                self.tilted_plane_on(w, at)?;
                Ok(true)
            }
            690 if self.coords.tilt.is_some() => {
                self.tilted_plane_off();
                Ok(true)
            }
            680 | 510 | 511 if self.coords.tilt.is_some() => Err(self.err_at(
                at,
                format!(
                    "{} while a tilted working plane (G68.2) is active is not supported: G69 first",
                    super::modal::g_name(code)
                ),
            )),
            _ => Ok(false),
        }
    }

    fn tilted_plane_on(&mut self, w: &mut Words, at: usize) -> R<()> {
        if self.comp.active.is_some() {
            return Err(self.err_at(at, "G68.2 with cutter radius compensation on (G40 first)"));
        }
        if self.coords.tilt.is_some() {
            return Err(self.err_at(
                at,
                "G68.2 while a tilted working plane is already active: G69 first",
            ));
        }
        if self.program_transform_on() || self.coords.rot_xy[self.modal.cs] != 0.0 {
            return Err(self.err_at(
                at,
                "G68.2 with scaling, mirror image or a coordinate rotation on (G50/G50.1/G69, or a G10 L2 R rotation): not supported together",
            ));
        }
        // P selects how I J K (and Q R) describe the plane; only P0, Euler angles, here.
        if let Some(p) = w.take('P') {
            if p != 0.0 {
                return Err(self.err_at(
                    at,
                    format!("G68.2 P{p} is not supported: only P0 (Euler angles I J K) is"),
                ));
            }
        }
        let u = self.unit();
        let origin = [0, 1, 2].map(|ai| w.take(AXES[ai]).unwrap_or(0.0) * u);
        let angles = ['I', 'J', 'K'].map(|c| w.take(c).unwrap_or(0.0));
        if origin.iter().chain(&angles).any(|v| !v.is_finite()) {
            return Err(self.err_at(at, "G68.2 with a value that is not a finite number"));
        }
        let plane = TiltedPlane::from_euler(origin, angles);
        if let Some(tip) = self.machine_position_as_tip() {
            self.cur = self.from_machine(tip);
        }
        self.change_offsets(|s| s.coords.tilt = Some(plane));
        Ok(())
    }

    /// Where plain moves are read as machine axes and the rotary axes are turned (a post
    /// that positions A/C before G68.2): the current machine position as the part-frame tip
    /// the tool-tip moves under G68.2 start from. None where the two readings agree.
    fn machine_position_as_tip(&self) -> Option<[f64; 6]> {
        if self.tool.tcp || self.opts.tool_tip_reading {
            return None;
        }
        self.machine_to_tip()
    }

    /// The current position read as machine axes, as the part-frame tip with the same
    /// rotary angles; None without kinematics or with the rotary axes at zero (the two
    /// readings agree).
    fn machine_to_tip(&self) -> Option<[f64; 6]> {
        let k = self.opts.kinematics.as_ref()?;
        let mut here = self.to_machine(self.cur);
        if k.rotary_slots().iter().all(|&s| here[s] == 0.0) {
            return None;
        }
        let tip = k.forward(&here).tip;
        here[..3].copy_from_slice(&tip);
        Some(here)
    }

    /// G69 after G68.2: program coordinates are the work coordinates again. Where the job
    /// reads plain moves as machine axes and the rotary axes are turned, the position is
    /// handed back as the machine axes that hold the tip where it is, so the next move starts
    /// there and not at the tip's part coordinates read as axes.
    fn tilted_plane_off(&mut self) {
        self.change_offsets(|s| s.coords.tilt = None);
        if self.tool.tcp || self.opts.tool_tip_reading {
            return;
        }
        if let Some(axes) = self.tip_to_machine() {
            self.cur = self.from_machine(axes);
        }
    }

    /// The current position read as the part-frame tip, as the machine axes that hold the
    /// tip there; None without kinematics or with the rotary axes at zero.
    fn tip_to_machine(&self) -> Option<[f64; 6]> {
        let k = self.opts.kinematics.as_ref()?;
        let here = self.to_machine(self.cur);
        if k.rotary_slots().iter().all(|&s| here[s] == 0.0) {
            return None;
        }
        Some(k.machine_axes([here[0], here[1], here[2]], &here))
    }

    /// G43.4/G43.5 switched on or off (G43, G43.1, G49) where plain moves are read as
    /// machine axes and no tilted plane is active: the position handed over between the two
    /// readings as G68.2 and G69 do, so that the next move starts where the tool is (with
    /// the table turned, the machine axes are not the tip's part coordinates).
    pub(super) fn tool_tip_control_changed(&mut self, on: bool) {
        if self.opts.tool_tip_reading || self.coords.tilt.is_some() {
            return;
        }
        let handed = if on {
            self.machine_to_tip()
        } else {
            self.tip_to_machine()
        };
        if let Some(p) = handed {
            self.cur = self.from_machine(p);
        }
    }

    /// G53.1: the rotary axes turn (a rapid, the tip held on the part) so that the tool is
    /// normal to the G68.2 plane.
    pub(super) fn turn_tool_to_plane(&mut self, at: usize) -> R<()> {
        if self.coords.tilt.is_none() {
            return Err(self.err_at(
                at,
                "G53.1 without a tilted working plane: define it with G68.2 first",
            ));
        }
        let opts = self.opts;
        let kin = opts
            .kinematics
            .as_ref()
            .filter(|k| !k.rotary_slots().is_empty())
            .ok_or_else(|| {
                self.err_at(
                    at,
                    "G53.1 turns the rotary axes normal to the G68.2 plane, but this machine has no rotary axes (give a machine with kinematics xyzac, xyzbc, head_table, …); without G53.1 the program runs in the tilted frame with the tool as it stands",
                )
            })?;
        let here = self.to_machine(self.cur);
        // The plane's normal in the part frame: the feature +Z through every transform.
        let mut up = self.cur;
        up[2] += 1.0;
        let top = self.to_machine(up);
        let d = [top[0] - here[0], top[1] - here[1], top[2] - here[2]];
        let pose = Pose {
            tip: [here[0], here[1], here[2]],
            axis: d,
        };
        // The tip stays in the part frame, so the current angles alone decide "nearest".
        let solution = kin.inverse(&pose, &here, 0).map_err(|_| {
            let n = crate::vec3::norm(d);
            self.err_at(
                at,
                format!(
                    "G53.1: the tool cannot be normal to the G68.2 plane on this machine: its normal ({:.6}, {:.6}, {:.6}) is out of reach of a {:?} machine's rotary axes",
                    d[0] / n,
                    d[1] / n,
                    d[2] / n,
                    kin.kinematics
                ),
            )
        })?;
        for issue in &solution.issues {
            if let PoseIssueKind::LimitViolation {
                axis,
                value,
                min,
                max,
            } = issue.kind
            {
                if matches!(axis, 'A' | 'B' | 'C') {
                    return Err(self.err_at(
                        at,
                        format!(
                            "G53.1: the tool normal to the G68.2 plane needs {axis}{value:.3}, outside the machine's {axis} limits [{min}, {max}] (and so does the other solution)"
                        ),
                    ));
                }
            }
        }
        let mut to = here;
        for &s in kin.rotary_slots() {
            to[s] = solution.axes[s];
        }
        let target = self.from_machine(to);
        self.straight(true, target)
    }

    /// An arc in a feature frame plane that is tilted in the part frame: a move's arc turns
    /// about X, Y or Z only, so the arc is cut as chords within the spline tolerance (as
    /// G5 splines are), each a feed move at the block's F. Arguments as `arc_move_machine`'s.
    pub(super) fn tilted_arc_as_chords(
        &mut self,
        plane: Plane,
        start: [f64; 6],
        end: [f64; 6],
        center: [f64; 2],
        sweep: f64,
        turns: u32,
    ) -> R<()> {
        if self.modal.feed_mode == FeedMode::InverseTime {
            // Each chord would take the block's whole 1/F.
            return Err(self.err_block(
                "G2/G3 in a tilted G68.2 plane in inverse time (G93) is not supported: the arc is cut as chords; use G94",
            ));
        }
        let u = self.unit();
        let [a, b, n] = plane.axes();
        let mm = |p: [f64; 6]| -> [f64; 6] {
            std::array::from_fn(|i| if i < 3 { p[i] * u } else { p[i] })
        };
        let (s, e) = (mm(start), mm(end));
        let mut c = [0.0; 3];
        c[a] = center[0] * u;
        c[b] = center[1] * u;
        c[n] = s[n];
        let radius = |p: &[f64; 6]| (p[a] - c[a]).hypot(p[b] - c[b]);
        let geom = ArcGeometry {
            start: s,
            end: e,
            center: c,
            normal: plane.normal(),
            axes: plane.axes(),
            sweep,
            start_radius: radius(&s),
            end_radius: radius(&e),
            clockwise: sweep < 0.0,
            turns: turns.max(1),
        };
        let points = sample_arc(&geom, self.opts.spline_tolerance);
        let last = points.len() - 1;
        for (k, p) in points.into_iter().enumerate().skip(1) {
            // The last point is the programmed end exactly (no unit round trip).
            let to = if k == last {
                end
            } else {
                std::array::from_fn(|i| if i < 3 { p[i] / u } else { p[i] })
            };
            self.straight(false, to)?;
        }
        Ok(())
    }

    /// Under G68.2 the plane sets the tool axis: A B C words are refused.
    #[cold]
    pub(super) fn refuse_rotary_under_tilt(&self, w: &Words) -> R<()> {
        for c in ['A', 'B', 'C'] {
            if w.has(c) {
                return Err(self.err_word(
                    w,
                    c,
                    format!("{c} word while a tilted working plane (G68.2) is active: G53.1 sets the rotary axes; G69 first to turn them yourself"),
                ));
            }
        }
        Ok(())
    }
}
