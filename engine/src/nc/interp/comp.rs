//! Cutter radius compensation (G41/G42, G41.1/G42.1, G40) in the XY and XZ planes (G17, G18:
//! the plane's two axes in LinuxCNC's order, Z X in G18), as LinuxCNC 2.9
//! does it (`convert_straight_comp1/2`, `convert_arc_comp2`, the move queue of
//! `interp_queue.cc`), checked against its interpreter:
//!
//! * The entry move (the first after G41/G42) is a line that ends tangent to a circle of the
//!   tool radius around its programmed end. An arc as the entry move is refused here. In the
//!   Fanuc dialect it waits for the next move in the plane and ends perpendicular to that
//!   move's start instead (Fanuc start-up type A): no corner there.
//! * Each compensated move waits in a queue until the next one gives the corner: an outside
//!   (convex) corner gets an arc around the programmed corner (a rapid gets a straight), an
//!   inside (concave) corner moves the waiting move's end back to where the tool touches both
//!   sides. A move whose end would have to go back past its start would gouge: refused, naming
//!   the line. A compensated arc: LinuxCNC refuses it longer than programmed; the Fanuc
//!   dialect refuses it more than 180 degrees from the programmed sweep (the control's
//!   interference check), also where no corner moved its end.
//! * G40 flushes the queue; the next move (a line) goes from the compensated position to its
//!   programmed end. Offsets, cycles, G28/G30/G53 and tool changes are refused while it is on.

use super::modal::Plane;
use super::words::Words;
use super::{Interp, R};
use crate::nc::{Move, MoveKind};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// LinuxCNC's angle tolerance for corners (TOLERANCE_CONCAVE_CORNER), radians.
const SMALL: f64 = 0.05;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Side {
    Left,
    Right,
}

/// A compensated move waiting for the next one.
pub(super) struct Queued {
    pub(super) mv: Move,
    pub(super) kind: QueuedKind,
}

pub(super) enum QueuedKind {
    /// A line, with the direction of its programmed motion (gouge check).
    Straight { dir: [f64; 2] },
    /// An arc (program coordinates), with its sweep as first computed (0: do not check).
    Arc {
        center: [f64; 2],
        turn: i32,
        sweep: f64,
    },
    /// Anything else (a dwell): kept in order, never moved.
    Other,
}

/// Cutter radius compensation: whether it is on, in which plane, and where it left the tool.
pub(super) struct CompState {
    /// Cutter radius compensation, while G41/G42 is on.
    pub(super) active: Option<Comp>,
    /// The plane of the last G41/G42 (G17 or G18).
    pub(super) plane: Plane,
    /// After G40: where the tool is (machine frame), the start of the next move, which must
    /// be a line (LinuxCNC).
    pub(super) exit_start: Option<[f64; 6]>,
}

/// Compensation state while G41/G42 is on.
pub(super) struct Comp {
    pub(super) side: Side,
    /// Tool radius, program units.
    pub(super) radius: f64,
    pub(super) first: bool,
    /// The programmed (uncompensated) position, program coordinates.
    pub(super) prog: [f64; 6],
    pub(super) queue: Vec<Queued>,
    /// Start of the queued moves (LinuxCNC `endpoint`), when known.
    pub(super) endpoint: Option<[f64; 2]>,
    /// Fanuc: the entry (start-up) move waits for the next move in the plane, whose start
    /// direction decides where it ends (start-up type A).
    pub(super) startup: bool,
}

/// Sweep of an arc from (x1, y1) to (x2, y2) about (cx, cy), `turn` turns (+ CCW, - CW), as
/// LinuxCNC's `find_turn`.
fn find_turn(p1: [f64; 2], c: [f64; 2], turn: i32, p2: [f64; 2]) -> f64 {
    if turn == 0 {
        return 0.0;
    }
    let mut alpha = (p1[1] - c[1]).atan2(p1[0] - c[0]);
    let mut beta = (p2[1] - c[1]).atan2(p2[0] - c[0]);
    if turn > 0 {
        if beta <= alpha {
            beta += TAU;
        }
        beta - alpha + f64::from(turn - 1) * TAU
    } else {
        if alpha <= beta {
            alpha += TAU;
        }
        beta - alpha + f64::from(turn + 1) * TAU
    }
}

