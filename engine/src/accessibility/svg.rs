//! A picture of a segment's free region on its section plane (SVG): walls seen along the
//! axis in grey, the reachable piece in blue, the largest tool's circle in red, the section
//! point as a cross, the plunge points as dots and the spiral's tool-centre path as a line.
//! Plane coordinates in mm, y up.

use std::fmt::Write;

use super::evaluate::{Detail, Evaluation};
use super::SegmentReach;

/// What a picture needs of an evaluation, in runs of cells per raster row.
#[derive(Clone, Debug)]
pub struct RegionPicture {
    pub lo: [f64; 2],
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
    /// (row, first column, last column) of covered cells.
    pub walls: Vec<(usize, usize, usize)>,
    /// The same for the reachable piece.
    pub free: Vec<(usize, usize, usize)>,
    pub circle: Option<([f64; 2], f64)>,
    pub plunges: Vec<[f64; 2]>,
    /// The clearing passes' tool-centre paths (the spiral and any other loops).
    pub passes: Vec<Vec<[f64; 2]>>,
    pub tool_radius: Option<f64>,
    pub caption: String,
}

fn runs(nx: usize, ny: usize, on: impl Fn(usize) -> bool) -> Vec<(usize, usize, usize)> {
    let mut out = Vec::new();
    for y in 0..ny {
        let mut x = 0;
        while x < nx {
            if on(y * nx + x) {
                let x0 = x;
                while x + 1 < nx && on(y * nx + x + 1) {
                    x += 1;
                }
                out.push((y, x0, x));
            }
            x += 1;
        }
    }
    out
}

impl RegionPicture {
    pub fn new(e: &Evaluation, d: &Detail, reach: &SegmentReach) -> RegionPicture {
        let r = &e.raster;
        let s = &e.section;
        let plane = |p: &[f64; 3]| {
            let l = s.local(*p);
            [l[0], l[1]]
        };
        RegionPicture {
            lo: r.window.lo,
            cell: r.cell,
            nx: r.nx,
            ny: r.ny,
            walls: runs(r.nx, r.ny, |k| d.covered[k]),
            free: runs(r.nx, r.ny, |k| d.component[k]),
            circle: e.circle.map(|c| (c.center, c.radius)),
            plunges: reach.plunges.iter().map(plane).collect(),
            passes: reach
                .clearing
                .iter()
                .flat_map(|c| c.passes.iter().map(|p| p.points.clone()))
                .collect(),
            tool_radius: reach.tool.as_ref().map(|t| t.diameter_mm / 2.0),
            caption: format!(
                "segment {}: axis ({:.4}, {:.4}, {:.4}), tilt {:.2}°, largest tool Ø{:.3} mm, free area {:.1} mm², reach {:.1} mm",
                reach.segment,
                reach.axis[0],
                reach.axis[1],
                reach.axis[2],
                reach.tilt_deg,
                reach.tool_diameter_mm,
                reach.free_area_mm2,
                reach.reach_mm
            ),
        }
    }

    /// The picture as SVG text, `width` pixels wide.
    pub fn to_svg(&self, width: f64) -> String {
        let w = self.nx as f64 * self.cell;
        let h = self.ny as f64 * self.cell;
        let k = width / w;
        let height = h * k + 40.0;
        // Plane (x, y) to picture pixels, y down.
        let px = |x: f64| (x - self.lo[0]) * k;
        let py = |y: f64| (h - (y - self.lo[1])) * k;
        let mut out = String::new();
        let _ = writeln!(
            out,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0}" height="{height:.0}" viewBox="0 0 {width:.1} {height:.1}">"#
        );
        let _ = writeln!(
            out,
            r##"<rect width="100%" height="100%" fill="#ffffff"/>"##
        );
        for (set, color) in [(&self.walls, "#9a9a9a"), (&self.free, "#8ec5ff")] {
            let _ = writeln!(out, r#"<g fill="{color}">"#);
            for &(y, x0, x1) in set {
                let _ = writeln!(
                    out,
                    r#"<rect x="{:.2}" y="{:.2}" width="{:.2}" height="{:.2}"/>"#,
                    x0 as f64 * self.cell * k,
                    (self.ny - 1 - y) as f64 * self.cell * k,
                    (x1 - x0 + 1) as f64 * self.cell * k,
                    self.cell * k
                );
            }
            let _ = writeln!(out, "</g>");
        }
        if let Some(r) = self.tool_radius {
            for p in &self.plunges {
                let _ = writeln!(
                    out,
                    r##"<circle cx="{:.2}" cy="{:.2}" r="{:.2}" fill="none" stroke="#2a7a2a" stroke-width="0.8"/>"##,
                    px(p[0]),
                    py(p[1]),
                    r * k
                );
            }
        }
        for p in &self.plunges {
            let _ = writeln!(
                out,
                r##"<circle cx="{:.2}" cy="{:.2}" r="1.5" fill="#2a7a2a"/>"##,
                px(p[0]),
                py(p[1])
            );
        }
        for pass in &self.passes {
            let mut d = String::new();
            for (i, p) in pass.iter().enumerate() {
                let _ = write!(
                    d,
                    "{}{:.1} {:.1}",
                    if i == 0 { "M" } else { "L" },
                    px(p[0]),
                    py(p[1])
                );
            }
            let _ = writeln!(
                out,
                r##"<path d="{d}" fill="none" stroke="#e07000" stroke-width="1"/>"##
            );
        }
        if let Some((c, r)) = self.circle {
            let _ = writeln!(
                out,
                r##"<circle cx="{:.2}" cy="{:.2}" r="{:.2}" fill="none" stroke="#d02020" stroke-width="2"/>"##,
                px(c[0]),
                py(c[1]),
                r * k
            );
        }
        let (tx, ty) = (px(0.0), py(0.0));
        let _ = writeln!(
            out,
            r#"<path d="M{:.1} {ty:.1}H{:.1}M{tx:.1} {:.1}V{:.1}" stroke="black" stroke-width="1.5"/>"#,
            tx - 6.0,
            tx + 6.0,
            ty - 6.0,
            ty + 6.0
        );
        let _ = writeln!(
            out,
            r#"<text x="6" y="{:.0}" font-family="sans-serif" font-size="12">{}</text>"#,
            h * k + 16.0,
            self.caption
        );
        let _ = writeln!(
            out,
            r#"<text x="6" y="{:.0}" font-family="sans-serif" font-size="11">grey: walls between the inlet and the section seen along the axis; blue: reachable; red: largest tool; green: plunges; orange: spiral (tool centre); cross: section point; {:.1} mm wide</text>"#,
            h * k + 32.0,
            w
        );
        out.push_str("</svg>\n");
        out
    }
}
