//! Coordinate systems: program <-> machine frame, work offsets (G10, G54..G59.3), G92, G28/G30
//! home positions, G53, the tool length offset.

use super::tilted_plane::TiltedPlane;
use super::transforms::ProgramTransforms;
use super::words::{Words, AXES};
use super::{Interp, CS_COUNT, R};

/// Where program coordinates are in the machine frame (work offsets, G92, G52, rotation,
/// Fanuc transforms, the tilted plane) and the G28/G30 home positions.
pub(super) struct Coords {
    /// Work offsets, mm/deg: G54..G59.3 (0..8), then the extended sets P1..P99 (Fanuc
    /// G54.1 Pn, Haas G154 Pn) at 8 + n.
    pub(super) g5x: [[f64; 6]; CS_COUNT],
    pub(super) g92: [f64; 6],
    pub(super) g92_applied: bool,
    /// Fanuc G52 local offset, mm/deg (LinuxCNC's G52 writes the G92 offset instead).
    pub(super) g52: [f64; 6],
    /// LinuxCNC G10 L2 R: rotation of each coordinate system in XY, degrees.
    pub(super) rot_xy: [f64; CS_COUNT],
    /// Fanuc mirror image, scaling and rotation.
    pub(super) prog_xf: ProgramTransforms,
    /// G68.2: the feature coordinate system program X Y Z are in, until G69.
    pub(super) tilt: Option<TiltedPlane>,
    /// No rotation, mirror or scaling active: `to_machine` is per-axis offsets only.
    pub(super) plain: bool,
    pub(super) g28: [f64; 6],
    pub(super) g30: [f64; 6],
}

