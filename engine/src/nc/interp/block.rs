//! One block: its steps in LinuxCNC's order of execution (feed mode, F, S, T, M codes, dwell,
//! plane, units, offsets, distance modes, group 0 codes, motion, stops).

use super::corners::PendingCorner;
use super::modal::{g_group, g_name, m_group, Motion, Plane};
use super::words::{letter_index, Words, AXES};
use super::{Interp, MM_PER_INCH, R};
use crate::nc::view::BlockView;
use crate::nc::{Dialect, FeedMode, MoveKind, SpindleDir, ToolChangeTo};

impl<'p> Interp<'p> {
    pub(super) fn exec_block(&mut self, idx: usize, b: &BlockView<'p>) -> R<()> {
        if self.is_macro_call(b) {
            return self.macro_call(b);
        }
        // The G and M lists keep their allocations from block to block.
        let mut w = Words {
            vals: [None; 26],
            used: [false; 26],
            gs: std::mem::take(&mut self.spare_gs),
            ms: std::mem::take(&mut self.spare_ms),
            corner_r: None,
            corner_c: None,
            polar_r: None,
            polar_a: None,
            polar_any: false,
            polar_open: false,
            transform: false,
            machine_mode: false,
        };
        w.gs.clear();
        w.ms.clear();
        let result = self.exec_words(idx, b, &mut w);
        self.spare_gs = w.gs;
        self.spare_ms = w.ms;
        result
    }

