//! Accessibility of a synthetic closed impeller (hub and shroud of revolution, seven ruled
//! blades), checked by brute force: a dense search of axes over the cone and of positions on
//! the section, with the walls sampled as points (no projection of triangles, no distance
//! transform, no hill-climb). Then the emitted roughing program is simulated against the
//! impeller's stock with the design part.

mod parts;

use std::collections::BTreeMap;

use millsim_engine::accessibility::program::{
    roughing_program, RoughingOptions, RoughingProgram, Strategy,
};
use millsim_engine::accessibility::{analyze, angle_deg, AccessRequest};
use millsim_engine::geometry::Mesh;
use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::machine::{Kinematics, Machine};
use millsim_engine::nc::InterpretOptions;
use millsim_engine::physics::Material;
use millsim_engine::pipeline::{
    simulate, AxisReading, SimulateSpec, SimulationOutput, StockSource,
};
use millsim_engine::tool::{HolderSegment, Tool};
use parts::{stl_bytes, Impeller};

type V3 = [f64; 3];

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn unit(a: V3) -> V3 {
    let n = dot(a, a).sqrt();
    a.map(|c| c / n)
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
/// Two unit vectors across `u` (the brute force's own frame).
fn across(u: V3) -> (V3, V3) {
    let r = if u[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let a = unit(cross(r, u));
    (a, cross(u, a))
}

/// Points on every triangle, no two neighbours more than `spacing` apart.
fn surface_points(mesh: &Mesh, spacing: f64) -> Vec<V3> {
    let mut out = Vec::new();
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        let len = |p: V3, q: V3| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        };
        let n = ((len(a, b).max(len(b, c)).max(len(c, a))) / spacing)
            .ceil()
            .max(1.0) as usize;
        for i in 0..=n {
            for j in 0..=n - i {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let w = 1.0 - u - v;
                out.push(std::array::from_fn(|k| u * a[k] + v * b[k] + w * c[k]));
            }
        }
    }
    out
}

/// Brute force for one axis: positions on a square lattice (`step`) of the section plane
/// through `target`, the clearance of each the distance (across the axis) to the nearest
/// wall point at or above the section; the free positions connected to the target's; the
/// best of them. Returns (radius, centre in 3-D).
fn brute_force_axis(points: &[V3], target: V3, u: V3, step: f64, free_above: f64) -> (f64, V3) {
    let (a, b) = across(u);
    // Points are bucketed over ±2·half; positions stay within ±half, so a point outside the
    // buckets is farther from any of them than the buckets' edge.
    let half = 40.0;
    let outer = 2.0 * half;
    let bucket = 1.0;
    let nb = (2.0 * outer / bucket) as usize + 1;
    let mut grid: Vec<Vec<[f64; 2]>> = vec![Vec::new(); nb * nb];
    for p in points {
        let d = [p[0] - target[0], p[1] - target[1], p[2] - target[2]];
        if dot(d, u) < 0.0 {
            continue;
        }
        let q = [dot(d, a), dot(d, b)];
        let (i, j) = (
            ((q[0] + outer) / bucket).floor(),
            ((q[1] + outer) / bucket).floor(),
        );
        if i >= 0.0 && j >= 0.0 && (i as usize) < nb && (j as usize) < nb {
            grid[j as usize * nb + i as usize].push(q);
        }
    }
    let clearance = |c: [f64; 2]| -> f64 {
        let mut best = (outer - c[0].abs()).min(outer - c[1].abs());
        let (ci, cj) = (
            ((c[0] + outer) / bucket).floor() as isize,
            ((c[1] + outer) / bucket).floor() as isize,
        );
        for ring in 0..nb as isize {
            if ring > 0 && (ring - 1) as f64 * bucket >= best {
                break;
            }
            for j in cj - ring..=cj + ring {
                for i in ci - ring..=ci + ring {
                    if (i - ci).abs() != ring && (j - cj).abs() != ring {
                        continue;
                    }
                    if i < 0 || j < 0 || i >= nb as isize || j >= nb as isize {
                        continue;
                    }
                    for q in &grid[j as usize * nb + i as usize] {
                        best = best.min((q[0] - c[0]).hypot(q[1] - c[1]));
                    }
                }
            }
        }
        best
    };
    let n = (2.0 * half / step) as isize;
    let idx = |i: isize, j: isize| ((j + n) * (2 * n + 1) + (i + n)) as usize;
    let mut seen = vec![false; ((2 * n + 1) * (2 * n + 1)) as usize];
    let mut best = (0.0, target);
    let c0 = clearance([0.0, 0.0]);
    if c0 <= free_above {
        return best;
    }
    let mut stack = vec![(0isize, 0isize)];
    seen[idx(0, 0)] = true;
    while let Some((i, j)) = stack.pop() {
        let c = [i as f64 * step, j as f64 * step];
        let r = clearance(c);
        if r <= free_above {
            continue;
        }
        if r > best.0 {
            best = (
                r,
                std::array::from_fn(|k| target[k] + c[0] * a[k] + c[1] * b[k]),
            );
        }
        for (di, dj) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
            let (p, q) = (i + di, j + dj);
            if p.abs() <= n && q.abs() <= n && !seen[idx(p, q)] {
                seen[idx(p, q)] = true;
                stack.push((p, q));
            }
        }
    }
    best
}

