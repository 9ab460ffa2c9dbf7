//! How far a set of engaged arcs reaches (entry, exit, the bounds of cos φ).

use std::f64::consts::PI;

use crate::engagement::Arcs;

/// Where a set of engaged arcs reaches: the bounds of cos φ over them (for the radial
/// width), the first entry and the last exit angle.
#[derive(Clone, Copy, Debug)]
pub(super) struct Spread {
    pub(super) cmax: f64,
    pub(super) cmin: f64,
    pub(super) entry: f64,
    pub(super) exit: f64,
}

impl Spread {
    pub(super) const NONE: Spread = Spread {
        cmax: f64::NEG_INFINITY,
        cmin: f64::INFINITY,
        entry: f64::INFINITY,
        exit: f64::NEG_INFINITY,
    };

    /// The arc (s, e): cos φ is largest at φ = 0 and smallest at π, else at an end.
    pub(super) fn of_arc(s: f64, e: f64) -> Spread {
        Spread {
            cmax: if s <= 0.0 || e >= 2.0 * PI - 1e-12 {
                1.0
            } else {
                s.cos().max(e.cos())
            },
            cmin: if s <= PI && PI <= e {
                -1.0
            } else {
                s.cos().min(e.cos())
            },
            entry: s,
            exit: e,
        }
    }

    /// The union's spread (exactly that of the arcs the union forms, bins being arcs).
    pub(super) fn join(self, o: Spread) -> Spread {
        Spread {
            cmax: self.cmax.max(o.cmax),
            cmin: self.cmin.min(o.cmin),
            entry: self.entry.min(o.entry),
            exit: self.exit.max(o.exit),
        }
    }

    pub(super) fn of_arcs(arcs: &Arcs) -> Spread {
        arcs.iter()
            .fold(Spread::NONE, |sp, &(s, e)| sp.join(Spread::of_arc(s, e)))
    }
}
