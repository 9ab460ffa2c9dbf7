//! The corner (the edge below the flank, κ < 90°): sampled point by point at the slice
//! centres, each bin's runs settled between the centres by bisection.

use super::{bisect, StepFrame};

/// Marks the corner's bins in material at the centres of slices `j0..jf0` (bit
/// (j − j0)·nb + m), and the slices with any.
pub(super) fn sample_corner(
    f: &StepFrame,
    j0: usize,
    jf0: usize,
    bits: &mut [bool],
    slice_hit: &mut [bool],
) {
    for j in j0..jf0 {
        let z = f.centre(j);
        let ep = f.tool.edge_normal(z);
        if ep.is_none() {
            continue;
        }
        for m in 0..f.nb {
            if f.corner_at(ep, z, m) {
                bits[(j - j0) * f.nb + m] = true;
                slice_hit[j - j0] = true;
            }
        }
    }
}

/// The corner's heights in material per bin: runs of slices whose centres are in
/// material, their ends settled between the centres by bisection, so that a depth of cut
/// need not be a whole number of slices.
pub(super) fn corner_ranges(
    f: &StepFrame,
    j0: usize,
    jf0: usize,
    bits: &[bool],
    zranges: &mut Vec<(usize, f64, f64)>,
) {
    let (dz, pos) = (f.dz, f.pos);
    // On a vertical tool the end is most often where the Z ray under the point in
    // material ends (a level stock top or floor): tried first, and kept when the
    // points just either side of it agree.
    let from_ray = |z_in: f64, z_out: f64, m: usize| -> Option<f64> {
        let ep = f.tool.edge_normal(z_in)?;
        let radial = f.radial(m);
        let ray = f.grid.z_ray(
            pos[0] + radial[0] * (ep.radius + f.out),
            pos[1] + radial[1] * (ep.radius + f.out),
        )?;
        let zi = pos[2] + z_in;
        let iv = ray.iter().find(|iv| iv[0] <= zi && zi <= iv[1])?;
        let end = if z_out > z_in { iv[1] } else { iv[0] } - pos[2];
        let eps = (z_out - z_in) / 256.0;
        let inside = (end - z_in) * (z_out - end) > 0.0;
        (inside && f.corner_in(end - eps, m) && !f.corner_in(end + eps, m)).then_some(end)
    };
    let settle = |z_in: f64, z_out: f64, m: usize| {
        if f.vertical {
            if let Some(end) = from_ray(z_in, z_out, m) {
                return end;
            }
        }
        bisect(z_in, z_out, |z| f.corner_in(z, m))
    };
    let top = (jf0 as f64 * dz).min(f.length);
    let zp = (j0 as f64 + 1.0 / 16.0) * dz;
    let probe = f.tool.edge_normal(zp);
    for m in 0..f.nb {
        let bit = |j: usize| bits[(j - j0) * f.nb + m];
        // A layer thinner than half a slice, under the first centre.
        if !bit(j0) && f.corner_at(probe, zp, m) {
            zranges.push((m, j0 as f64 * dz, settle(zp, f.centre(j0), m)));
        }
        let mut j = j0;
        while j < jf0 {
            if !bit(j) {
                j += 1;
                continue;
            }
            let ja = j;
            while j < jf0 && bit(j) {
                j += 1;
            }
            let lo = if ja == j0 {
                ja as f64 * dz
            } else {
                settle(f.centre(ja), f.centre(ja - 1), m)
            };
            let hi = if j < jf0 {
                settle(f.centre(j - 1), f.centre(j), m)
            } else if f.corner_in(top, m) {
                top
            } else {
                settle(f.centre(j - 1), top, m)
            };
            zranges.push((m, lo, hi));
        }
    }
}