    pub(super) fn exec_words(&mut self, idx: usize, b: &BlockView<'p>, w: &mut Words) -> R<()> {
        self.motion_prev = self.motion;
        let avals = self.read_words(b, w)?;
        for (a, v) in b.assignments.iter().zip(avals) {
            self.assign(a, v)?;
        }
        if w.polar_any {
            self.check_polar_words(w)?;
        }
        // Fanuc comma-less corners: R and C on a G1 block (CCR parameter).
        if self.fanuc && self.corners_without_comma {
            let g1 = w.g(10).is_some()
                || (self.motion == Some(Motion::Linear)
                    && !w.gs.iter().any(|g| g_group(g.0) == Some(1)));
            if g1 {
                for c in ['R', 'C'] {
                    let li = letter_index(c);
                    if let Some(v) = w.vals[li].take() {
                        let slot = if c == 'R' {
                            &mut w.corner_r
                        } else {
                            &mut w.corner_c
                        };
                        if slot.is_some() {
                            return Err(self.err_at(
                                self.word_pos(v.1),
                                format!("both {c} and ,{c} in one block"),
                            ));
                        }
                        *slot = Some(v);
                    }
                }
            }
            if w.has('C') {
                return Err(self.err_word(w, 'C', "C word: with comma-less corners (CCR) C is a chamfer, only on G1 blocks; the C axis is not available"));
            }
        }
        if w.corner_r.is_some() && w.corner_c.is_some() {
            let (_, i) = w.corner_c.expect("checked");
            return Err(self.err_at(
                self.word_pos(i),
                "corner rounding and chamfer in the same block",
            ));
        }

        // 3. feed mode
        for (code, mode) in [
            (930, FeedMode::InverseTime),
            (940, FeedMode::PerMin),
            (950, FeedMode::PerRev),
        ] {
            if w.g(code).is_some() {
                if self.modal.feed_mode != mode
                    && (mode == FeedMode::InverseTime
                        || self.modal.feed_mode == FeedMode::InverseTime)
                {
                    // LinuxCNC: entering or leaving G93 forgets the feed, so an inverse-time F
                    // is never taken as a feed per minute (or the reverse).
                    self.modal.feed_word = 0.0;
                }
                self.modal.feed_mode = mode;
            }
        }
        // 4. F
        if let Some(f) = w.take('F') {
            if f < 0.0 {
                return Err(self.err_word(w, 'F', "negative F word"));
            }
            self.modal.feed_word = f;
            self.modal.feed_factor = self.unit();
        } else if self.modal.feed_mode == FeedMode::InverseTime {
            // Inverse time: F applies to its own block only.
            self.modal.feed_word = 0.0;
        }
        // 5. S
        if let Some(s) = w.take('S') {
            if s < 0.0 {
                return Err(self.err_word(w, 'S', "negative S word"));
            }
            self.modal.speed = s;
        }
        // 6. T
        if let Some(t) = w.take('T') {
            if t < 0.0 || t.fract() != 0.0 || t > u32::MAX as f64 {
                return Err(self.err_word(w, 'T', format!("T{t} is not a tool number")));
            }
            self.selected_tool = Some(t as u32);
            if !self.selected_tools.iter().any(|&(n, _)| n == t as u32) {
                self.selected_tools.push((t as u32, self.program_line()));
            }
        }
        // 8-10 act on M codes only; most CAM blocks have none.
        if !w.ms.is_empty() {
            // 8. M6 / M61
            if let Some(i) = w.m(6).filter(|_| self.comp.is_some()) {
                return Err(self.err_at(
                    self.word_pos(i),
                    "tool change with cutter radius compensation on (G40 first)",
                ));
            }
            if w.m(6).is_some() {
                let t = self.selected_tool.unwrap_or(self.tool);
                self.tool = t;
                let p = self.to_machine(self.cur);
                let m = self.base_move(MoveKind::ToolChange, p, p);
                self.push(m)?;
                // The change takes the tip where the machine changes tools: the next move
                // starts there, not where the last tool stopped.
                if let Some(to) = self.opts.tool_change {
                    let mut q = p;
                    match to {
                        ToolChangeTo::Position([x, y, z]) => {
                            q[0] = x;
                            q[1] = y;
                            q[2] = z;
                        }
                        ToolChangeTo::RaiseTo(z) => q[2] = q[2].max(z),
                    }
                    self.cur = self.from_machine(q);
                }
            }
            if let Some(i) = w.m(61) {
                let Some(q) = w.take('Q') else {
                    return Err(self.err_at(self.word_pos(i), "M61 needs a Q word (tool number)"));
                };
                if q < 0.0 || q.fract() != 0.0 || q > u32::MAX as f64 {
                    return Err(self.err_word(w, 'Q', format!("Q{q} is not a tool number")));
                }
                self.tool = q as u32;
            }
            // 9. spindle
            if w.m(3).is_some() {
                self.modal.spindle = SpindleDir::Cw;
            }
            if w.m(4).is_some() {
                self.modal.spindle = SpindleDir::Ccw;
            }
            if w.m(5).is_some() {
                self.modal.spindle = SpindleDir::Off;
            }
            // 10. save / restore modal state
            if w.m(70).is_some() {
                self.saved_modal = Some(self.modal.clone());
            }
            if w.m(71).is_some() {
                self.saved_modal = None;
            }
            if let Some(i) = w.m(72) {
                let Some(m) = self.saved_modal.clone() else {
                    return Err(self.err_at(self.word_pos(i), "M72 without state saved by M70"));
                };
                self.restore_modal(&m);
            }
            if let Some(i) = w.m(73) {
                let m = self.modal.clone();
                let Some(f) = self.frames.last_mut() else {
                    return Err(self.err_at(self.word_pos(i), "M73 outside a subroutine"));
                };
                f.auto_restore = Some(m);
            }
        }
        // 11-13. coolant, overrides, passthrough M codes: no effect on motion. M50-M53
        // (feed and spindle override, adaptive feed, feed stop) take P0/P1: read, no effect
        // (a block with G codes leaves its P to them).
        if !w.ms.is_empty() && w.gs.is_empty() && w.ms.iter().any(|m| (50..=53).contains(&m.0)) {
            w.take('P');
        }
        // 14-22 act on G codes only; most CAM blocks have none.
        if !w.gs.is_empty() {
            // 14. dwell
            if let Some(i) = w.g(40) {
                let secs = if self.fanuc {
                    match (w.take('P'), w.take('X')) {
                        (Some(_), Some(_)) => {
                            return Err(self.err_at(self.word_pos(i), "G4 with both P and X"))
                        }
                        (Some(p), None) => p / 1000.0,
                        (None, Some(x)) => x,
                        (None, None) => {
                            return Err(self.err_at(self.word_pos(i), "G4 needs P (ms) or X (s)"))
                        }
                    }
                } else {
                    match w.take('P') {
                        Some(p) => p,
                        None => {
                            return Err(self.err_at(self.word_pos(i), "G4 needs a P word (seconds)"))
                        }
                    }
                };
                if secs < 0.0 {
                    return Err(self.err_at(self.word_pos(i), "negative dwell time"));
                }
                self.dwell(secs)?;
            }
            // 15. plane
            for (code, plane) in [(170, Plane::XY), (180, Plane::XZ), (190, Plane::YZ)] {
                if let Some(i) = w.g(code) {
                    if self.comp.is_some() && plane != self.modal.plane {
                        return Err(self.err_at(
                            self.word_pos(i),
                            "plane change with cutter radius compensation on (G40 first)",
                        ));
                    }
                    self.modal.plane = plane;
                }
            }
            // 16. units
            for (code, metric) in [(200, false), (210, true)] {
                if w.g(code).is_some() && self.modal.metric != metric {
                    let f = if metric {
                        MM_PER_INCH
                    } else {
                        1.0 / MM_PER_INCH
                    };
                    for i in 0..3 {
                        self.cur[i] *= f;
                    }
                    self.modal.metric = metric;
                }
            }
            // 17. cutter radius compensation
            if w.g(400).is_some() {
                self.comp_off()?;
            }
            for (code, left, dynamic) in [
                (410u16, true, false),
                (420, false, false),
                (411, true, true),
                (421, false, true),
            ] {
                if let Some(i) = w.g(code) {
                    self.comp_on(w, left, dynamic, self.word_pos(i))?;
                }
            }
            // 18. tool length offset; G43.4/G43.5 (tool-centre-point control) take it as G43
            // does and make X Y Z the tool tip on the part from here to G43/G43.1/G49.
            let tcp = w.g(434).or(w.g(435));
            if let Some(i) = w.g(435) {
                if ['I', 'J', 'K'].iter().any(|&c| w.has(c)) {
                    return Err(self.err_at(
                        self.word_pos(i),
                        "G43.5 with a tool-axis vector (I J K) is not supported: program the rotary angles (A/B/C) under G43.4".to_string(),
                    ));
                }
            }
            if let Some(i) = w.g(430).or(tcp) {
                let h = match w.take('H') {
                    Some(h) => {
                        if h < 0.0 || h.fract() != 0.0 || h > u32::MAX as f64 {
                            return Err(self.err_word(
                                w,
                                'H',
                                format!("H{h} is not a tool number"),
                            ));
                        }
                        h as u32
                    }
                    None => self.tool,
                };
                // Fanuc: a D here is the radius offset number later G41/G42 take.
                if self.fanuc {
                    if let Some(d) = w.take('D') {
                        if d < 0.0 || d.fract() != 0.0 || d > u32::MAX as f64 {
                            return Err(self.err_word(
                                w,
                                'D',
                                format!("D{d} is not an offset number"),
                            ));
                        }
                        self.radius_offset = Some(d as u32);
                    }
                }
                let off = match self.tool_length(h) {
                    Some(z) => z,
                    None => {
                        if self.warned_tools.insert(h) {
                            self.warnings.push(self.err_at(
                                self.word_pos(i),
                                format!(
                                    "G43: tool {h} is not in the tool table; tool length 0 used"
                                ),
                            ));
                        }
                        0.0
                    }
                };
                self.set_tlo(Some(off));
                self.tcp = tcp.is_some();
            }
            if w.g(431).is_some() {
                self.tcp = false;
                // G43.1: the offset comes from the Z word (program units).
                let Some(z) = w.take('Z') else {
                    return Err(self.err_block("G43.1 needs a Z word (tool length)"));
                };
                if AXES.iter().any(|&c| c != 'Z' && w.has(c)) {
                    return Err(self.err_block("G43.1 takes only a Z offset here"));
                }
                let z = z * self.unit();
                self.set_tlo(Some(z));
            }
            if w.g(490).is_some() {
                self.tcp = false;
                self.set_tlo(None);
            }
            // 19. coordinate system
            for (k, code) in [540u16, 550, 560, 570, 580, 590, 591, 592, 593]
                .iter()
                .enumerate()
            {
                if let Some(i) = w.g(*code) {
                    self.select_cs(k, i)?;
                }
            }
            // Extended work offsets: Fanuc G54.1 P1..P48, Haas G154 P1..P99.
            for code in [541u16, 1540] {
                if let Some(i) = w.g(code) {
                    let k = self.extended_cs(w, code, i)?;
                    self.select_cs(k, i)?;
                }
            }
            // 20. path control: blending changes no end point.
            if w.g(640).is_some() {
                w.take('P');
                w.take('Q');
            }
            // 21. distance modes
            if w.g(900).is_some() {
                self.modal.absolute = true;
            }
            if w.g(910).is_some() {
                self.modal.absolute = false;
            }
            if w.g(901).is_some() {
                self.modal.arc_absolute = true;
            }
            if w.g(911).is_some() {
                self.modal.arc_absolute = false;
            }
            // 22. retract mode
            if w.g(980).is_some() {
                self.modal.retract_r_plane = false;
            }
            if w.g(990).is_some() {
                self.modal.retract_r_plane = true;
            }
        }
        // Fanuc: an H without G43 (posts write `G53 Z0 H0`, `G91 G28 Z0 H0`) changes the
        // length offset number of the active compensation; H0 is always zero.
        if self.fanuc && w.has('H') && w.g(430).is_none() {
            self.fanuc_h_word(w)?;
        }
        // 22a. Fanuc transforms: scaling, mirror image, rotation, polar mode.
        if w.transform {
            for k in 0..w.gs.len() {
                if matches!(w.gs[k].0, 500 | 510 | 501 | 511 | 680 | 690 | 150 | 160) {
                    self.fanuc_transform_code(w, k)?;
                }
            }
        }
        if self.polar_mode {
            self.fanuc_polar_words(w);
        }
        // 23. group 0 codes that use axis words, and 24. motion.
        let group0 =
            w.gs.iter()
                .find(|g| g_group(g.0) == Some(0) && g.0 != 40 && g.0 != 530)
                .copied();
        // G80: LinuxCNC cancels the motion mode; on a Fanuc control canned cycles are a group
        // of their own, so the G0/G1/G2/G3 mode from before the cycle is back.
        if w.g(800).is_some() {
            self.motion = self.after_g80();
            self.cycle_il = None;
        }
        let block_motion =
            w.gs.iter()
                .find(|g| g_group(g.0) == Some(1) && g.0 != 800)
                .or_else(|| w.gs.iter().find(|g| g.0 == 800))
                .copied();
        let g53 = w.g(530);
        if let (Some((g0, i0)), Some((gm, _))) = (group0, block_motion) {
            if matches!(g0, 100 | 280 | 300 | 520 | 920) && gm != 800 && w.has_axis() {
                return Err(self.err_at(
                    self.word_pos(i0),
                    format!("{} and {} both use axis words", g_name(g0), g_name(gm)),
                ));
            }
        }
        if let Some((g0, i0)) = group0 {
            if self.comp.is_some() && matches!(g0, 100 | 280 | 300 | 520 | 920 | 921 | 922 | 923) {
                return Err(self.err_at(
                    self.word_pos(i0),
                    format!(
                        "{} with cutter radius compensation on (G40 first)",
                        g_name(g0)
                    ),
                ));
            }
            self.exec_group0(w, g0, i0)?;
        }
        if let Some((gm, _)) = block_motion {
            self.motion = match gm {
                0 => Some(Motion::Rapid),
                10 => Some(Motion::Linear),
                20 => Some(Motion::Arc { cw: true }),
                30 => Some(Motion::Arc { cw: false }),
                331 => Some(Motion::RigidTap),
                382..=385 => Some(Motion::Probe(gm)),
                50 => Some(Motion::Spline { cubic: true }),
                51 => Some(Motion::Spline { cubic: false }),
                52 => Some(Motion::Nurbs),
                53 => {
                    self.nurbs_end(self.word_pos(w.g(53).expect("in block")))?;
                    None
                }
                800 => self.after_g80(),
                g => Some(Motion::Cycle(g / 10)),
            };
            if matches!(gm, 0 | 10 | 20 | 30) {
                self.motion_01 = self.motion;
            }
            if gm == 800 {
                self.cycle_il = None;
                if w.has_axis()
                    && self.motion.is_none()
                    && !matches!(group0, Some((100 | 280 | 300 | 520 | 920, _)))
                {
                    return Err(self.err_block("axis words with G80 (motion cancelled)"));
                }
            }
        }
        let axis_users = matches!(group0, Some((100 | 280 | 300 | 520 | 920, _)));
        let mut moved = false;
        let corner = w
            .corner_r
            .or(w.corner_c)
            .map(|(v, i)| (v, i, w.corner_c.is_some()));
        if w.has_axis() && !axis_users {
            let motion = match self.motion {
                Some(m) => m,
                None => self.motion_after_g80()?,
            };
            if let Some(i) = g53 {
                if !matches!(motion, Motion::Rapid | Motion::Linear) {
                    return Err(self.err_at(self.word_pos(i), "G53 needs G0 or G1"));
                }
            }
            self.exec_motion(w, motion, g53.is_some(), corner)?;
            moved = true;
        } else if matches!(block_motion, Some((52, _))) && !axis_users {
            // G5.2 with only a weight for its first point (P) or an order (L).
            self.exec_motion(w, Motion::Nurbs, false, None)?;
        } else if matches!(block_motion, Some((0 | 10 | 20 | 30, _)))
            && !axis_users
            && corner.is_none()
        {
            // LinuxCNC: an explicit G0/G1 without axis words still makes a (zero-length) move,
            // and G2/G3 with only a centre makes a full circle.
            let motion = self.motion.expect("set above");
            self.exec_motion(w, motion, g53.is_some(), None)?;
        } else if let Some(i) = g53 {
            if !axis_users {
                return Err(self.err_at(self.word_pos(i), "G53 without axis words"));
            }
        } else if let Some((_, i, _)) = corner {
            return Err(self.err_at(
                self.word_pos(i),
                "corner rounding/chamfer on a block without a G1 move",
            ));
        }
        if self
            .pending_corner
            .as_ref()
            .map(|p| p.block != idx)
            .unwrap_or(false)
            && w.has_axis()
        {
            // exec_motion resolved it or failed; anything left is an error below.
        }
        // 25. stops, and Fanuc subprogram calls and returns (after the block's motion).
        if w.m(2).is_some() || w.m(30).is_some() {
            self.ended = true;
        }
        if !w.ms.is_empty() {
            if let Some(i) = w.m(98) {
                self.call_subprogram(w, i)?;
            }
            if let Some(i) = w.m(99) {
                self.return_subprogram(w, i)?;
            }
        }
        if w.transform && w.g(670).is_some() {
            if !self.fanuc {
                return Err(self.err_at(
                    self.word_pos(w.g(670).expect("in block")),
                    "G67 cancels a Fanuc G66 modal macro call; not valid with dialect linuxcnc",
                ));
            }
            // The last G66 first (nested modal calls end in reverse order).
            self.modal_calls.pop();
        } else if moved && !self.modal_calls.is_empty() {
            self.modal_macro_after_move()?;
        }
        if w.m(60).is_some() {
            return Err(self.err_block("M60 pallet change is not supported"));
        }
        if w.polar_any {
            self.unused_polar(w)?;
        }
        // Fanuc: a D anywhere (`T1 D1 M6`) selects the radius offset later G41/G42 take.
        if self.fanuc && !w.used[letter_index('D')] {
            if let Some(d) = w.take('D') {
                if d < 0.0 || d.fract() != 0.0 || d > u32::MAX as f64 {
                    return Err(self.err_word(w, 'D', format!("D{d} is not an offset number")));
                }
                self.radius_offset = Some(d as u32);
            }
        }
        // Every word must have been used by something; P and Q go with a machine's own M code
        // (M62 P1, M66 P0 L3 Q5: parameters we cannot interpret).
        if !w.ms.is_empty() && w.ms.iter().any(|m| m_group(m.0).is_none()) {
            for c in ['L', 'P', 'Q'] {
                w.used[letter_index(c)] = true;
            }
        }
        if w.machine_mode {
            for c in ['P', 'Q', 'R', 'E'] {
                w.used[letter_index(c)] = true;
            }
        }
        for li in 0..26 {
            if let Some((v, i)) = w.vals[li] {
                if !w.used[li] {
                    let c = (b'A' + li as u8) as char;
                    let hint = if c == 'R' && self.motion == Some(Motion::Linear) {
                        " (Fanuc corner rounding is written ,R; for controls that take R/C without the comma set fanuc_corners_without_comma)"
                    } else {
                        ""
                    };
                    return Err(self.err_at(
                        self.word_pos(i),
                        format!("{c}{v} is not used by any code in this block{hint}"),
                    ));
                }
            }
        }
        Ok(())
    }

