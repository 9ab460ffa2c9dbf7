//! The G-code steps of a block before its motion: 14-22 (dwell, plane, units, cutter and
//! tool length compensation, coordinate system, path control, distance and retract modes)
//! and the Fanuc transforms (22a).

use super::super::modal::{g_name, Plane};
use super::super::words::{Words, AXES};
use super::super::{Interp, MM_PER_INCH, R};

impl Interp<'_> {
    /// 14. G4.
    pub(super) fn dwell_code(&mut self, w: &mut Words) -> R<()> {
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
                        // G4 X is how Fanuc and Haas posts write a dwell: say so, rather
                        // than only what LinuxCNC wants.
                        let message = if w.take('X').is_some() {
                            "G4 X (seconds) is Fanuc's dwell; with dialect linuxcnc G4 takes P in seconds (dialect fanuc, or auto on a Fanuc program, reads G4 X and G4 P in ms)"
                        } else {
                            "G4 needs a P word (seconds)"
                        };
                        return Err(self.err_at(self.word_pos(i), message));
                    }
                }
            };
            if secs < 0.0 {
                return Err(self.err_at(self.word_pos(i), "negative dwell time"));
            }
            self.dwell(secs)?;
        }
        Ok(())
    }

    /// 15. G17, G18, G19.
    pub(super) fn set_plane(&mut self, w: &Words) -> R<()> {
        for (code, plane) in [(170, Plane::XY), (180, Plane::XZ), (190, Plane::YZ)] {
            if let Some(i) = w.g(code) {
                if self.comp.active.is_some() && plane != self.modal.plane {
                    return Err(self.err_at(
                        self.word_pos(i),
                        "plane change with cutter radius compensation on (G40 first)",
                    ));
                }
                self.modal.plane = plane;
            }
        }
        Ok(())
    }

    /// 16. G20, G21: the current point follows the units.
    pub(super) fn set_units(&mut self, w: &Words) {
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
    }

    /// 17. G40, G41, G42 (G41.1, G42.1).
    pub(super) fn set_cutter_comp(&mut self, w: &mut Words) -> R<()> {
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
        Ok(())
    }

    pub(super) fn set_tool_length_offset(&mut self, w: &mut Words) -> R<()> {
        // 18. tool length offset; G43.4/G43.5 (tool-centre-point control) take it as G43
        // does and make X Y Z the tool tip on the part from here to G43/G43.1/G49.
        let tcp = w.g(434).or(w.g(435));
        let was_tcp = self.tool.tcp;
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
                        return Err(self.err_word(w, 'H', format!("H{h} is not a tool number")));
                    }
                    h as u32
                }
                None => self.tool.current,
            };
            // Fanuc: a D here is the radius offset number later G41/G42 take.
            if self.fanuc {
                if let Some(d) = w.take('D') {
                    if d < 0.0 || d.fract() != 0.0 || d > u32::MAX as f64 {
                        return Err(self.err_word(w, 'D', format!("D{d} is not an offset number")));
                    }
                    self.tool.radius_offset = Some(d as u32);
                }
            }
            let off = match self.tool_length(h) {
                Some(z) => z,
                None => {
                    // Without any tool table or G10 length every H reads as length 0 (the
                    // programmed point is the tool tip, as a CAM post writes it): said only
                    // where lengths were given and this one is not among them.
                    let given =
                        !self.opts.tool_table.tools.is_empty() || !self.tool.lengths.is_empty();
                    if given && self.tool.warned.insert(h) {
                        self.out.warnings.push(self.err_at(
                            self.word_pos(i),
                            format!("G43: tool {h} is not in the tool table; tool length 0 used"),
                        ));
                    }
                    0.0
                }
            };
            self.set_tlo(Some(off));
            self.tool.tcp = tcp.is_some();
        }
        if w.g(431).is_some() {
            self.tool.tcp = false;
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
            self.tool.tcp = false;
            self.set_tlo(None);
        }
        if self.tool.tcp != was_tcp {
            self.tool_tip_control_changed(self.tool.tcp);
        }
        Ok(())
    }

    /// 19. G54..G59.3, and the extended work offsets.
    pub(super) fn select_coordinate_system(&mut self, w: &mut Words) -> R<()> {
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
        Ok(())
    }

    /// G97 (spindle speed in rpm, the only mode simulated) is accepted; G96 (constant
    /// surface speed: the rpm follows the cutting radius, a lathe's mode) is refused.
    pub(super) fn spindle_mode(&mut self, w: &Words) -> R<()> {
        if let Some(i) = w.g(960) {
            return Err(self.err_at(
                self.word_pos(i),
                "G96 (constant surface speed: the spindle speed follows the cutting radius) is not supported: program the spindle speed in rpm (G97 S..)",
            ));
        }
        Ok(())
    }

    pub(super) fn set_path_control(&mut self, w: &mut Words) {
        // 20. path control: blending changes no end point.
        if w.g(640).is_some() {
            w.take('P');
            w.take('Q');
        }
    }

    /// 21. G90, G91, G90.1, G91.1.
    pub(super) fn set_distance_modes(&mut self, w: &Words) {
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
    }

    /// 22. G98, G99.
    pub(super) fn set_retract_mode(&mut self, w: &Words) {
        if w.g(980).is_some() {
            self.modal.retract_r_plane = false;
        }
        if w.g(990).is_some() {
            self.modal.retract_r_plane = true;
        }
    }

    pub(super) fn fanuc_h_word_alone(&mut self, w: &mut Words) -> R<()> {
        // Fanuc: an H without G43 (posts write `G53 Z0 H0`, `G91 G28 Z0 H0`) changes the
        // length offset number of the active compensation; H0 is always zero.
        if self.fanuc && w.has('H') && w.g(430).is_none() {
            self.fanuc_h_word(w)?;
        }
        Ok(())
    }

    /// 22a. Fanuc transforms (scaling, mirror image, rotation, polar mode), then the polar
    /// words.
    pub(super) fn fanuc_transforms(&mut self, w: &mut Words) -> R<()> {
        if w.transform {
            for k in 0..w.gs.len() {
                let (code, i) = w.gs[k];
                if matches!(code, 500 | 510 | 501 | 511 | 680 | 682 | 690)
                    && self.tilted_plane_code(w, code, self.word_pos(i))?
                {
                    continue;
                }
                if matches!(code, 500 | 510 | 501 | 511 | 680 | 690 | 150 | 160) {
                    self.fanuc_transform_code(w, k)?;
                }
            }
        }
        if self.polar.mode {
            self.fanuc_polar_words(w);
        }
        Ok(())
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
}
