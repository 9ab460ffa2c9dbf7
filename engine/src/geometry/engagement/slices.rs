//! The engaged slices assembled from the heights in material per bin, and the step's
//! metrics from them.

use super::super::sweep::ToolBody;
use super::spread::Spread;
use super::{StepFrame, StepMetrics};
use crate::engagement::{Arcs, EngagedSlice};

/// The buffers `slices_of_ranges` works in (see `Scratch`).
pub(super) struct Assembly<'s> {
    pub(super) edges: &'s mut Vec<(usize, bool, usize)>,
    pub(super) sorted: &'s mut Vec<(usize, bool, usize)>,
    pub(super) at_slice: &'s mut Vec<usize>,
    pub(super) marks: &'s mut Vec<bool>,
    pub(super) parts: &'s mut Vec<(usize, usize, f64, f64)>,
    pub(super) cuts: &'s mut Vec<usize>,
    pub(super) row: &'s mut Vec<bool>,
    pub(super) depth: &'s mut Vec<u32>,
    pub(super) sub: &'s mut Vec<f64>,
    pub(super) bin_spread: &'s [Spread],
}

/// The engaged slices of the heights in material per bin, and the step's metrics from
/// them. Each height range is the whole slices it covers and the parts of at most two
/// slices it covers in part. Slices of a range share their arcs with their neighbours
/// except where some bin's range starts or ends, so runs of whole slices between those
/// breaks share arcs found once per run.
pub(super) fn slices_of_ranges(
    f: &StepFrame,
    body: &ToolBody,
    zranges: &[(usize, f64, f64)],
    buf: Assembly,
    slices: &mut Vec<EngagedSlice>,
    met: &mut StepMetrics,
) {
    let (nb, dz, dphi, tool) = (f.nb, f.dz, f.dphi, f.tool);
    let Assembly {
        edges,
        sorted,
        at_slice,
        marks,
        parts,
        cuts,
        row,
        depth,
        sub,
        bin_spread,
    } = buf;
    // The arcs of a row of bins.
    let arcs_in = |row: &[bool]| arcs_of_bins(&row[..nb], dphi);
    // A slice's metrics from the spread of all its engaged arcs: entry, exit, radial
    // width at the edge's radius at height `z`, and the edge length over [z0, z1].
    let measure = |sp: Spread, z: f64, z0: f64, z1: f64, met: &mut StepMetrics| {
        met.entry_angle = met.entry_angle.min(sp.entry);
        met.exit_angle = met.exit_angle.max(sp.exit);
        if let Some(ep) = tool.edge_normal(z) {
            met.radial_width = met.radial_width.max(ep.radius * (sp.cmax - sp.cmin));
            met.engaged_edge_length += body.profile_length(z0, z1);
        }
    };
    let mut push = |z: f64, h: f64, arcs: Arcs| {
        if tool.edge_normal(z).is_some() {
            slices.push(EngagedSlice { z, dz: h, arcs });
        }
    };
    edges.clear();
    parts.clear();
    for &(m, lo, hi) in zranges.iter() {
        let (lo, hi) = (snap_to_slices(lo, dz), snap_to_slices(hi, dz));
        if !(hi > lo) {
            continue;
        }
        let (jl, jh) = ((lo / dz).ceil(), (hi / dz).floor());
        if jl < jh {
            edges.push((jl as usize, true, m));
            edges.push((jh as usize, false, m));
        }
        if lo < jl * dz {
            parts.push((jl as usize - 1, m, lo, hi.min(jl * dz)));
        }
        if jh >= jl && hi > jh * dz {
            parts.push((jh as usize, m, jh * dz, hi));
        }
    }
    if edges.is_empty() && parts.is_empty() {
        return;
    }
    // By slice, and in a slice by the heights covered, so that bins covering the same
    // heights are neighbours.
    parts.sort_unstable_by(|p, q| {
        (p.0.cmp(&q.0))
            .then(p.2.total_cmp(&q.2))
            .then(p.3.total_cmp(&q.3))
            .then(p.1.cmp(&q.1))
    });
    // Where whole-slice ranges open and close, in slice order (by counting: slice indices
    // are few), swept once below: the bins in material per run of slices follow from
    // them. The runs break at the slices holding an edge or a part.
    let n = edges
        .iter()
        .map(|e| e.0)
        .chain(parts.iter().map(|p| p.0 + 1))
        .max()
        .map_or(0, |j| j + 1);
    at_slice.clear();
    at_slice.resize(n + 1, 0);
    marks.clear();
    marks.resize(n, false);
    for e in edges.iter() {
        at_slice[e.0 + 1] += 1;
        marks[e.0] = true;
    }
    for p in parts.iter() {
        marks[p.0] = true;
        marks[p.0 + 1] = true;
    }
    for j in 0..n {
        at_slice[j + 1] += at_slice[j];
    }
    sorted.clear();
    sorted.resize(edges.len(), (0, false, 0));
    for &e in edges.iter() {
        sorted[at_slice[e.0]] = e;
        at_slice[e.0] += 1;
    }
    let edges = &*sorted;
    cuts.clear();
    cuts.extend((0..n).filter(|&j| marks[j]));
    row.clear();
    row.resize(nb, false);
    // Per bin, how many of its whole-slice ranges hold the current slice.
    depth.clear();
    depth.resize(nb, 0);
    let (mut next_edge, mut open_bins) = (0, 0usize);
    let mut next_part = 0;
    for w in cuts.windows(2) {
        let (ja, jb) = (w[0], w[1]);
        // Every edge's slice is a cut: the edges up to `ja` are those at it.
        while let Some(&(j, opens, m)) = edges.get(next_edge) {
            if j > ja {
                break;
            }
            if opens {
                depth[m] += 1;
                open_bins += (depth[m] == 1) as usize;
            } else {
                depth[m] -= 1;
                open_bins -= (depth[m] == 0) as usize;
            }
            row[m] = depth[m] > 0;
            next_edge += 1;
        }
        let any = open_bins > 0;
        let first_part = next_part;
        while next_part < parts.len() && parts[next_part].0 == ja {
            next_part += 1;
        }
        if first_part == next_part {
            if !any {
                continue;
            }
            let arcs = arcs_in(row);
            let spread = Spread::of_arcs(&arcs);
            for j in ja..jb {
                let z = f.centre(j);
                measure(spread, z, z - 0.5 * dz, z + 0.5 * dz, met);
                push(z, dz, arcs.clone());
            }
            continue;
        }
        // A slice covered in part (the cuts hold its index and the next). Each bin is
        // cut over its own heights, bins covering the same heights together: the force
        // model then samples each bin once in the slice, as in a whole slice, rather
        // than once per height where some other bin's range ends.
        let (z0, z1) = (ja as f64 * dz, (ja + 1) as f64 * dz);
        let in_slice = &parts[first_part..next_part];
        let row_arcs = any.then(|| arcs_in(row));
        let row_spread = row_arcs.as_ref().map_or(Spread::NONE, Spread::of_arcs);
        // The slice's metrics: at each height between the ends of its bins' ranges,
        // from all the bins in material there.
        sub.clear();
        sub.extend([z0, z1]);
        for p in in_slice {
            sub.extend([p.2, p.3]);
        }
        sub.sort_unstable_by(f64::total_cmp);
        sub.dedup();
        for c in sub.windows(2) {
            let (c0, c1) = (c[0], c[1]);
            if c1 - c0 <= 1e-9 * dz {
                continue;
            }
            // The parts covering [c0, c1]: those starting at c0 or below, the first ones
            // of `in_slice` (sorted by their start), that end at c1 or above.
            let (mut spread, mut hit) = (row_spread, any);
            for p in in_slice {
                if p.2 > c0 {
                    break;
                }
                if c1 <= p.3 {
                    spread = spread.join(bin_spread[p.1]);
                    hit = true;
                }
            }
            if hit {
                measure(spread, 0.5 * (c0 + c1), c0, c1, met);
            }
        }
        if let Some(arcs) = row_arcs {
            push(f.centre(ja), dz, arcs);
        }
        // Bins covering the same heights are neighbours in `in_slice`, in bin order.
        let mut g = 0;
        while g < in_slice.len() {
            let (lo, hi) = (in_slice[g].2, in_slice[g].3);
            let mut arcs = Arcs::new();
            while g < in_slice.len() && in_slice[g].2 == lo && in_slice[g].3 == hi {
                let m = in_slice[g].1;
                let (s, e) = (m as f64 * dphi, (m + 1) as f64 * dphi);
                match arcs.last_mut() {
                    Some(last) if last.1 == s => last.1 = e,
                    _ => arcs.push((s, e)),
                }
                g += 1;
            }
            if hi - lo > 1e-9 * dz {
                push(0.5 * (lo + hi), hi - lo, arcs);
            }
        }
    }
}

/// The arcs of a row of bins (bin m spans [m, m + 1)·dphi): one per run of set bins.
pub(in crate::geometry) fn arcs_of_bins(row: &[bool], dphi: f64) -> Arcs {
    let nb = row.len();
    let mut arcs = Arcs::new();
    let mut m = 0;
    while m < nb {
        if row[m] {
            let start = m;
            while m < nb && row[m] {
                m += 1;
            }
            arcs.push((start as f64 * dphi, m as f64 * dphi));
        } else {
            m += 1;
        }
    }
    arcs
}

/// `z` on the nearest slice boundary when it is within rounding of one (a cut whose depth
/// is a whole number of slices keeps whole slices).
pub(super) fn snap_to_slices(z: f64, dz: f64) -> f64 {
    let k = (z / dz).round();
    if ((z / dz) - k).abs() <= 1e-9 {
        k * dz
    } else {
        z
    }
}