    pub(super) fn exec_motion(
        &mut self,
        w: &mut Words,
        motion: Motion,
        g53: bool,
        corner: Option<(f64, usize, bool)>,
    ) -> R<()> {
        if !matches!(motion, Motion::Cycle(_)) {
            self.cycle_il = None;
        }
        if self.modal.feed_mode == FeedMode::InverseTime
            && matches!(motion, Motion::Linear | Motion::Arc { .. })
            && self.modal.feed_word <= 0.0
        {
            return Err(self.err_block(
                "G1/G2/G3 in inverse time mode (G93) needs an F word in the same block",
            ));
        }
        if self.comp.is_some() {
            if g53 {
                return Err(self.err_block("G53 with cutter radius compensation on"));
            }
            if let Some((_, i, _)) = corner {
                return Err(self.err_at(
                    self.word_pos(i),
                    "corner rounding/chamfer with cutter radius compensation on",
                ));
            }
            return match motion {
                Motion::Rapid | Motion::Linear => {
                    let to = self.comp_target(w)?;
                    self.comp_straight(matches!(motion, Motion::Rapid), to)
                }
                Motion::Arc { cw } => self.comp_arc(w, cw),
                _ => Err(self.err_block(
                    "canned cycles, tapping and probing are not allowed with cutter radius compensation on (G40 first)",
                )),
            };
        }
        if self.exit_start.is_some() && matches!(motion, Motion::Arc { .. }) {
            return Err(self.err_block(
                "the move just after G40 (cutter compensation off) must be a line, not an arc",
            ));
        }
        let pending = self.pending_corner.take();
        if pending.is_some() && !matches!(motion, Motion::Linear) {
            let p = pending.expect("checked");
            return Err(self.err_at(
                p.word_pos,
                "corner rounding/chamfer must be followed by a G1 move (the next move here is not G1)",
            ));
        }
        match motion {
            Motion::Rapid | Motion::Linear => {
                let to = self.target(w, g53)?;
                if let Some(p) = pending {
                    self.resolve_corner(p, to)?;
                }
                if let Some((size, i, chamfer)) = corner {
                    if g53 {
                        return Err(
                            self.err_at(self.word_pos(i), "corner rounding/chamfer with G53")
                        );
                    }
                    if motion != Motion::Linear {
                        return Err(
                            self.err_at(self.word_pos(i), "corner rounding/chamfer needs G1")
                        );
                    }
                    if size <= 0.0 {
                        return Err(self.err_at(self.word_pos(i), "corner size must be positive"));
                    }
                    self.straight(false, to)?;
                    self.pending_corner = Some(PendingCorner {
                        move_index: self.moves.len() - 1,
                        block: self.cur_block,
                        word_pos: self.word_pos(i),
                        chamfer,
                        size,
                        corner: to,
                        plane: self.modal.plane,
                    });
                    return Ok(());
                }
                self.straight(matches!(motion, Motion::Rapid), to)
            }
            Motion::Arc { cw } => self.arc(w, cw),
            Motion::RigidTap => self.rigid_tap(w),
            Motion::Probe(g) => self.probe(w, g),
            Motion::Cycle(g) => self.cycle(w, g),
            Motion::Spline { cubic } => self.spline(w, cubic),
            Motion::Nurbs => {
                let starts = self.motion_prev != Some(Motion::Nurbs);
                self.nurbs_point(w, starts)
            }
        }
    }

