//! Canned cycles (G73, G81..G89) and rigid tapping (G33.1), as LinuxCNC 2.9.

use super::modal::{Motion, Plane};
use super::words::{Words, AXES};
use super::{Interp, G83_RAPID_DELTA_INCH, MM_PER_INCH, R};
use crate::nc::{FeedMode, SpindleDir};

/// Canned cycle sticky values (program units), kept from one cycle block to the next.
#[derive(Default)]
pub(super) struct CycleState {
    pub(super) r: f64,
    pub(super) cc: f64,
    pub(super) p: f64,
    pub(super) q: f64,
    pub(super) i: f64,
    pub(super) j: f64,
    pub(super) k: f64,
    pub(super) il: Option<f64>,
}

impl Interp<'_> {
    /// G33.1: feed to the target synchronized with the spindle (K = pitch), then back out.
    pub(super) fn rigid_tap(&mut self, w: &mut Words) -> R<()> {
        let Some(k) = w.take('K') else {
            return Err(self.err_block("G33.1 needs a K word (thread pitch)"));
        };
        if k <= 0.0 {
            return Err(self.err_word(w, 'K', "G33.1 pitch K must be positive"));
        }
        if self.modal.speed <= 0.0 || self.modal.spindle == SpindleDir::Off {
            return Err(self.err_block("G33.1 with the spindle stopped"));
        }
        let start = self.cur;
        let to = self.target(w, false)?;
        if (0..2).any(|i| to[i] != start[i]) || (3..6).any(|i| to[i] != start[i]) {
            return Err(self.err_block("G33.1 moves Z only here (X/Y/A/B/C must not change)"));
        }
        let (mode, word, factor) = (
            self.modal.feed_mode,
            self.modal.feed_word,
            self.modal.feed_factor,
        );
        self.modal.feed_mode = FeedMode::PerRev;
        self.modal.feed_word = k;
        self.modal.feed_factor = self.unit();
        let r = (|| {
            self.straight(false, to)?;
            self.straight(false, start)
        })();
        self.modal.feed_mode = mode;
        self.modal.feed_word = word;
        self.modal.feed_factor = factor;
        r
    }

    /// Canned cycles, as LinuxCNC 2.9 (`convert_cycle_xy/yz/zx`).
    pub(super) fn cycle(&mut self, w: &mut Words, g: u16) -> R<()> {
        if self.modal.feed_mode == FeedMode::InverseTime {
            return Err(self.err_block("canned cycle in inverse time mode (G93)"));
        }
        self.check_feed()?;
        let same = self.motion_was_cycle(g);
        // Fanuc keeps the cycle data (R, hole bottom, P, Q) from one cycle code to the next
        // until G80 or G00-G03 clears it; LinuxCNC only while the same cycle repeats.
        let kept = same || (self.fanuc && matches!(self.motion.prev, Some(Motion::Cycle(_))));
        let plane = self.modal.plane;
        let [ia, ib, ic] = plane.axes();
        let (la, lb, lc) = (AXES[ia], AXES[ib], AXES[ic]);
        let rotary_words = AXES[3..].iter().any(|&c| w.has(c));
        if rotary_words && !self.fanuc {
            return Err(self.err_block(
                "rotary axis words in a canned cycle (LinuxCNC refuses them; a Fanuc control indexes the rotary axis with the hole positioning)",
            ));
        }
        let r_word = w.take('R');
        let r_num = match r_word {
            Some(r) => r,
            None if kept => self.cycle.r,
            // Fanuc: G80 clears R, which the manual defines as R = 0 incremental: the R point
            // is then the initial level.
            None if self.fanuc => {
                self.out.warnings.push(self.err_block(format!(
                    "G{g} without R and no R since the last G80: the R point is the initial level, as a Fanuc control clears R to 0 incremental at G80"
                )));
                if self.modal.absolute {
                    self.cycle.il.unwrap_or(self.cur[ic])
                } else {
                    0.0
                }
            }
            None => {
                return Err(self.err_block(format!(
                    "G{g} needs an R word (retract plane) under LinuxCNC rules; a Fanuc control takes the initial level without one (dialect fanuc)"
                )))
            }
        };
        // Repeats: L (LinuxCNC); Fanuc uses K except in G87 where K is the bore top.
        let mut l = w.take('L').map(|v| ('L', v));
        if self.fanuc && g != 87 {
            if let Some(k) = w.take('K') {
                if l.is_some() {
                    return Err(self.err_word(w, 'K', "both L and K repeat counts"));
                }
                l = Some(('K', k));
            }
        }
        // Fanuc K0 (Haas L0): the cycle's data is stored and no hole is made.
        let least = if self.fanuc { 0.0 } else { 1.0 };
        let repeats = match l {
            Some((c, v)) if v.fract() != 0.0 || v < least => {
                return Err(self.err_block(format!(
                    "repeat count {c}{v} must be a whole number of at least {least}"
                )))
            }
            Some((_, v)) => v,
            None => 1.0,
        };
        // Fanuc: an additional (rotary) axis moves with the positioning rapid of the hole
        // (operation 1 of the cycle), as a 4th-axis bolt circle `G81 .. / G91 A45.` does.
        let mut rotary = None;
        if rotary_words {
            if repeats > 1.0 {
                return Err(self.err_block(
                    "rotary axis words with a repeat count (K/L) in a canned cycle are not supported",
                ));
            }
            let mut t = [self.cur[3], self.cur[4], self.cur[5]];
            for (k, &c) in AXES[3..].iter().enumerate() {
                if let Some(v) = w.take(c) {
                    t[k] = if self.modal.absolute { v } else { t[k] + v };
                }
            }
            rotary = Some(t);
        }
        let cc_word = w.get(lc);
        if !kept && cc_word.is_none() {
            return Err(self.err_block(format!(
                "G{g} needs a {lc} word (hole bottom) in {}",
                plane.name()
            )));
        }
        w.take(lc);
        let cc_num = cc_word.unwrap_or(self.cycle.cc);
        let current_cc0 = self.cur[ic];
        let mut current_cc = current_cc0;
        let mut old_cc = match self.cycle.il {
            Some(v) => v,
            None => {
                self.cycle.il = Some(current_cc0);
                current_cc0
            }
        };
        let (mut aa, mut bb, aa_inc, bb_inc, r, cc);
        let wa = w.take(la);
        let wb = w.take(lb);
        if self.modal.absolute {
            aa_inc = 0.0;
            bb_inc = 0.0;
            r = r_num;
            cc = cc_num;
            aa = wa.unwrap_or(self.cur[ia]);
            bb = wb.unwrap_or(self.cur[ib]);
        } else {
            aa_inc = wa.unwrap_or(0.0);
            bb_inc = wb.unwrap_or(0.0);
            r = r_num + old_cc;
            cc = r + cc_num;
            aa = self.cur[ia];
            bb = self.cur[ib];
        }
        let polar_inc = self.cycle_polar(w, &mut aa, &mut bb)?;
        if r < cc {
            // Fanuc's G87 starts below the part (R) and bores upward to Z with a bar that
            // passes the hole oriented and shifted: no rotating-tool model of it here.
            if g == 87 && self.fanuc {
                return Err(self.err_block(format!(
                    "G87 with R ({r}) below {lc} ({cc}) is Fanuc's back boring (the oriented bar lowered through the hole, shifted by Q, then boring upward): not supported; LinuxCNC's G87 (I J K, R above) is"
                )));
            }
            return Err(
                self.err_block(format!("R ({r}) below the hole bottom {lc} ({cc}) in G{g}"))
            );
        }
        // Cycle-specific words (sticky when the cycle repeats).
        let mut p = 0.0;
        let mut q = 0.0;
        let (mut ci, mut cj, mut ck) = (0.0, 0.0, 0.0);
        match g {
            76 | 82 | 86 | 88 | 89 => {
                if g == 76 {
                    // The oriented spindle's shift away from the wall (Q, and the direction
                    // a parameter sets) keeps the stopped bar off the bore on the way out; a
                    // rotating tool retracting straight up its own bore cuts nothing either,
                    // so the shift is not simulated.
                    w.take('Q');
                }
                p = match w.take('P') {
                    // Fanuc: the dwell in ms, as G04 P.
                    Some(v) if self.fanuc => v / 1000.0,
                    Some(v) => v,
                    None if kept => self.cycle.p,
                    // Fanuc: G80 clears P, so no dwell.
                    None if self.fanuc => 0.0,
                    None => return Err(self.err_block(format!("G{g} needs a P word (dwell)"))),
                };
                self.cycle.p = p;
            }
            74 | 84 => {
                p = match w.take('P') {
                    Some(v) if self.fanuc => v / 1000.0,
                    Some(v) => v,
                    None => self.cycle.p,
                };
                self.cycle.p = p;
                let (need, m) = if g == 84 {
                    (SpindleDir::Cw, "clockwise (M3)")
                } else {
                    (SpindleDir::Ccw, "counterclockwise (M4)")
                };
                if self.modal.spindle != need {
                    return Err(self.err_block(format!("G{g} needs the spindle turning {m}")));
                }
            }
            73 | 83 => {
                q = match w.take('Q') {
                    Some(v) => v,
                    None if kept => self.cycle.q,
                    None => return Err(self.err_block(format!("G{g} needs a Q word (peck depth)"))),
                };
                if q <= 0.0 {
                    return Err(self.err_block(format!("G{g} peck depth Q must be positive")));
                }
                self.cycle.q = q;
                // Fanuc (small-hole peck drilling), Haas and Mitsubishi: P is a dwell at the
                // hole's bottom, in ms as G04 P; LinuxCNC has none (P is refused there). Only
                // a P given to this peck cycle dwells: a G82's kept P is no peck dwell.
                if self.fanuc {
                    p = match w.take('P') {
                        Some(v) => {
                            self.cycle.p = v / 1000.0;
                            self.cycle.p
                        }
                        None if same => self.cycle.p,
                        None => 0.0,
                    };
                }
            }
            87 => {
                // I J K of the XY plane; in other planes the letters follow the plane's axes.
                let [li, lj] = [['I', 'J', 'K'][ia], ['I', 'J', 'K'][ib]];
                let lk = ['I', 'J', 'K'][ic];
                if !same {
                    for c in [li, lj, lk] {
                        if !w.has(c) {
                            return Err(
                                self.err_block(format!("G87 needs {li}, {lj} and {lk} words"))
                            );
                        }
                    }
                }
                ci = w.take(li).unwrap_or(self.cycle.i);
                cj = w.take(lj).unwrap_or(self.cycle.j);
                ck = w.take(lk).unwrap_or(self.cycle.k);
                self.cycle.i = ci;
                self.cycle.j = cj;
                self.cycle.k = ck;
                if !self.modal.absolute {
                    ck += cc;
                }
            }
            _ => {}
        }
        if matches!(g, 76 | 86 | 87 | 88) && self.modal.spindle == SpindleDir::Off {
            return Err(self.err_block(format!("G{g} needs the spindle turning")));
        }
        if repeats == 0.0 {
            // Stored for the holes that follow; nothing moves, the position words included
            // (the control makes no hole and no positioning at K0).
            if wa.is_some() || wb.is_some() || rotary.is_some() {
                self.out.warnings.push(self.err_block(format!(
                    "G{g} with a repeat count of 0: the cycle's data is stored and nothing moves; this block's {la}/{lb} are not moved to"
                )));
            }
            self.cycle.cc = cc_num;
            self.cycle.r = r_num;
            return Ok(());
        }
        // Below the R plane: rapid up to it first.
        if old_cc < r {
            let mut t = self.cur;
            t[ic] = r;
            self.straight(true, t)?;
            old_cc = r;
            current_cc = old_cc;
        }
        let clear = if self.modal.retract_r_plane {
            r
        } else {
            old_cc
        };
        // rs274 (2.9) never positions at or below the R plane: from there it positions at
        // the clearance height (R in G99, the initial level in G98).
        if current_cc <= r {
            current_cc = clear;
        }
        let mut repeat = repeats;
        while repeat >= 1.0 {
            aa += aa_inc;
            bb += bb_inc;
            self.polar_step(&mut aa, &mut bb, polar_inc)?;
            if let Some(t) = rotary.take() {
                let mut to = self.cur;
                to[3..].copy_from_slice(&t);
                to[ia] = aa;
                to[ib] = bb;
                to[ic] = current_cc;
                self.straight(true, to)?;
            } else {
                self.cyc_move(true, plane, aa, bb, current_cc)?;
            }
            // rs274 (2.9) moves down to R whenever the positioning height is not R.
            if current_cc != r {
                self.cyc_move(true, plane, aa, bb, r)?;
            }
            match g {
                81 => {
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                }
                82 => {
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.dwell(p)?;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                }
                73 | 83 => {
                    let delta =
                        G83_RAPID_DELTA_INCH * if self.modal.metric { MM_PER_INCH } else { 1.0 };
                    let mut depth = r - q;
                    while depth > cc {
                        self.cyc_move(false, plane, aa, bb, depth)?;
                        if g == 83 {
                            self.cyc_move(true, plane, aa, bb, r)?;
                        }
                        self.cyc_move(true, plane, aa, bb, depth + delta)?;
                        depth -= q;
                    }
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    if p > 0.0 {
                        self.dwell(p)?;
                    }
                    self.cyc_move(true, plane, aa, bb, clear)?;
                }
                74 | 84 => {
                    // Tap in, reverse the spindle, dwell, feed out, restore the direction.
                    let (dir, rev) = if g == 84 {
                        (SpindleDir::Cw, SpindleDir::Ccw)
                    } else {
                        (SpindleDir::Ccw, SpindleDir::Cw)
                    };
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.modal.spindle = rev;
                    self.dwell(p)?;
                    self.cyc_move(false, plane, aa, bb, clear)?;
                    self.modal.spindle = dir;
                }
                85 => {
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.cyc_move(false, plane, aa, bb, r)?;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                }
                // Fanuc fine boring: bore, dwell, orient and stop, rapid out.
                76 | 86 => {
                    let dir = self.modal.spindle;
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.dwell(p)?;
                    self.modal.spindle = SpindleDir::Off;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                    self.modal.spindle = dir;
                }
                87 => {
                    let dir = self.modal.spindle;
                    let (oa, ob) = (aa + ci, bb + cj);
                    self.cyc_move(true, plane, oa, ob, r)?;
                    self.modal.spindle = SpindleDir::Off;
                    self.cyc_move(true, plane, oa, ob, cc)?;
                    self.cyc_move(true, plane, aa, bb, cc)?;
                    self.modal.spindle = dir;
                    self.cyc_move(false, plane, aa, bb, ck)?;
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.modal.spindle = SpindleDir::Off;
                    self.cyc_move(true, plane, oa, ob, cc)?;
                    self.cyc_move(true, plane, oa, ob, clear)?;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                    self.modal.spindle = dir;
                }
                88 => {
                    // The control stops at the bottom and the operator retracts by hand; the
                    // program then goes on as if the tool were at the clearance height. That
                    // retract is emitted as a rapid (spindle stopped) so the path stays connected.
                    let dir = self.modal.spindle;
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.dwell(p)?;
                    self.modal.spindle = SpindleDir::Off;
                    self.out.warnings.push(self.err_block(
                        "G88: program stop at the hole bottom; the operator's manual retract is modelled as a rapid to the clearance height",
                    ));
                    self.cyc_move(true, plane, aa, bb, clear)?;
                    self.modal.spindle = dir;
                }
                89 => {
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.dwell(p)?;
                    self.cyc_move(false, plane, aa, bb, clear)?;
                }
                _ => return Err(self.err_block(format!("G{g} is not a supported canned cycle"))),
            }
            // Later repeats position at the clearance height.
            current_cc = clear;
            repeat -= 1.0;
        }
        // LinuxCNC leaves the third axis at the clearance value whatever the last move was
        // (for G88 the operator's manual retract, emitted as a rapid below).
        self.cur[ia] = aa;
        self.cur[ib] = bb;
        self.cur[ic] = clear;
        self.cycle.cc = cc_num;
        self.cycle.r = r_num;
        Ok(())
    }

    pub(super) fn motion_was_cycle(&self, g: u16) -> bool {
        self.motion.prev == Some(Motion::Cycle(g))
    }

    pub(super) fn cyc_move(
        &mut self,
        rapid: bool,
        plane: Plane,
        aa: f64,
        bb: f64,
        cc: f64,
    ) -> R<()> {
        let [ia, ib, ic] = plane.axes();
        let mut t = self.cur;
        t[ia] = aa;
        t[ib] = bb;
        t[ic] = cc;
        self.straight(rapid, t)
    }

    /// G38.2..G38.5 probing (and Fanuc's G31 skip, `g` 310): without a probe model the
    /// move runs to its programmed end point (a probe that never trips), with a warning.
    pub(super) fn probe(&mut self, w: &mut Words, g: u16) -> R<()> {
        let name = super::modal::g_name(g);
        if self.modal.feed_mode == FeedMode::InverseTime {
            return Err(self.err_block(format!("{name} probing in inverse time mode (G93)")));
        }
        let to = self.target(w, false)?;
        let d: f64 = (0..3)
            .map(|i| (to[i] - self.cur[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        if d * self.unit() < 0.254 {
            return Err(self.err_block(format!(
                "{name}: start point too close to the probe point (under 0.254 mm)"
            )));
        }
        self.out.warnings.push(self.err_block(format!(
            "{name} probing: no probe contact is modelled; the move goes to its programmed end point"
        )));
        self.straight(false, to)
    }
}
