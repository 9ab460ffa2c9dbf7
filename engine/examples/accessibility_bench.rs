//! The accessibility speed benchmark: a synthetic closed impeller (the tests' generator)
//! at a chosen size, a 20° cone, timed. With `--write DIR` it also writes the part's STL
//! and a `millsim accessibility` INPUT.json there, for measuring the CLI's peak memory, and
//! analyzes the part as read back from that STL.
//!
//! ```text
//! cargo run --release -p millsim-engine --example accessibility_bench -- [small|test|200k|800k] [--write DIR] [--tool D] [--svg FILE]
//! ```
//! `--tool D` gives a tool list of one Ø D flat end mill (its spiral is drawn); `--svg FILE`
//! writes the target section's free region.

#[path = "../tests/parts/mod.rs"]
mod parts;

use millsim_engine::accessibility::{analyze, AccessRequest};
use millsim_engine::job::CancelFlag;
use parts::{stl_bytes, Impeller};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let size = args
        .iter()
        .find(|a| !a.starts_with("--"))
        .map(String::as_str)
        .unwrap_or("200k");
    let write = args
        .iter()
        .position(|a| a == "--write")
        .and_then(|i| args.get(i + 1))
        .filter(|d| !d.starts_with("--"));
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let base = Impeller::test_part();
    let imp = match size {
        // 25,312 triangles: the acceptance test's part.
        "test" => base,
        "small" => Impeller {
            along: 12,
            across: 4,
            per_pitch: 8,
            blade_cells: 2,
            ..base
        },
        // 200,704 triangles.
        "200k" => Impeller {
            along: 84,
            across: 12,
            per_pitch: 40,
            blade_cells: 10,
            ..base
        },
        // About 800k triangles.
        "800k" => Impeller {
            along: 168,
            across: 24,
            per_pitch: 80,
            blade_cells: 20,
            ..base
        },
        other => panic!("size {other}: small, test, 200k or 800k"),
    };
    let clock = std::time::Instant::now();
    let mut mesh = imp.mesh();
    let built = clock.elapsed().as_secs_f64();
    let entry = imp.passage_point(0.0);
    let target = imp.passage_point(0.5);
    if let Some(dir) = write {
        let dir = std::path::Path::new(dir);
        std::fs::create_dir_all(dir).unwrap();
        let stl = format!("impeller_{size}.stl");
        std::fs::write(dir.join(&stl), stl_bytes(&mesh)).unwrap();
        let input = format!(
            "{{\"part\": \"{stl}\", \"entry\": {entry:?}, \"target\": {target:?}, \"max_tilt_deg\": 20.0}}\n"
        );
        std::fs::write(dir.join(format!("impeller_{size}.json")), input).unwrap();
        println!("wrote {}", dir.join(&stl).display());
        // From here on as the CLI runs: the part read back from its file.
        drop(mesh);
        let bytes = std::fs::read(dir.join(&stl)).unwrap();
        mesh = millsim_engine::geometry::Mesh::from_stl_bytes(&bytes).unwrap();
    }
    let mut request = AccessRequest::new(entry, target);
    request.max_tilt_deg = 20.0;
    if let Some(d) = value("--tool") {
        let mut tool = millsim_engine::tool::Tool::flat(d.parse().expect("--tool D (mm)"), 3);
        tool.flute_length = 40.0;
        request.tools = vec![tool];
        request.allowance = 0.6;
    }
    let clock = std::time::Instant::now();
    let report = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
    let took = clock.elapsed().as_secs_f64();
    let r = report.target();
    println!(
        "{} triangles (built in {built:.2} s): Ø{:.4}, tilt {:.3}°, area {:.2} mm², axis [{:.6}, {:.6}, {:.6}]; {} axes evaluated in {took:.3} s on {} threads",
        mesh.triangles.len(),
        r.tool_diameter_mm,
        r.tilt_deg,
        r.free_area_mm2,
        r.axis[0],
        r.axis[1],
        r.axis[2],
        report.evaluations,
        rayon::current_num_threads()
    );
    if let Some(path) = value("--svg") {
        std::fs::write(&path, report.regions.last().unwrap().to_svg(640.0)).unwrap();
        println!("wrote {path}");
    }
}