impl Interp<'_> {
    // ----- frames -----

    pub(super) fn g92_eff(&self) -> [f64; 6] {
        if self.coords.g92_applied {
            self.coords.g92
        } else {
            [0.0; 6]
        }
    }

    /// Change offsets keeping the tool where it physically is.
    pub(super) fn change_offsets(&mut self, f: impl FnOnce(&mut Self)) {
        let phys = self.to_machine(self.cur);
        f(self);
        self.update_plain();
        self.cur = self.from_machine(phys);
    }

    /// Fanuc/Haas `G10 L20 Pn`: the values of extended work offset n (G54.1 Pn / G154 Pn),
    /// as given (G90) or added to it (G91).
    fn g10_extended_offset(&mut self, w: &mut Words, p: f64, i: usize) -> R<()> {
        if p.fract() != 0.0 || !(1.0..=super::EXTENDED_CS as f64).contains(&p) {
            return Err(self.err_at(
                self.word_pos(i),
                format!(
                    "G10 L20 P{p}: the extended work offset number must be a whole number 1..{}",
                    super::EXTENDED_CS
                ),
            ));
        }
        if self.program_transform_on() {
            return Err(self.err_at(
                self.word_pos(i),
                "G10 work offsets with scaling, mirror image or rotation on (G50/G50.1/G69 first)",
            ));
        }
        let k = 8 + p as usize;
        let u = self.unit();
        let mut new = self.coords.g5x[k];
        for (ai, &c) in AXES.iter().enumerate() {
            if let Some(v) = w.take(c) {
                let v = if ai < 3 { v * u } else { v };
                new[ai] = if self.modal.absolute { v } else { new[ai] + v };
            }
        }
        self.change_offsets(|st| st.coords.g5x[k] = new);
        Ok(())
    }

    /// Selects work coordinate system `k` (the G code is word `i`).
    pub(super) fn select_cs(&mut self, k: usize, i: usize) -> R<()> {
        if self.comp.active.is_some() && self.modal.cs != k {
            return Err(self.err_at(
                self.word_pos(i),
                "coordinate system change with cutter radius compensation on (G40 first)",
            ));
        }
        self.change_offsets(|s| s.modal.cs = k);
        Ok(())
    }

    /// The coordinate system index of Fanuc `G54.1 Pn` (n 1..48) or Haas `G154 Pn` (n 1..99):
    /// the extended sets after G59.3. A control reads their values from its offset page; here
    /// they are zero until G10 L20 Pn sets them.
    pub(super) fn extended_cs(&mut self, w: &mut Words, code: u16, i: usize) -> R<usize> {
        let (name, max) = if code == 541 {
            ("G54.1", 48.0)
        } else {
            ("G154", super::EXTENDED_CS as f64)
        };
        if !self.fanuc {
            return Err(self.err_at(
                self.word_pos(i),
                format!("{name} (extended work offsets) is Fanuc/Haas: with dialect fanuc (or auto on a Fanuc program); LinuxCNC has G54-G59.3"),
            ));
        }
        let p = w.take('P').ok_or_else(|| {
            self.err_at(
                self.word_pos(i),
                format!("{name} needs P1..P{max} (the extended work offset number)"),
            )
        })?;
        if p.fract() != 0.0 || !(1.0..=max).contains(&p) {
            return Err(self.err_at(
                self.word_pos(i),
                format!(
                    "{name} P{p}: the extended work offset number must be a whole number 1..{max}"
                ),
            ));
        }
        Ok(8 + p as usize)
    }

    pub(super) fn set_tlo(&mut self, tlo: Option<f64>) {
        // The spindle does not move; the controlled point (tool tip) is now elsewhere.
        let old = self.tool.tlo.unwrap_or(0.0);
        let new = tlo.unwrap_or(0.0);
        self.cur[2] += (old - new) / self.unit();
        self.tool.tlo = tlo;
    }

    pub(super) fn exec_group0(&mut self, w: &mut Words, g: u16, i: usize) -> R<()> {
        let u = self.unit();
        match g {
            100 => {
                let l = w
                    .take('L')
                    .ok_or_else(|| self.err_at(self.word_pos(i), "G10 needs an L word"))?;
                let p = w
                    .take('P')
                    .ok_or_else(|| self.err_at(self.word_pos(i), "G10 needs a P word"))?;
                if matches!(l, 1.0 | 10.0 | 11.0) || (self.fanuc && matches!(l, 12.0 | 13.0)) {
                    return self.g10_tool(w, l, p, i);
                }
                if l != 2.0 && l != 20.0 {
                    return Err(self.err_at(
                        self.word_pos(i),
                        format!("G10 L{l} is not supported (L1/L10/L11 tool offsets, L2/L20 work offsets; Fanuc L10-L13)"),
                    ));
                }
                if w.has('R') && (l != 2.0 || self.fanuc) {
                    return Err(self.err_word(
                        w,
                        'R',
                        "R (coordinate system rotation) is only taken by G10 L2 (LinuxCNC)",
                    ));
                }
                if self.fanuc && l == 20.0 {
                    return self.g10_extended_offset(w, p, i);
                }
                if p.fract() != 0.0 || !(0.0..=9.0).contains(&p) {
                    return Err(self.err_word(
                        w,
                        'P',
                        format!("G10 P{p}: coordinate system must be 0..9"),
                    ));
                }
                let k = if p == 0.0 {
                    self.modal.cs
                } else {
                    p as usize - 1
                };
                if l == 20.0 && self.coords.rot_xy[k] != 0.0 {
                    return Err(self.err_at(
                        self.word_pos(i),
                        "G10 L20 on a rotated coordinate system (G10 L2 R) is not supported",
                    ));
                }
                if self.program_transform_on() {
                    return Err(self.err_at(
                        self.word_pos(i),
                        "G10 work offsets with scaling, mirror image or rotation on (G50/G50.1/G69 first)",
                    ));
                }
                let phys = self.to_machine(self.cur);
                let g92 = self.local_offset();
                let mut new = self.coords.g5x[k];
                for (ai, &c) in AXES.iter().enumerate() {
                    if let Some(v) = w.take(c) {
                        let s = if ai < 3 { u } else { 1.0 };
                        new[ai] = if l == 2.0 {
                            v * s
                        } else {
                            phys[ai] - g92[ai] - v * s
                        };
                    }
                }
                let rot = w.take('R');
                self.change_offsets(|st| st.coords.g5x[k] = new);
                if let Some(r) = rot {
                    self.set_cs_rotation(k, r);
                }
            }
            280 | 300 => {
                // Fanuc's G30 P2..P4: the second to fourth reference points. There is one
                // G30 position here (the machine's, else the start above the stock): P2 is
                // it, P3 and P4 (machine parameters) are taken as it with a warning.
                if g == 300 && self.fanuc {
                    if let Some(p) = w.take('P') {
                        if !matches!(p, 2.0 | 3.0 | 4.0) {
                            return Err(self.err_at(
                                self.word_pos(i),
                                format!("G30 P{p}: the reference point is P2, P3 or P4"),
                            ));
                        }
                        if p != 2.0 {
                            self.out.warnings.push(self.err_at(
                                self.word_pos(i),
                                format!("G30 P{p}: the machine's reference point {p} is not known; its G30 (second reference) position is taken"),
                            ));
                        }
                    }
                }
                let home = if g == 280 {
                    self.coords.g28
                } else {
                    self.coords.g30
                };
                if w.has_axis() {
                    let mut mid = self.cur;
                    let mut which = [false; 6];
                    for (ai, &c) in AXES.iter().enumerate() {
                        if let Some(v) = w.take(c) {
                            mid[ai] = if self.modal.absolute {
                                v
                            } else {
                                self.cur[ai] + v
                            };
                            which[ai] = true;
                        }
                    }
                    self.straight(true, mid)?;
                    let hp = self.from_machine(home);
                    let mut end = self.cur;
                    for ai in 0..6 {
                        if which[ai] {
                            end[ai] = hp[ai];
                        }
                    }
                    self.straight(true, end)?;
                } else {
                    // LinuxCNC still makes the (zero-length) move to the intermediate point.
                    self.straight(true, self.cur)?;
                    let hp = self.from_machine(home);
                    self.straight(true, hp)?;
                }
            }
            282 => {
                // Smoothieware's and Bantam Tools' homing cycle (`G28.2 X0 Y0 Z0` in a
                // header): the named axes (every axis when none is named; the values are
                // flags) go to the home position, straight, with no intermediate point. The
                // simulated home is the stored G28 position.
                let mut which = [!w.has_axis(); 6];
                for (ai, &c) in AXES.iter().enumerate() {
                    if w.take(c).is_some() {
                        which[ai] = true;
                    }
                }
                let hp = self.from_machine(self.coords.g28);
                let mut end = self.cur;
                for ai in 0..6 {
                    if which[ai] {
                        end[ai] = hp[ai];
                    }
                }
                self.out.warnings.push(self.err_at(
                    self.word_pos(i),
                    "G28.2 (homing cycle) simulated as a rapid of the named axes to the G28 home position",
                ));
                self.straight(true, end)?;
            }
            281 | 301 => {
                let m = self.to_machine(self.cur);
                if g == 281 {
                    self.coords.g28 = m;
                } else {
                    self.coords.g30 = m;
                }
            }
            920 => {
                if !w.has_axis() {
                    return Err(self.err_at(self.word_pos(i), "G92 needs at least one axis word"));
                }
                if self.program_transform_on() {
                    return Err(self.err_at(
                        self.word_pos(i),
                        "G92 with scaling, mirror image or rotation on (G50/G50.1/G69 first)",
                    ));
                }
                // The new offset makes the current point (before any rotation of the
                // coordinate system, which rs274 applies after G92) read as the given value.
                let mut new = self.g92_eff();
                let local = self.local_offset();
                for (ai, &c) in AXES.iter().enumerate() {
                    if let Some(v) = w.take(c) {
                        let s = if ai < 3 { u } else { 1.0 };
                        new[ai] = self.cur[ai] * s + local[ai] - self.coords.g52[ai] - v * s;
                    }
                }
                self.change_offsets(|st| {
                    st.coords.g92 = new;
                    st.coords.g92_applied = true;
                });
            }
            921 => self.change_offsets(|st| {
                st.coords.g92 = [0.0; 6];
                st.coords.g92_applied = true;
            }),
            922 => self.change_offsets(|st| st.coords.g92_applied = false),
            923 => self.change_offsets(|st| st.coords.g92_applied = true),
            520 => self.g52(w, self.word_pos(i))?,
            531 => self.turn_tool_to_plane(self.word_pos(i))?,
            _ => {}
        }
        Ok(())
    }

    /// Target of a straight or arc move in program coordinates.
    pub(super) fn target(&self, w: &mut Words, g53: bool) -> R<[f64; 6]> {
        if self.coords.tilt.is_some() {
            self.refuse_rotary_under_tilt(w)?;
        }
        let mut t = self.cur;
        if g53 {
            return self.g53_target(w);
        }
        for (ai, &c) in AXES.iter().enumerate() {
            if let Some(v) = w.take(c) {
                t[ai] = if self.modal.absolute {
                    v
                } else {
                    self.cur[ai] + v
                };
            }
        }
        if w.polar_any {
            self.apply_polar(w, &mut t)?;
        }
        Ok(t)
    }

    /// The target of a G53 move: machine coordinates for the given axes (Z counted from
    /// `InterpretOptions::machine_z_home`).
    fn g53_target(&self, w: &mut Words) -> R<[f64; 6]> {
        let mut t = self.cur;
        if !self.modal.absolute {
            return Err(self.err_block("G53 in incremental mode (G91)"));
        }
        let mut home = [0.0; 6];
        home[2] = self.opts.machine_z_home.unwrap_or(0.0);
        if !self.only_offsets() {
            // Machine coordinates for the given axes, the current machine position for the
            // others, back through the transforms.
            let mut m = self.to_machine(self.cur);
            for (ai, &c) in AXES.iter().enumerate() {
                if let Some(v) = w.take(c) {
                    m[ai] = (if ai < 3 { v * self.unit() } else { v }) + home[ai];
                }
            }
            return Ok(self.from_machine(m));
        }
        for (ai, &c) in AXES.iter().enumerate() {
            if let Some(v) = w.take(c) {
                let s = if ai < 3 { self.unit() } else { 1.0 };
                t[ai] = (v * s + home[ai]
                    - self.coords.g5x[self.modal.cs][ai]
                    - self.local_offset()[ai])
                    / s;
            }
        }
        Ok(t)
    }

    /// G10 tool offset writes. LinuxCNC: L1 sets tool P's length (Z) and radius (R); L10 sets
    /// the length so that the current Z becomes the given one with that tool's offset, L11 the
    /// same in G59.3 without G92. Fanuc (offset memory C): L10/L11 length geometry/wear, L12/L13
    /// radius geometry/wear of offset number P, value R (added in G91).
    fn g10_tool(&mut self, w: &mut Words, l: f64, p: f64, i: usize) -> R<()> {
        let at = self.word_pos(i);
        if p.fract() != 0.0 || !(0.0..=u32::MAX as f64).contains(&p) {
            return Err(self.err_word(w, 'P', format!("G10 L{l} P{p}: P is a tool/offset number")));
        }
        let t = p as u32;
        let u = self.unit();
        if self.fanuc && l >= 10.0 {
            let Some(r) = w.take('R') else {
                return Err(self.err_at(at, format!("G10 L{l} needs R (the offset value)")));
            };
            let (map, base) = match l as u32 {
                10 => (
                    &mut self.tool.lengths,
                    self.opts.tool_table.get(t).map(|e| e.z_offset),
                ),
                11 => (&mut self.tool.length_wear, None),
                12 => (
                    &mut self.tool.radii,
                    self.opts
                        .tool_table
                        .get(t)
                        .and_then(|e| e.diameter)
                        .map(|d| d / 2.0),
                ),
                _ => (&mut self.tool.radius_wear, None),
            };
            let old = map.get(&t).copied().or(base).unwrap_or(0.0);
            let new = if self.modal.absolute {
                r * u
            } else {
                old + r * u
            };
            map.insert(t, new);
            return Ok(());
        }
        if let Some(r) = w.take('R') {
            self.tool.radii.insert(t, r * u);
        }
        let Some(z) = w.take('Z') else {
            if l == 1.0 {
                return Ok(());
            }
            return Err(self.err_at(at, format!("G10 L{l} needs a Z word")));
        };
        let length = if l == 1.0 {
            z * u
        } else {
            // Where the spindle is: the controlled point plus the active length offset.
            let spindle = self.to_machine(self.cur)[2] + self.tool.tlo.unwrap_or(0.0);
            let origin = if l == 10.0 {
                self.coords.g5x[self.modal.cs][2] + self.g92_eff()[2]
            } else {
                self.coords.g5x[8][2]
            };
            spindle - origin - z * u
        };
        self.tool.lengths.insert(t, length);
        Ok(())
    }

    /// Tool length (mm) of offset/tool number `h`: G10 writes, else the tool table (None: in
    /// neither), plus any Fanuc wear.
    pub(super) fn tool_length(&self, h: u32) -> Option<f64> {
        let geometry = self
            .tool
            .lengths
            .get(&h)
            .copied()
            .or_else(|| self.opts.tool_table.get(h).map(|t| t.z_offset))?;
        Some(geometry + self.tool.length_wear.get(&h).copied().unwrap_or(0.0))
    }

    /// Fanuc H without G43: the new offset number of the active length compensation (none
    /// active: it waits for the next G43, which names its own H here anyway).
    pub(super) fn fanuc_h_word(&mut self, w: &mut Words) -> R<()> {
        let Some(h) = w.take('H') else {
            return Ok(());
        };
        if h < 0.0 || h.fract() != 0.0 || h > u32::MAX as f64 {
            return Err(self.err_word(w, 'H', format!("H{h} is not an offset number")));
        }
        if self.tool.tlo.is_some() {
            let length = if h == 0.0 {
                0.0
            } else {
                self.tool_length(h as u32).unwrap_or(0.0)
            };
            self.set_tlo(Some(length));
        }
        Ok(())
    }
}
