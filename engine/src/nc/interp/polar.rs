//! Polar coordinates. LinuxCNC: `@` (radius) and `^` (angle, degrees) words in G17, read as
//! rs274's `find_ends` and canned cycles read them (about the XY origin; G91 adds to the
//! current point's radius and angle). Fanuc: in G16 mode the selected plane's first axis word
//! is the radius and the second the angle; with G90 both count from the work origin, with G91
//! the radius counts from the current position and the angle from the last polar angle.

use super::modal::Motion;
use super::words::{Words, AXES};
use super::{Interp, R};

/// Fanuc G16 polar mode, and the last polar radius and angle (degrees) it went to.
#[derive(Default)]
pub(super) struct PolarState {
    pub(super) mode: bool,
    pub(super) last: std::cell::Cell<Option<(f64, f64)>>,
}

impl Interp<'_> {
    /// G16 (on) / G15 (off).
    pub(super) fn set_polar_mode(&mut self, on: bool) {
        self.polar.mode = on;
        self.polar.last.set(None);
    }

    /// LinuxCNC's checks on `@`/`^` words before anything in the block runs (its
    /// enhance_block: the plane is the one from before the block).
    pub(super) fn check_polar_words(&self, w: &Words) -> R<()> {
        let Some(i) = w.polar_r.or(w.polar_a).map(|p| p.1) else {
            return Ok(());
        };
        let at = self.word_pos(i);
        if self.fanuc {
            return Err(self.err_at(
                at,
                "@ and ^ (polar words) are LinuxCNC; with dialect fanuc use G16",
            ));
        }
        if self.modal.plane != super::Plane::XY {
            return Err(self.err_at(at, "polar coordinates (@ ^) only in the G17 plane"));
        }
        for c in ['X', 'Y'] {
            if w.has(c) {
                return Err(self.err_word(
                    w,
                    c,
                    format!("both a polar coordinate (@ ^) and a {c} word"),
                ));
            }
        }
        if w.g(530).is_some() {
            return Err(self.err_at(at, "polar coordinates (@ ^) with G53"));
        }
        Ok(())
    }

    /// Fanuc G16: a motion block's words for the plane's two axes become the radius and the
    /// angle. Blocks that use axis words as data (G10, G52, G92, G28/G30, G53) keep them.
    pub(super) fn fanuc_polar_words(&mut self, w: &mut Words) {
        if !self.polar.mode {
            return;
        }
        let data = w.gs.iter().any(|g| {
            matches!(
                g.0,
                100 | 280 | 300 | 520 | 530 | 920 | 510 | 511 | 501 | 680
            )
        });
        let moving = self.motion.mode.is_some()
            || w.gs
                .iter()
                .any(|g| super::modal::g_group(g.0) == Some(1) && g.0 != 800);
        if data || !moving {
            return;
        }
        let [a, b, _] = self.modal.plane.axes();
        let la = super::words::letter_index(AXES[a]);
        let lb = super::words::letter_index(AXES[b]);
        if w.used[la] || w.used[lb] {
            return;
        }
        w.polar_r = w.vals[la].take();
        w.polar_a = w.vals[lb].take();
        w.polar_any = w.polar_r.is_some() || w.polar_a.is_some();
        w.polar_open = w.polar_any;
    }

    /// The end point's two plane coordinates from polar words; `t` holds the point the move
    /// would go to without them (the current or programmed point in those axes).
    #[cold]
    pub(super) fn apply_polar(&self, w: &mut Words, t: &mut [f64; 6]) -> R<()> {
        let (r, th) = (w.polar_r.map(|p| p.0), w.polar_a.map(|p| p.0));
        if r.is_none() && th.is_none() {
            return Ok(());
        }
        w.polar_open = false;
        let [a, b, _] = if self.fanuc {
            self.modal.plane.axes()
        } else {
            [0, 1, 2]
        };
        let (x, y) = (t[a], t[b]);
        if self.fanuc {
            let (last_r, last_th) = self
                .polar
                .last
                .get()
                .unwrap_or((x.hypot(y), y.atan2(x).to_degrees()));
            let (cx, cy, r, th) = if self.modal.absolute {
                (0.0, 0.0, r.unwrap_or(last_r), th.unwrap_or(last_th))
            } else {
                (x, y, r.unwrap_or(last_r), last_th + th.unwrap_or(0.0))
            };
            self.polar.last.set(Some((r, th)));
            let (s, c) = th.to_radians().sin_cos();
            t[a] = cx + r * c;
            t[b] = cy + r * s;
            return Ok(());
        }
        let at = self.word_pos(w.polar_r.or(w.polar_a).expect("checked").1);
        let origin = x == 0.0 && y == 0.0;
        if self.modal.absolute {
            let (r, th) = match (r, th) {
                (Some(r), Some(th)) => (r, th.to_radians()),
                (Some(r), None) => {
                    if origin {
                        return Err(self.err_at(at, "polar radius (@) without an angle (^) at the origin: the direction is undefined"));
                    }
                    (r, y.atan2(x))
                }
                (None, th) => (x.hypot(y), th.expect("checked").to_radians()),
            };
            t[0] = r * th.cos();
            t[1] = r * th.sin();
        } else {
            if origin {
                return Err(self.err_at(
                    at,
                    "incremental (G91) polar move from the origin: the direction is undefined",
                ));
            }
            let (mut x, mut y) = (x, y);
            if let Some(dr) = r {
                let (th, r) = (y.atan2(x), x.hypot(y) + dr);
                x = r * th.cos();
                y = r * th.sin();
            }
            if let Some(dth) = th {
                let (th, r) = (y.atan2(x) + dth.to_radians(), x.hypot(y));
                x = r * th.cos();
                y = r * th.sin();
            }
            t[0] = x;
            t[1] = y;
        }
        Ok(())
    }

    /// Polar words in a canned cycle: the hole position in absolute mode, or the radius and
    /// angle increments of every repeat in incremental mode (rs274's convert_cycle_xy).
    pub(super) fn cycle_polar(&mut self, w: &mut Words, aa: &mut f64, bb: &mut f64) -> R<[f64; 2]> {
        if w.polar_r.is_none() && w.polar_a.is_none() {
            return Ok([0.0; 2]);
        }
        if self.fanuc && !self.modal.absolute {
            // Fanuc G16 G91 (the manual's bolt hole circle `G91 Y120.`): the angle advances
            // from the last hole's about the work origin, the radius kept, once per repeat
            // (K). A radius word in G91 would put the polar origin at the current position.
            if let Some((_, i)) = w.polar_r {
                return Err(self.err_at(
                    self.word_pos(i),
                    "G16 radius word in an incremental (G91) canned cycle (polar origin at the current position) is not supported; give the angle only, or the radius in G90",
                ));
            }
            w.polar_open = false;
            return Ok([0.0, w.polar_a.map_or(0.0, |p| p.0.to_radians())]);
        }
        if self.modal.absolute || self.fanuc {
            let mut t = self.cur;
            self.apply_polar(w, &mut t)?;
            let [a, b, _] = if self.fanuc {
                self.modal.plane.axes()
            } else {
                [0, 1, 2]
            };
            *aa = t[a];
            *bb = t[b];
            return Ok([0.0; 2]);
        }
        w.polar_open = false;
        Ok([
            w.polar_r.map_or(0.0, |p| p.0),
            w.polar_a.map_or(0.0, |p| p.0.to_radians()),
        ])
    }

    /// One repeat's step of an incremental polar cycle: the radius, then the angle.
    pub(super) fn polar_step(&self, aa: &mut f64, bb: &mut f64, inc: [f64; 2]) -> R<()> {
        if inc == [0.0; 2] {
            return Ok(());
        }
        if *aa == 0.0 && *bb == 0.0 {
            return Err(self.err_block(
                "incremental (G91) polar move from the origin: the direction is undefined",
            ));
        }
        if inc[0] != 0.0 {
            let (th, r) = (bb.atan2(*aa), aa.hypot(*bb) + inc[0]);
            *aa = r * th.cos();
            *bb = r * th.sin();
        }
        if inc[1] != 0.0 {
            let (th, r) = (bb.atan2(*aa) + inc[1], aa.hypot(*bb));
            *aa = r * th.cos();
            *bb = r * th.sin();
            if self.fanuc {
                // The next G16 block counts from this hole.
                self.polar.last.set(Some((r, th.to_degrees())));
            }
        }
        Ok(())
    }

    /// Polar words that no motion used.
    pub(super) fn unused_polar(&self, w: &Words) -> R<()> {
        match w.polar_r.or(w.polar_a) {
            Some((_, i)) if w.polar_open => Err(self.err_at(
                self.word_pos(i),
                match self.motion.mode {
                    Some(Motion::Cycle(_))
                    | Some(Motion::Rapid | Motion::Linear | Motion::Arc { .. }) => {
                        "polar words with a code that does not take them"
                    }
                    _ => "polar words (@ ^) without a motion that takes them",
                },
            )),
            _ => Ok(()),
        }
    }
}
