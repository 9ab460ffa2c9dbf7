//! Coordinate systems: program <-> machine frame, work offsets (G10, G54..G59.3), G92, G28/G30
//! home positions, G53, the tool length offset.

use super::words::{Words, AXES};
use super::{Interp, R};

impl Interp<'_> {
    // ----- frames -----

    pub(super) fn g92_eff(&self) -> [f64; 6] {
        if self.g92_applied {
            self.g92
        } else {
            [0.0; 6]
        }
    }

    /// Program coordinates -> machine frame, mm/deg.
    pub(super) fn to_machine(&self, p: [f64; 6]) -> [f64; 6] {
        let u = self.unit();
        let g92 = self.g92_eff();
        let mut m = [0.0; 6];
        for i in 0..6 {
            let s = if i < 3 { u } else { 1.0 };
            m[i] = p[i] * s + self.g5x[self.modal.cs][i] + g92[i];
        }
        m
    }

    pub(super) fn from_machine(&self, m: [f64; 6]) -> [f64; 6] {
        let u = self.unit();
        let g92 = self.g92_eff();
        let mut p = [0.0; 6];
        for i in 0..6 {
            let s = if i < 3 { u } else { 1.0 };
            p[i] = (m[i] - self.g5x[self.modal.cs][i] - g92[i]) / s;
        }
        p
    }

    /// Change offsets keeping the tool where it physically is.
    pub(super) fn change_offsets(&mut self, f: impl FnOnce(&mut Self)) {
        let phys = self.to_machine(self.cur);
        f(self);
        self.cur = self.from_machine(phys);
    }

    pub(super) fn set_tlo(&mut self, tlo: Option<f64>) {
        // The spindle does not move; the controlled point (tool tip) is now elsewhere.
        let old = self.tlo.unwrap_or(0.0);
        let new = tlo.unwrap_or(0.0);
        self.cur[2] += (old - new) / self.unit();
        self.tlo = tlo;
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
                if l != 2.0 && l != 20.0 {
                    return Err(self.err_at(
                        self.word_pos(i),
                        format!("G10 L{l} is not supported (only L2 and L20 work offsets)"),
                    ));
                }
                if w.has('R') {
                    return Err(self.err_word(
                        w,
                        'R',
                        "G10 coordinate system rotation (R) is not supported",
                    ));
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
                let phys = self.to_machine(self.cur);
                let g92 = self.g92_eff();
                let mut new = self.g5x[k];
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
                self.change_offsets(|st| st.g5x[k] = new);
            }
            280 | 300 => {
                let home = if g == 280 { self.g28 } else { self.g30 };
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
            281 | 301 => {
                let m = self.to_machine(self.cur);
                if g == 281 {
                    self.g28 = m;
                } else {
                    self.g30 = m;
                }
            }
            920 => {
                if !w.has_axis() {
                    return Err(self.err_at(self.word_pos(i), "G92 needs at least one axis word"));
                }
                let phys = self.to_machine(self.cur);
                let mut new = self.g92_eff();
                for (ai, &c) in AXES.iter().enumerate() {
                    if let Some(v) = w.take(c) {
                        let s = if ai < 3 { u } else { 1.0 };
                        new[ai] = phys[ai] - self.g5x[self.modal.cs][ai] - v * s;
                    }
                }
                self.change_offsets(|st| {
                    st.g92 = new;
                    st.g92_applied = true;
                });
            }
            921 => self.change_offsets(|st| {
                st.g92 = [0.0; 6];
                st.g92_applied = true;
            }),
            922 => self.change_offsets(|st| st.g92_applied = false),
            923 => self.change_offsets(|st| st.g92_applied = true),
            _ => {}
        }
        Ok(())
    }

    /// Target of a straight or arc move in program coordinates.
    pub(super) fn target(&self, w: &mut Words, g53: bool) -> R<[f64; 6]> {
        let mut t = self.cur;
        if g53 && !self.modal.absolute {
            return Err(self.err_block("G53 in incremental mode (G91)"));
        }
        for (ai, &c) in AXES.iter().enumerate() {
            if let Some(v) = w.take(c) {
                t[ai] = if g53 {
                    let s = if ai < 3 { self.unit() } else { 1.0 };
                    (v * s - self.g5x[self.modal.cs][ai] - self.g92_eff()[ai]) / s
                } else if self.modal.absolute {
                    v
                } else {
                    self.cur[ai] + v
                };
            }
        }
        Ok(t)
    }
}