/// The clearance of one (axis, centre) by the points: the distance across the axis to the
/// nearest wall point at or above the section.
fn brute_force_clearance(points: &[V3], center: V3, u: V3) -> f64 {
    points
        .iter()
        .filter_map(|p| {
            let d = [p[0] - center[0], p[1] - center[1], p[2] - center[2]];
            let t = dot(d, u);
            (t >= 0.0).then(|| (dot(d, d) - t * t).max(0.0).sqrt())
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn impeller_axis_and_diameter_match_a_dense_brute_force_search() {
    let imp = Impeller::test_part();
    let mesh = imp.mesh();
    let entry = imp.passage_point(0.0);
    let target = imp.passage_point(0.5);
    let mut request = AccessRequest::new(entry, target);
    request.max_tilt_deg = 20.0;
    let clock = std::time::Instant::now();
    let report = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
    let took = clock.elapsed().as_secs_f64();
    let r = report.target();
    eprintln!(
        "impeller ({} triangles): axis {:?}, tilt {:.2}°, Ø{:.3}, area {:.1} mm², reach {:.1} mm, {} axes in {took:.2} s",
        mesh.triangles.len(),
        r.axis,
        r.tilt_deg,
        r.tool_diameter_mm,
        r.free_area_mm2,
        r.reach_mm,
        report.evaluations
    );
    assert!(r.tool_diameter_mm > 2.0, "{r:?}");

    let spacing = 0.4;
    // The impeller's far side (over 80 mm from the target) is left out: every wall of the
    // passage and its neighbours lies within that.
    let points: Vec<V3> = surface_points(&mesh, spacing)
        .into_iter()
        .filter(|p| {
            let d = [p[0] - target[0], p[1] - target[1], p[2] - target[2]];
            dot(d, d) < 80.0 * 80.0
        })
        .collect();
    // Sampled walls are at most `spacing` from any wall point: a sampled clearance is at
    // least the true one and at most `spacing` more.
    let ours = brute_force_clearance(&points, r.center.unwrap(), r.axis);
    assert!(
        ours + 1e-9 >= r.tool_diameter_mm / 2.0,
        "the reported tool touches a wall: clearance {ours} < radius {}",
        r.tool_diameter_mm / 2.0
    );
    // Dense axes: every 4° over the cone, then every 0.5° within 3° of the best.
    let d0 = unit([
        entry[0] - target[0],
        entry[1] - target[1],
        entry[2] - target[2],
    ]);
    let (b1, b2) = across(d0);
    let axis_at = |x: f64, y: f64| -> V3 {
        let (tx, ty) = (x.to_radians().tan(), y.to_radians().tan());
        unit(std::array::from_fn(|k| d0[k] + tx * b1[k] + ty * b2[k]))
    };
    let step = 0.25;
    let sweep = |centre: (f64, f64), pitch: f64, half: i32, limit: f64| {
        let mut best = (0.0, [0.0; 3], [0.0; 3], (0.0, 0.0));
        let grid: Vec<(f64, f64)> = (-half..=half)
            .flat_map(|i| (-half..=half).map(move |j| (i, j)))
            .map(|(i, j)| (centre.0 + i as f64 * pitch, centre.1 + j as f64 * pitch))
            .filter(|&(x, y)| angle_deg(axis_at(x, y), d0) <= limit + 1e-9)
            .collect();
        let results: Vec<_> = std::thread::scope(|s| {
            let chunks: Vec<_> = grid.chunks(grid.len().div_ceil(2)).collect();
            let handles: Vec<_> = chunks
                .into_iter()
                .map(|c| {
                    s.spawn(|| {
                        c.iter()
                            .map(|&(x, y)| {
                                let u = axis_at(x, y);
                                let (rad, at) = brute_force_axis(&points, target, u, step, spacing);
                                (rad, u, at, (x, y))
                            })
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                .flat_map(|h| h.join().unwrap())
                .collect()
        });
        for res in results {
            if res.0 > best.0 {
                best = res;
            }
        }
        best
    };
    let coarse = sweep((0.0, 0.0), 4.0, 5, 20.0);
    let fine = sweep(coarse.3, 0.5, 6, 20.0);
    let bf = if fine.0 > coarse.0 { fine } else { coarse };
    let off = angle_deg(bf.1, r.axis);
    eprintln!(
        "brute force: axis {:?} (tilt {:.2}°), Ø{:.3} at {:?}; ours {off:.2}° from it",
        bf.1,
        angle_deg(bf.1, d0),
        2.0 * bf.0,
        bf.2
    );
    // The brute force overstates a clearance by at most the sampling (and finds the best
    // position to within half a lattice diagonal): ours is no worse than that.
    let slack = spacing + step * std::f64::consts::FRAC_1_SQRT_2;
    assert!(
        r.tool_diameter_mm / 2.0 >= bf.0 - slack,
        "brute force finds Ø{:.3}, ours Ø{:.3}",
        2.0 * bf.0,
        r.tool_diameter_mm
    );
    // And the brute force's best lattice position cannot beat ours by more than that either
    // at the brute force's own axis (ours is the exact optimum of the projected walls).
    assert!(
        r.tool_diameter_mm / 2.0 <= bf.0 + slack,
        "ours Ø{} above the brute force Ø{}",
        r.tool_diameter_mm,
        2.0 * bf.0
    );
    assert!(off < 2.0, "axis {off:.2}° from the brute force's");

    // A picture of the free region for the note.
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let path = dir.join("accessibility_impeller_free_region.svg");
    std::fs::write(&path, report.regions.last().unwrap().to_svg(640.0)).unwrap();
    eprintln!("free region picture: {}", path.display());
}

/// Runs `program` on the impeller's stock with the design part at 0.25 mm.
fn simulate_program(
    program: &RoughingProgram,
    part: &Mesh,
    stock: &Mesh,
    machine: Machine,
) -> SimulationOutput {
    let tools: BTreeMap<u32, _> = program
        .tools
        .iter()
        .map(|t| (t.number, t.tool.clone()))
        .collect();
    let spec = SimulateSpec {
        program: program.text.clone(),
        interpret: InterpretOptions::default(),
        stock: StockSource::Stl(stl_bytes(stock).into()),
        tools,
        material: Material::builtin("Al7075-T6").unwrap(),
        machine,
        cell: Some(0.25),
        memory_limit: 4 << 30,
        force_positions: 36,
        optimize: None,
        axes: AxisReading::Machine,
        workpiece: None,
        chatter: None,
        part: Some(stl_bytes(part).into()),
        fixture: None,
    };
    simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap()
}

#[test]
fn impeller_roughing_program_simulates_without_gouge_or_holder_contact() {
    let imp = Impeller::test_part();
    let part = imp.mesh();
    let stock = Impeller {
        filled: true,
        ..imp
    }
    .mesh();
    let entry = imp.passage_point(0.0);
    let target = imp.passage_point(0.5);
    let mut request = AccessRequest::new(entry, target);
    request.segments = 2;
    request.allowance = 0.6;
    // The holder starts 45 mm above the tip: it stays above the inlet.
    request.stickout = Some(45.0);
    request.holder = vec![HolderSegment {
        length: 60.0,
        bottom_diameter: 32.0,
        top_diameter: 32.0,
    }];
    let report = analyze(&part, &request, &CancelFlag::new()).unwrap();
    for s in &report.segments {
        eprintln!(
            "segment {}: axis {:?}, Ø{:.3}, reach {:.1} mm, {} plunges",
            s.segment,
            s.axis,
            s.tool_diameter_mm,
            s.reach_mm,
            s.plunges.len()
        );
        assert!(s.tool_diameter_mm > 1.0 && !s.plunges.is_empty(), "{s:?}");
    }
    let machine = Machine {
        kinematics: Kinematics::XyzAc,
        ..Machine::generic()
    };
    let program = roughing_program(
        &part,
        &request,
        &report,
        &machine,
        &RoughingOptions::default(),
    )
    .unwrap();
    assert!(
        program.text.contains("T1 M6") && program.text.contains("T2 M6"),
        "{}",
        program.text
    );
    let out = simulate_program(&program, &part, &stock, machine);
    let s = &out.summary;
    let cmp = s.part.clone().unwrap();
    eprintln!(
        "simulated: removed {:.0} mm³ in {:.0} s of cycle time; gouge {:.4} mm³; holder/shank contacts {}; rapids in material {}; flutes exceeded {}; allowance min {:.3} mm",
        s.removed_volume,
        s.cycle_time_s,
        cmp.gouge_volume,
        s.holder_or_shank_contact_moves,
        s.rapid_in_material_moves,
        s.flute_length_exceeded_moves,
        cmp.allowance_min
    );
    assert_eq!(s.holder_or_shank_contact_moves, 0, "{:?}", s.collisions);
    assert_eq!(s.rapid_in_material_moves, 0, "{:?}", s.collisions);
    assert!(cmp.gouge_volume < 1e-6, "gouge {:?}", cmp);
    // It removed material from the passage, and no more than the passage holds.
    let passage = stock.volume() - part.volume();
    assert!(
        s.removed_volume > 0.02 * passage / imp.blades as f64,
        "{} of {passage}",
        s.removed_volume
    );
    assert!(s.removed_volume < passage / imp.blades as f64);
}

/// With a listed tool smaller than the largest, the spiral strategy (helical entry, offset
/// spiral, depth by depth) against the plunges of the same tool at the same points: both
/// clean, the spiral removes more.
#[test]
fn impeller_spiral_clearing_removes_more_than_plunges_without_gouge() {
    let imp = Impeller::test_part();
    let part = imp.mesh();
    let stock = Impeller {
        filled: true,
        ..imp
    }
    .mesh();
    let mut request = AccessRequest::new(imp.passage_point(0.0), imp.passage_point(0.5));
    request.segments = 2;
    request.allowance = 0.6;
    request.stickout = Some(45.0);
    request.holder = vec![HolderSegment {
        length: 60.0,
        bottom_diameter: 32.0,
        top_diameter: 32.0,
    }];
    let mut tool = Tool::flat(8.0, 3);
    tool.flute_length = 35.0;
    request.tools = vec![tool];
    let report = analyze(&part, &request, &CancelFlag::new()).unwrap();
    let machine = Machine {
        kinematics: Kinematics::XyzAc,
        ..Machine::generic()
    };
    let mut removed = Vec::new();
    for strategy in [Strategy::Plunge, Strategy::Spiral] {
        let options = RoughingOptions {
            strategy,
            ..RoughingOptions::default()
        };
        let program = roughing_program(&part, &request, &report, &machine, &options).unwrap();
        let out = simulate_program(&program, &part, &stock, machine.clone());
        let s = &out.summary;
        let cmp = s.part.as_ref().unwrap();
        eprintln!(
            "{strategy:?}: {} lines, tools {:?}; removed {:.0} mm³ in {:.0} s of cycle time; gouge {:.4} mm³; holder/shank contacts {}; rapids in material {}; allowance min {:.3} mm",
            program.text.lines().count(),
            program
                .tools
                .iter()
                .map(|t| (t.segment, t.depths, t.passes, t.helices, t.plunges, t.feed_length_mm.round()))
                .collect::<Vec<_>>(),
            s.removed_volume,
            s.cycle_time_s,
            cmp.gouge_volume,
            s.holder_or_shank_contact_moves,
            s.rapid_in_material_moves,
            cmp.allowance_min
        );
        assert_eq!(s.holder_or_shank_contact_moves, 0, "{:?}", s.collisions);
        assert_eq!(s.rapid_in_material_moves, 0, "{:?}", s.collisions);
        assert!(cmp.gouge_volume < 1e-6, "gouge {:?}", cmp);
        if strategy == Strategy::Spiral {
            assert!(program
                .tools
                .iter()
                .all(|t| t.helices >= 1 && t.depths >= 2));
        }
        removed.push(s.removed_volume);
    }
    assert!(
        removed[1] > 1.2 * removed[0],
        "spiral {} mm³ against plunges {} mm³",
        removed[1],
        removed[0]
    );
}

/// The speed figure of the note: a 200k-triangle impeller, a 20° cone. Run with
/// `cargo test --release -p millsim-engine --test accessibility_impeller -- --ignored --nocapture`.
#[test]
#[ignore]
fn impeller_of_200k_triangles_is_answered_in_seconds() {
    let imp = Impeller {
        along: 84,
        across: 12,
        per_pitch: 40,
        blade_cells: 10,
        ..Impeller::test_part()
    };
    let clock = std::time::Instant::now();
    let mesh = imp.mesh();
    let built = clock.elapsed().as_secs_f64();
    let mut request = AccessRequest::new(imp.passage_point(0.0), imp.passage_point(0.5));
    request.max_tilt_deg = 20.0;
    let clock = std::time::Instant::now();
    let report = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
    let took = clock.elapsed().as_secs_f64();
    let r = report.target();
    eprintln!(
        "{} triangles (built in {built:.1} s): Ø{:.3}, tilt {:.2}°, {} axes evaluated in {took:.2} s on {} threads",
        mesh.triangles.len(),
        r.tool_diameter_mm,
        r.tilt_deg,
        report.evaluations,
        rayon::current_num_threads()
    );
    assert!(mesh.triangles.len() >= 190_000);
    assert!(r.tool_diameter_mm > 2.0);
}