    /// G51/G50, G51.1/G50.1, G68/G69, G16/G15 (the block's G code number `k`): Fanuc only.
    #[cold]
    fn fanuc_transform_code(&mut self, w: &mut Words, k: usize) -> R<()> {
        let (code, i) = w.gs[k];
        if !self.fanuc {
            return Err(self.err_at(
                self.word_pos(i),
                format!(
                    "{} is Fanuc ({}); not valid with dialect linuxcnc{}",
                    g_name(code),
                    match code {
                        500 | 510 => "scaling",
                        501 | 511 => "programmable mirror image",
                        680 | 690 => "coordinate rotation",
                        _ => "polar coordinates",
                    },
                    match code {
                        680 | 690 => " (LinuxCNC rotates a coordinate system with G10 L2 P.. R..)",
                        150 | 160 => " (LinuxCNC writes polar moves with @ radius and ^ angle)",
                        _ => "",
                    }
                ),
            ));
        }
        if code == 150 || code == 160 {
            self.set_polar_mode(code == 160);
            Ok(())
        } else {
            self.exec_transform(w, code, self.word_pos(i))
        }
    }

    /// Axis words with no motion mode. A post for a Fanuc-type control writes `G80` then
    /// `Z5.` meaning the G0/G1 of before the cycle (canned cycles are a group of their own
    /// there); LinuxCNC refuses the block. With the dialect left to `auto` the Fanuc rule
    /// applies, with a warning.
    #[cold]
    fn motion_after_g80(&mut self) -> R<Motion> {
        match self.motion_01 {
            Some(m) if self.opts.dialect == Dialect::Auto => {
                self.warnings.push(self.err_block(format!(
                    "axis words after G80 with no motion mode: the Fanuc rule is applied (G80 keeps the {} of before the cycle); LinuxCNC refuses this block (set the dialect to choose)",
                    motion_name(m)
                )));
                self.motion = Some(m);
                Ok(m)
            }
            _ => Err(self.err_block(
                "axis words but no motion mode (G80 is active); give G0/G1/G2/G3 or a cycle",
            )),
        }
    }

    /// The motion mode after G80: none (LinuxCNC), or the G0/G1/G2/G3 mode from before the
    /// cycle (Fanuc: canned cycles are a modal group of their own).
    fn after_g80(&self) -> Option<Motion> {
        if self.fanuc {
            self.motion_01
        } else {
            None
        }
    }
}

/// The G code of a group 01 motion mode, for messages.
fn motion_name(m: Motion) -> &'static str {
    match m {
        Motion::Rapid => "G0",
        Motion::Linear => "G1",
        Motion::Arc { cw: true } => "G2",
        Motion::Arc { cw: false } => "G3",
        _ => "motion mode",
    }
}