/// The compensated end of an arc ending at `e` about `c`: the tool radius `r` towards the
/// centre on the arc's inside, away from it outside.
fn arc_end_offset(inside: bool, c: [f64; 2], e: [f64; 2], r: f64) -> [f64; 2] {
    let gamma = if inside {
        (c[1] - e[1]).atan2(c[0] - e[0])
    } else {
        (e[1] - c[1]).atan2(e[0] - c[0])
    };
    [e[0] + r * gamma.cos(), e[1] + r * gamma.sin()]
}

fn inside(side: Side, turn: i32) -> bool {
    (side == Side::Left && turn > 0) || (side == Side::Right && turn < 0)
}

impl Interp<'_> {
    /// A point's two coordinates in the compensation plane (X Y in G17, Z X in G18).
    fn xy(&self, p: &[f64; 6]) -> [f64; 2] {
        let [a, b, _] = self.comp.plane.axes();
        [p[a], p[b]]
    }

    /// `p` with its two coordinates in the compensation plane replaced.
    fn with_xy(&self, p: &[f64; 6], x: f64, y: f64) -> [f64; 6] {
        let [a, b, _] = self.comp.plane.axes();
        let mut q = *p;
        q[a] = x;
        q[b] = y;
        q
    }

    /// G41/G42 (`dynamic`: G41.1/G42.1 with D the diameter).
    pub(super) fn comp_on(&mut self, w: &mut Words, left: bool, dynamic: bool, at: usize) -> R<()> {
        let name = match (left, dynamic) {
            (true, false) => "G41",
            (false, false) => "G42",
            (true, true) => "G41.1",
            (false, true) => "G42.1",
        };
        if self.modal.plane == super::Plane::YZ {
            return Err(self.err_at(
                at,
                format!(
                    "{name}: cutter radius compensation is supported in the XY (G17) and XZ (G18) planes only, as on LinuxCNC"
                ),
            ));
        }
        self.comp.plane = self.modal.plane;
        if self.comp.active.is_some() {
            return Err(self.err_at(
                at,
                format!("{name}: cutter radius compensation is already on (G40 first)"),
            ));
        }
        let u = self.unit();
        let mut radius = if dynamic {
            let Some(d) = w.take('D') else {
                return Err(self.err_at(at, format!("{name} needs D (the tool diameter)")));
            };
            w.take('L');
            d / 2.0
        } else {
            let number = match w.take('D') {
                Some(d) if d < 0.0 || d.fract() != 0.0 || d > u32::MAX as f64 => {
                    return Err(self.err_word(
                        w,
                        'D',
                        format!("{name} D{d}: D is a tool (offset) number"),
                    ));
                }
                Some(d) => {
                    if self.fanuc {
                        self.tool.radius_offset = Some(d as u32);
                    }
                    d as u32
                }
                None => self.tool.radius_offset.unwrap_or(self.tool.current),
            };
            match self.tool_radius(number) {
                Some((r, from_the_job)) => {
                    // CAM posts write G41 D1 both on the part's outline (control compensation,
                    // D the radius) and on a path already offset (wear compensation, D only
                    // the wear): the program does not say which, the offset table does.
                    if from_the_job && self.out.warned_radii.insert(number) {
                        self.out.warnings.push(self.err_at(
                            at,
                            format!("{name} D{number}: no tool table radius; the radius {r} mm of the job's tool {number} is taken (control compensation). A program posted with wear compensation (its path already offset) wants a tool table with D0 or G10 L1 P{number} R0"),
                        ));
                    }
                    r / u
                }
                // Fanuc's offset number 0 is the zero offset (D0/D00 cancels the radius while
                // G41/G42 stays modal): the path runs uncompensated, as the control runs it.
                None if self.fanuc && number == 0 => 0.0,
                // Simulating the uncompensated path would cut in the wrong place: refuse.
                None => {
                    return Err(self.err_at(
                        at,
                        format!("{name} D{number}: no radius for tool {number} (no diameter in the tool table, no G10 radius); give a tool table with D, G10 L1 P{number} R.., or G41.1/G42.1 D<diameter>"),
                    ))
                }
            }
        };
        let mut side = if left { Side::Left } else { Side::Right };
        if radius < 0.0 {
            radius = -radius;
            side = if left { Side::Right } else { Side::Left };
        }
        if radius == 0.0 {
            return Ok(());
        }
        self.comp.active = Some(Comp {
            side,
            radius,
            first: true,
            prog: self.cur,
            queue: Vec::new(),
            endpoint: None,
            startup: false,
        });
        Ok(())
    }

    /// Radius (mm) of tool/offset number `n`, and whether it is the caller's tool's: a G10
    /// radius (plus Fanuc wear), else half the tool table's diameter, else half the diameter
    /// of the caller's tool of that number (or of its one tool).
    pub(super) fn tool_radius(&self, n: u32) -> Option<(f64, bool)> {
        let program_own = self.tool.radii.get(&n).copied().or_else(|| {
            self.opts
                .tool_table
                .get(n)
                .and_then(|t| t.diameter)
                .map(|d| d / 2.0)
        });
        let (geometry, from_the_job) = match program_own {
            Some(r) => (r, false),
            None => {
                let d = self.opts.tool_diameters.get(&n).copied().or_else(|| {
                    let one = self.opts.tool_diameters.get(&0).copied();
                    one.filter(|_| n != 0 && self.opts.tool_diameters.len() == 1)
                })?;
                (d / 2.0, true)
            }
        };
        let wear = self.tool.radius_wear.get(&n).copied().unwrap_or(0.0);
        Some((geometry + wear, from_the_job))
    }

    /// G40: the waiting moves go out; the next move starts where the tool is and goes to its
    /// programmed end.
    pub(super) fn comp_off(&mut self) -> R<()> {
        let Some(c) = self.comp.active.as_ref() else {
            return Ok(());
        };
        let prog = c.prog;
        let here = self.xy(&self.cur);
        self.move_endpoint_and_flush(here)?;
        self.comp.exit_start = Some(self.to_machine(self.cur));
        self.cur = prog;
        self.comp.active = None;
        Ok(())
    }

    /// Moves still queued at the end of the program.
    pub(super) fn comp_finish(&mut self) -> R<()> {
        if self.comp.active.is_some() {
            let here = self.xy(&self.cur);
            self.move_endpoint_and_flush(here)?;
        }
        Ok(())
    }

    fn comp_mut(&mut self) -> &mut Comp {
        self.comp.active.as_mut().expect("compensation on")
    }

    fn dequeue(&mut self) -> R<()> {
        let c = self.comp_mut();
        c.endpoint = None;
        let queue = std::mem::take(&mut c.queue);
        if self.fanuc {
            // Fanuc checks every compensated arc, also one whose ends no corner moved (a
            // start moved by the corner before it past its end).
            for q in &queue {
                if let QueuedKind::Arc {
                    center,
                    turn,
                    sweep,
                } = q.kind
                {
                    let from = self.xy(&self.from_machine(q.mv.start));
                    let to = self.xy(&self.from_machine(q.mv.end));
                    if sweep != 0.0 {
                        self.fanuc_arc_check(q.mv.line, find_turn(from, center, turn, to), sweep)?;
                    }
                }
            }
        }
        for q in queue {
            self.push_now(q.mv)?;
        }
        Ok(())
    }

    fn set_endpoint(&mut self, p: [f64; 2]) {
        self.comp_mut().endpoint = Some(p);
    }

    fn enqueue(&mut self, mv: Move, kind: QueuedKind) -> R<()> {
        if self.out.moves_sent + self.out.moves.len() + self.comp_mut().queue.len()
            >= self.opts.max_moves
        {
            return self.push_now(mv);
        }
        self.comp_mut().queue.push(Queued { mv, kind });
        Ok(())
    }

    /// Move the end of every waiting move to `p` (program coordinates), refusing a move that
    /// would then run backwards (a gouge), and send them out.
    fn move_endpoint_and_flush(&mut self, p: [f64; 2]) -> R<()> {
        let endpoint = self.comp_mut().endpoint;
        let mut queue = std::mem::take(&mut self.comp_mut().queue);
        for q in &mut queue {
            let line = q.mv.line;
            let end_prog = self.from_machine(q.mv.end);
            let new_end = self.to_machine(self.with_xy(&end_prog, p[0], p[1]));
            match &mut q.kind {
                QueuedKind::Straight { dir } => {
                    if let Some(ep) = endpoint {
                        let dot = dir[0] * (p[0] - ep[0]) + dir[1] * (p[1] - ep[1]);
                        if dot < 0.0 {
                            let what = if q.mv.kind == MoveKind::Rapid {
                                "rapid"
                            } else {
                                "feed move"
                            };
                            return Err(self.comp_gouge(line, format!("the compensated {what} of line {line} would have to run backwards to reach this inside corner (the tool does not fit: it would gouge)")));
                        }
                    }
                    q.mv.end = new_end;
                }
                QueuedKind::Arc {
                    center,
                    turn,
                    sweep,
                } => {
                    let old_end = self.xy(&end_prog);
                    let r1 = (old_end[0] - center[0]).hypot(old_end[1] - center[1]);
                    let r2 = (p[0] - center[0]).hypot(p[1] - center[1]);
                    if (r1 - r2).abs() > 0.01 {
                        return Err(self.comp_gouge(line, format!("cutter compensation made an arc with mismatched radii on line {line} ({r1:.4}, {r2:.4})")));
                    }
                    let start_prog = self.from_machine(q.mv.start);
                    let from = endpoint.unwrap_or(self.xy(&start_prog));
                    let l2 = find_turn(from, *center, *turn, p);
                    if *sweep != 0.0 && endpoint.is_some() {
                        if self.fanuc {
                            self.fanuc_arc_check(line, l2, *sweep)?;
                        } else if l2.abs() > sweep.abs() + 0.001 {
                            return Err(self.comp_gouge(line, format!("the compensated arc of line {line} cannot reach this inside corner without gouging")));
                        }
                    }
                    // The arc again with its new end (through the transforms, if any).
                    let moved = self.arc_move(
                        start_prog,
                        self.with_xy(&end_prog, p[0], p[1]),
                        *center,
                        *turn,
                    )?;
                    q.mv.end = new_end;
                    if let (Some(g), Some(n)) = (q.mv.arc.as_mut(), moved.arc) {
                        g.end = new_end;
                        g.sweep = n.sweep;
                        g.end_radius = n.end_radius;
                    }
                }
                // A dwell waiting between two moves happens where the first one now ends.
                QueuedKind::Other => {
                    q.mv.start = new_end;
                    q.mv.end = new_end;
                }
            }
        }
        self.comp_mut().queue = queue;
        self.dequeue()?;
        self.set_endpoint(p);
        Ok(())
    }

    /// Fanuc start-up type A (the control's default, parameter SUP clear): the entry move
    /// ends where the tool stands perpendicular to the next move's start direction `dir` at
    /// the programmed point, whatever the corner there, so the next move starts without a
    /// corner of its own (`G41 X-5.` then `G3 I5.`, a helical hole, works with any tool
    /// smaller than the hole). LinuxCNC ends it perpendicular to the entry move itself.
    fn fanuc_startup(&mut self, dir: [f64; 2]) {
        let c = self.comp_mut();
        c.startup = false;
        let (side, radius, op) = (c.side, c.radius, c.prog);
        let len = dir[0].hypot(dir[1]);
        if len == 0.0 {
            return;
        }
        let (dx, dy) = (dir[0] / len, dir[1] / len);
        let (nx, ny) = if side == Side::Left {
            (-dy, dx)
        } else {
            (dy, -dx)
        };
        let [ox, oy] = self.xy(&op);
        let p = [ox + radius * nx, oy + radius * ny];
        // The entry line and anything queued after it (a Z move, a dwell) end there.
        let mut queue = std::mem::take(&mut self.comp_mut().queue);
        for q in &mut queue {
            let end_prog = self.from_machine(q.mv.end);
            let new_end = self.to_machine(self.with_xy(&end_prog, p[0], p[1]));
            match q.kind {
                QueuedKind::Straight { .. } => q.mv.end = new_end,
                QueuedKind::Other => {
                    q.mv.start = new_end;
                    q.mv.end = new_end;
                }
                QueuedKind::Arc { .. } => {}
            }
        }
        self.comp_mut().queue = queue;
        self.cur = self.with_xy(&self.cur, p[0], p[1]);
    }

    /// On the inside of an arc the tool must be smaller than the arc.
    fn check_tool_fits(&self, radius: f64, arc_radius: f64) -> R<()> {
        if arc_radius <= radius {
            return Err(self.err_block(format!(
                "cutter radius compensation: the tool radius ({radius}) is not less than the radius ({arc_radius:.4}) of the arc on line {}: the tool does not fit inside this arc",
                self.cur_line
            )));
        }
        Ok(())
    }

    /// Fanuc's interference check on a compensated arc (the control's alarm): its sweep `l2`
    /// more than 180 degrees from the programmed `sweep` (the tool would go round the other
    /// way). A compensated arc longer or shorter than programmed is run otherwise; LinuxCNC
    /// refuses any compensated arc longer than its programmed one.
    fn fanuc_arc_check(&self, line: u32, l2: f64, sweep: f64) -> R<()> {
        if (l2 - sweep).abs() > PI {
            return Err(self.comp_gouge(line, format!(
                "the compensated arc of line {line} would turn {:.1} degrees where the program turns {:.1} (more than 180 apart: interference, the tool would gouge)",
                l2.to_degrees(),
                sweep.to_degrees()
            )));
        }
        Ok(())
    }

    fn comp_gouge(&self, line: u32, msg: String) -> crate::nc::Diagnostic {
        let _ = line;
        self.err_block(format!("cutter radius compensation: {msg}"))
    }

    fn front_arc(&self) -> Option<([f64; 2], i32, [f64; 2])> {
        let c = self.comp.active.as_ref()?;
        let q = c.queue.first()?;
        match q.kind {
            QueuedKind::Arc { center, turn, .. } => {
                let end = self.from_machine(q.mv.end);
                Some((center, turn, self.xy(&end)))
            }
            _ => None,
        }
    }

    fn straight_move(&self, rapid: bool, from: [f64; 6], to: [f64; 6]) -> Move {
        let kind = if rapid {
            MoveKind::Rapid
        } else {
            MoveKind::Linear
        };
        self.base_move(kind, self.to_machine(from), self.to_machine(to))
    }

    fn arc_move(&self, from: [f64; 6], to: [f64; 6], center: [f64; 2], turn: i32) -> R<Move> {
        let sweep = find_turn(self.xy(&from), center, turn, self.xy(&to));
        self.arc_move_machine(
            self.comp.plane,
            from,
            to,
            center,
            sweep,
            turn.unsigned_abs().max(1),
        )
    }

    /// A G0/G1 move to `to` (programmed, program coordinates) with compensation on.
    pub(super) fn comp_straight(&mut self, rapid: bool, to: [f64; 6]) -> R<()> {
        if !rapid {
            self.check_feed()?;
        }
        if let Some(op) = self
            .comp
            .active
            .as_ref()
            .filter(|c| c.startup)
            .map(|c| c.prog)
        {
            let ([px, py], [ox, oy]) = (self.xy(&to), self.xy(&op));
            if px != ox || py != oy {
                self.fanuc_startup([px - ox, py - oy]);
            }
        }
        let c = self.comp.active.as_ref().expect("compensation on");
        let (side, radius, first, op) = (c.side, c.radius, c.first, c.prog);
        let cur = self.cur;
        let [px, py] = self.xy(&to);
        let [cx, cy] = self.xy(&cur);
        if first {
            let distance = (px - cx).hypot(py - cy);
            if distance <= radius {
                return Err(self.err_block(format!(
                    "cutter radius compensation: the entry move is not longer than the tool radius ({radius})"
                )));
            }
            let alpha = (py - cy).atan2(px - cx)
                + if side == Side::Left {
                    FRAC_PI_2
                } else {
                    -FRAC_PI_2
                };
            let end = self.with_xy(&to, px + radius * alpha.cos(), py + radius * alpha.sin());
            self.set_endpoint([cx, cy]);
            let mv = self.straight_move(rapid, cur, end);
            self.enqueue(
                mv,
                QueuedKind::Straight {
                    dir: [alpha.cos(), alpha.sin()],
                },
            )?;
            let fanuc = self.fanuc;
            let c = self.comp_mut();
            c.first = false;
            c.prog = to;
            c.startup = fanuc;
            self.cur = end;
            return Ok(());
        }
        let [opx, opy] = self.xy(&op);
        let mut end = self.with_xy(&to, cx, cy);
        // Where the next queued move starts.
        let mut from = cur;
        if !(px == opx && py == opy) {
            let mut theta = (cy - opy).atan2(cx - opx);
            let mut alpha = (py - opy).atan2(px - opx);
            let (beta, gamma) = if side == Side::Left {
                if theta < alpha {
                    theta += TAU;
                }
                (theta - alpha - FRAC_PI_2, FRAC_PI_2)
            } else {
                if alpha < theta {
                    alpha += TAU;
                }
                (alpha - theta - FRAC_PI_2, -FRAC_PI_2)
            };
            end = self.with_xy(
                &to,
                px + radius * (alpha + gamma).cos(),
                py + radius * (alpha + gamma).sin(),
            );
            let mid = [
                opx + radius * (alpha + gamma).cos(),
                opy + radius * (alpha + gamma).sin(),
            ];
            let front = self.front_arc();
            let concave = !(-SMALL..=PI + SMALL).contains(&beta)
                || (beta > PI - SMALL
                    && front.is_some_and(|(_, turn, _)| {
                        (side == Side::Right && turn > 0) || (side == Side::Left && turn < 0)
                    }));
            if !concave && beta > SMALL {
                // Outside corner: an arc around the programmed corner (a straight for G0).
                self.move_endpoint_and_flush([cx, cy])?;
                let corner_end = self.with_xy(&self.with_xy(&cur, mid[0], mid[1]), mid[0], mid[1]);
                let mut corner_end = corner_end;
                corner_end[3..].copy_from_slice(&to[3..]);
                let mv = if rapid {
                    self.straight_move(true, cur, corner_end)
                } else {
                    let turn = if side == Side::Left { -1 } else { 1 };
                    self.arc_move(cur, corner_end, [opx, opy], turn)?
                };
                self.push_now(mv)?;
                self.set_endpoint(mid);
                from = corner_end;
            } else if concave {
                match front {
                    None => {
                        // Line to line: back along the waiting move to where the tool
                        // touches both lines.
                        let halfcorner = (beta + PI) / 2.0;
                        if halfcorner == 0.0 {
                            return Err(self.err_block(
                                "cutter radius compensation: a zero-degree inside corner",
                            ));
                        }
                        let retreat = radius / halfcorner.tan();
                        let m = [
                            cx + retreat * (theta + gamma).cos(),
                            cy + retreat * (theta + gamma).sin(),
                        ];
                        self.move_endpoint_and_flush(m)?;
                        from = self.with_xy(&cur, m[0], m[1]);
                    }
                    Some((center, turn, arc_end)) => {
                        // Arc to line: along the waiting (compensated) arc.
                        let oldrad = (center[1] - arc_end[1]).hypot(center[0] - arc_end[0]);
                        let base_dir = (py - opy).atan2(px - opx);
                        let theta = if turn > 0 {
                            base_dir + FRAC_PI_2
                        } else {
                            base_dir - FRAC_PI_2
                        };
                        let phi = (center[1] - opy).atan2(center[0] - opx);
                        let ins = inside(side, turn);
                        let oldrad_uncomp = if ins {
                            oldrad + radius
                        } else {
                            oldrad - radius
                        };
                        let d = oldrad_uncomp * (theta - phi).cos();
                        let l = if ins {
                            (d - radius) / oldrad
                        } else {
                            (d + radius) / oldrad
                        };
                        if !(-1.0..=1.0).contains(&l) {
                            return Err(self.err_block("cutter radius compensation: arc to straight motion makes a corner the tool cannot fit in without gouging"));
                        }
                        let angle = match (ins, turn > 0) {
                            (true, true) | (false, false) => -l.acos() + theta + PI,
                            _ => l.acos() + theta + PI,
                        };
                        let m = [
                            center[0] + oldrad * angle.cos(),
                            center[1] + oldrad * angle.sin(),
                        ];
                        self.move_endpoint_and_flush(m)?;
                        from = self.with_xy(&cur, m[0], m[1]);
                    }
                }
            } else {
                // Straight on (collinear, or tangent arc to line).
                self.dequeue()?;
                self.set_endpoint([cx, cy]);
            }
        }
        let mv = self.straight_move(rapid, from, end);
        self.enqueue(
            mv,
            QueuedKind::Straight {
                dir: [px - opx, py - opy],
            },
        )?;
        self.comp_mut().prog = to;
        self.cur = end;
        Ok(())
    }

    /// A G2/G3 move with compensation on (not the entry move).
    pub(super) fn comp_arc(&mut self, w: &mut Words, cw: bool) -> R<()> {
        self.check_feed()?;
        let c = self.comp.active.as_ref().expect("compensation on");
        let (side, radius, first, op) = (c.side, c.radius, c.first, c.prog);
        let plane = self.comp.plane;
        self.off_plane_centre_word(w, plane)?;
        let target = self.comp_target(w)?;
        let turns = match w.take('P') {
            Some(p) if p.fract() != 0.0 || !(1.0..=super::MAX_ARC_TURNS).contains(&p) => {
                return Err(self.err_word(
                    w,
                    'P',
                    format!("arc P{p}: turns must be a whole number"),
                ))
            }
            Some(p) => p as i32,
            None => 1,
        };
        let turn = if cw { -turns } else { turns };
        if first {
            return self.comp_entry_arc(w, cw, turn, target);
        }
        let (ccx, ccy) = self.arc_center(w, cw, &op, &target)?;
        let center = [ccx, ccy];
        if self.comp.active.as_ref().is_some_and(|c| c.startup) {
            // The arc's start tangent.
            let [ox, oy] = self.xy(&op);
            let (rx, ry) = (ox - ccx, oy - ccy);
            self.fanuc_startup(if cw { [ry, -rx] } else { [-ry, rx] });
        }
        let cur = self.cur;
        let [cx, cy] = self.xy(&cur);
        let [opx, opy] = self.xy(&op);
        let [ex, ey] = self.xy(&target);
        let arc_radius = (ccx - ex).hypot(ccy - ey);
        let mut theta = (cy - opy).atan2(cx - opx);
        theta = if side == Side::Left {
            theta - FRAC_PI_2
        } else {
            theta + FRAC_PI_2
        };
        let mut delta = (ccy - opy).atan2(ccx - opx);
        let alpha = if cw {
            delta + FRAC_PI_2
        } else {
            delta - FRAC_PI_2
        };
        let mut beta = if side == Side::Left {
            theta - alpha
        } else {
            alpha - theta
        };
        if beta > 1.5 * PI {
            beta -= TAU;
        } else if beta < -FRAC_PI_2 {
            beta += TAU;
        }
        if inside(side, turn) {
            self.check_tool_fits(radius, arc_radius)?;
        } else {
            delta += PI;
        }
        let [nx, ny] = arc_end_offset(inside(side, turn), [ccx, ccy], [ex, ey], radius);
        let new_end = self.with_xy(&target, nx, ny);
        let sweep = find_turn([opx, opy], center, turn, [ex, ey]);
        let mut from = cur;
        if !(-SMALL..=PI + SMALL).contains(&beta)
            || ((beta - PI).abs() < SMALL && !inside(side, turn))
        {
            let m = match self.front_arc() {
                None => {
                    // Line to arc.
                    let cyy = arc_radius * (beta - FRAC_PI_2).sin();
                    let (dist, l, a) = if inside(side, turn) {
                        let dist = arc_radius - radius;
                        let l = (cyy + radius) / dist;
                        (
                            dist,
                            l,
                            if turn > 0 {
                                theta + l.asin()
                            } else {
                                theta - l.asin()
                            },
                        )
                    } else {
                        let dist = arc_radius + radius;
                        let l = (cyy - radius) / dist;
                        (
                            dist,
                            l,
                            if turn > 0 {
                                theta + PI - l.asin()
                            } else {
                                theta + PI + l.asin()
                            },
                        )
                    };
                    if !(-1.0..=1.0).contains(&l) {
                        return Err(self.err_block("cutter radius compensation: the arc in this inside corner cannot be reached by the tool without gouging"));
                    }
                    [ccx + dist * a.cos(), ccy + dist * a.sin()]
                }
                Some((pc, pturn, pend)) => {
                    // Arc to arc.
                    let oldrad = (pc[1] - pend[1]).hypot(pc[0] - pend[0]);
                    let newrad = if inside(side, turn) {
                        arc_radius - radius
                    } else {
                        arc_radius + radius
                    };
                    let arc_cc = (pc[1] - ccy).hypot(pc[0] - ccx);
                    if oldrad == 0.0 || arc_cc == 0.0 {
                        return Err(self.err_block("cutter radius compensation: arc to arc motion with both arcs on the same centre"));
                    }
                    let a = (oldrad * oldrad + arc_cc * arc_cc - newrad * newrad)
                        / (2.0 * oldrad * arc_cc);
                    if !(-1.0..=1.0).contains(&a) {
                        return Err(self.err_block("cutter radius compensation: arc to arc motion makes a corner the tool cannot fit in without gouging"));
                    }
                    let pullback = a.acos();
                    let cc_dir = (ccy - pc[1]).atan2(ccx - pc[0]);
                    let dir = match (inside(side, pturn), turn > 0) {
                        (true, true) | (false, false) => cc_dir + pullback,
                        _ => cc_dir - pullback,
                    };
                    [pc[0] + oldrad * dir.cos(), pc[1] + oldrad * dir.sin()]
                }
            };
            self.move_endpoint_and_flush(m)?;
            from = self.with_xy(&cur, m[0], m[1]);
        } else if beta > SMALL {
            // Outside corner: an arc around the programmed corner first.
            let mid = [opx + radius * delta.cos(), opy + radius * delta.sin()];
            self.dequeue()?;
            let mut corner_end = self.with_xy(&cur, mid[0], mid[1]);
            corner_end[3..].copy_from_slice(&target[3..]);
            let mv = self.arc_move(
                cur,
                corner_end,
                [opx, opy],
                if side == Side::Left { -1 } else { 1 },
            )?;
            self.push_now(mv)?;
            self.set_endpoint(mid);
            from = corner_end;
        } else {
            self.dequeue()?;
            self.set_endpoint([cx, cy]);
        }
        self.queue_comp_arc(from, new_end, center, turn, sweep, target)
    }

    /// The first move after G41/G42 as an arc: an arc through the programmed end that the
    /// tool, where it is now, touches; the tool ends offset from the programmed end.
    fn comp_entry_arc(&mut self, w: &mut Words, cw: bool, turn: i32, target: [f64; 6]) -> R<()> {
        let c = self.comp.active.as_ref().expect("compensation on");
        let (side, radius) = (c.side, c.radius);
        let cur = self.cur;
        let [cx, cy] = self.xy(&cur);
        let [ex, ey] = self.xy(&target);
        if (ex - cx).hypot(ey - cy) <= radius {
            return Err(self.err_block(format!(
                "cutter radius compensation: the entry arc's end is not farther than the tool radius ({radius}) from the start"
            )));
        }
        let (ccx, ccy) = self.arc_center(w, cw, &cur, &target)?;
        let arc_radius = (ccx - cx).hypot(ccy - cy);
        if inside(side, turn) {
            self.check_tool_fits(radius, arc_radius)?;
        }
        let [nx, ny] = arc_end_offset(inside(side, turn), [ccx, ccy], [ex, ey], radius);
        // The compensated arc's centre: on the line from its end towards the programmed
        // centre, equally far from its start and its end.
        let b_len = (cy - ny).hypot(cx - nx) / 2.0;
        let ab_ang = (ccy - ny).atan2(ccx - nx);
        let a_ang = (cy - ny).atan2(cx - nx) - ab_ang;
        if a_ang.cos().abs() < 1e-4 {
            return Err(self.err_block("cutter radius compensation: the entry arc cannot be compensated (tool radius not less than the arc radius)"));
        }
        let c_len = b_len / a_ang.cos();
        let center = [nx + c_len * ab_ang.cos(), ny + c_len * ab_ang.sin()];
        let new_end = self.with_xy(&target, nx, ny);
        let sweep = find_turn([cx, cy], center, turn, [nx, ny]);
        self.queue_comp_arc(cur, new_end, center, turn, sweep, target)
    }

    /// The compensated arc from `from` to `new_end` waits in the queue for the next move's
    /// corner; the programmed position is `target`.
    fn queue_comp_arc(
        &mut self,
        from: [f64; 6],
        new_end: [f64; 6],
        center: [f64; 2],
        turn: i32,
        sweep: f64,
        target: [f64; 6],
    ) -> R<()> {
        let mv = self.arc_move(from, new_end, center, turn)?;
        self.enqueue(
            mv,
            QueuedKind::Arc {
                center,
                turn,
                sweep,
            },
        )?;
        let c = self.comp_mut();
        c.first = false;
        c.prog = target;
        self.cur = new_end;
        Ok(())
    }

    /// The programmed end of a move with compensation on: absent and incremental words count
    /// from the programmed position, not the compensated one.
    pub(super) fn comp_target(&self, w: &mut Words) -> R<[f64; 6]> {
        let c = self.comp.active.as_ref().expect("compensation on");
        let base = if c.first { self.cur } else { c.prog };
        let mut t = base;
        for (ai, &l) in super::words::AXES.iter().enumerate() {
            if let Some(v) = w.take(l) {
                t[ai] = if self.modal.absolute { v } else { base[ai] + v };
            }
        }
        self.apply_polar(w, &mut t)?;
        Ok(t)
    }
}
