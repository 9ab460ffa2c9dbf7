//! [`PeakResponse`]: peak |F|, torque and chip of one engagement as exact functions of the
//! feed per tooth (a tool without runout), and [`Peaks`], their values at one feed.

use crate::vec3::dot;

/// Peak |F|, peak torque and the thickest chip of one engagement as functions of the feed
/// per tooth fz over a range, for a tool without runout: each sample's force is fz·A + E,
/// so |F|² = a·fz² + 2b·fz + c and the torque a·fz + b. Only the samples that can hold
/// the peak somewhere in the range are kept: a sample is dropped when one of the samples
/// that peak at a few feeds across the range is at least as large over the whole range,
/// so the maximum over the kept samples is the maximum over all of them.
#[derive(Clone, Debug, PartialEq)]
pub struct PeakResponse {
    range: (f64, f64),
    force: Vec<[f64; 3]>,
    /// Torque, N·mm.
    torque: Vec<[f64; 2]>,
    /// Thickest chip per unit feed per tooth.
    chip: f64,
}

/// What [`PeakResponse::at`] gives: peak |F| (N), peak torque (N·m), thickest chip (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peaks {
    pub force: f64,
    pub torque: f64,
    pub chip: f64,
}

impl PeakResponse {
    pub(super) fn new(
        tot_a: &[f64],
        tot_e: &[f64],
        kpos: usize,
        tooth_hmax: &[f64],
        range: (f64, f64),
    ) -> PeakResponse {
        let comp = |t: &[f64], c: usize, i: usize| t[c * kpos + i];
        let mut quads = Vec::with_capacity(kpos);
        let mut lines = Vec::with_capacity(kpos);
        for i in 0..kpos {
            let a = [0, 1, 2].map(|c| comp(tot_a, c, i));
            let e = [0, 1, 2].map(|c| comp(tot_e, c, i));
            quads.push([dot(a, a), dot(a, e), dot(e, e)]);
            lines.push([comp(tot_a, 3, i), comp(tot_e, 3, i)]);
        }
        let (lo, hi) = range;
        let quad = |q: &[f64; 3], t: f64| (q[0] * t + 2.0 * q[1]) * t + q[2];
        let line = |l: &[f64; 2], t: f64| l[0] * t + l[1];
        // Leaders: the largest sample at a few feeds across the range.
        const PROBES: usize = 5;
        let probes: [f64; PROBES] = [0.0, 1.0, 0.5, 0.25, 0.75].map(|w| lo + w * (hi - lo));
        let (mut fl, mut fv) = ([0usize; PROBES], [f64::NEG_INFINITY; PROBES]);
        let (mut tl, mut tv) = ([0usize; PROBES], [f64::NEG_INFINITY; PROBES]);
        for i in 0..kpos {
            for p in 0..PROBES {
                let (q, l) = (quad(&quads[i], probes[p]), line(&lines[i], probes[p]));
                if q > fv[p] {
                    (fv[p], fl[p]) = (q, i);
                }
                if l > tv[p] {
                    (tv[p], tl[p]) = (l, i);
                }
            }
        }
        // A lower bound of the envelope over the range: the largest leader minimum. |F|² is
        // convex in the feed and the torque affine, so a sample's maximum over the range is
        // at an end; a sample whose ends stay under that bound cannot hold the peak.
        let quad_min = |q: &[f64; 3]| {
            let mut m = quad(q, lo).min(quad(q, hi));
            if q[0] > 0.0 {
                let v = -q[1] / q[0];
                if v > lo && v < hi {
                    m = m.min(quad(q, v));
                }
            }
            m
        };
        let force_floor = fl
            .iter()
            .map(|&j| quad_min(&quads[j]))
            .fold(f64::NEG_INFINITY, f64::max);
        let torque_floor = tl
            .iter()
            .map(|&j| line(&lines[j], lo).min(line(&lines[j], hi)))
            .fold(f64::NEG_INFINITY, f64::max);
        // q_j ≥ q_i over [lo, hi]: the difference, a parabola, is ≥ 0 at the ends and, when it
        // opens upwards with its vertex inside, at the vertex.
        let covers = |j: usize, i: usize| {
            let (qj, qi) = (&quads[j], &quads[i]);
            quad_min(&[qj[0] - qi[0], qj[1] - qi[1], qj[2] - qi[2]]) >= 0.0
        };
        let force = (0..kpos)
            .filter(|&i| {
                if fl.contains(&i) {
                    return true;
                }
                let top = quad(&quads[i], lo).max(quad(&quads[i], hi));
                top > force_floor && !fl.iter().any(|&j| covers(j, i))
            })
            .map(|i| quads[i])
            .collect();
        let torque = (0..kpos)
            .filter(|&i| {
                if tl.contains(&i) {
                    return true;
                }
                let (a, b) = (line(&lines[i], lo), line(&lines[i], hi));
                a.max(b) > torque_floor
                    && !tl
                        .iter()
                        .any(|&j| line(&lines[j], lo) >= a && line(&lines[j], hi) >= b)
            })
            .map(|i| lines[i])
            .collect();
        PeakResponse {
            range,
            force,
            torque,
            chip: tooth_hmax.iter().copied().fold(0.0, f64::max),
        }
    }

    /// The feed-per-tooth range the response holds for, mm.
    pub fn range(&self) -> (f64, f64) {
        self.range
    }

    /// Peaks at feed per tooth `fz` (mm), None outside the range.
    pub fn at(&self, fz: f64) -> Option<Peaks> {
        let (lo, hi) = self.range;
        if !(fz >= lo * (1.0 - 1e-12) && fz <= hi * (1.0 + 1e-12)) {
            return None;
        }
        let f2 = self
            .force
            .iter()
            .map(|q| (q[0] * fz + 2.0 * q[1]) * fz + q[2])
            .fold(0.0, f64::max);
        let t = self
            .torque
            .iter()
            .map(|l| l[0] * fz + l[1])
            .fold(f64::NEG_INFINITY, f64::max);
        Some(Peaks {
            force: f2.sqrt(),
            torque: t * 1e-3,
            chip: (self.chip * fz).max(0.0),
        })
    }
}
