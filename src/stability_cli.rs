//! `millsim stability INPUT.json`: stability lobes offline. Reads the same JSON object the
//! `stability` job takes (its options, parsed by the job's own parser: the lobe input, with
//! `recommend` {near_rpm, depth_mm, window_rpm} or `allowance` and `allowances_mm` for 3-D
//! lobes) and returns the CSV for stdout: `rpm,depth_mm` (critical axial depth per spindle
//! speed) or `allowance_mm,rpm,depth_mm`, and the recommendation's line for stderr.

use std::path::Path;

use millsim_engine::physics::stability::{
    compute_lobes, compute_lobes_3d, recommend_spindle_speed,
};

use crate::jobs::stability::{options, StabilityRequest};

/// What the command prints: the CSV, and a note (the recommended speed) when asked.
#[derive(Debug)]
pub struct StabilityOutput {
    pub csv: String,
    pub note: Option<String>,
}

/// Reads INPUT.json, computes the lobes with the chosen method and returns the CSV text.
/// Errors name the file and, for bad input, the offending field.
pub fn run(path: &Path) -> Result<StabilityOutput, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    // The job's fields are `options.X`; here the file is the options object.
    let request = options(&value).map_err(|e| {
        let field = e.field.strip_prefix("options.").unwrap_or(&e.field);
        format!("{}: field `{field}`: {}", path.display(), e.message)
    })?;
    let refused = |e: millsim_engine::physics::PhysicsError| format!("{}: {e}", path.display());
    Ok(match request {
        StabilityRequest::Lobes(input, recommend) => {
            let curve = compute_lobes(&input).map_err(refused)?;
            let note = recommend.map(|r| {
                match recommend_spindle_speed(&curve.points, r.near_rpm, r.depth_mm, r.window_rpm) {
                    Some(rec) => format!(
                        "recommended: {}",
                        serde_json::to_string(&rec).unwrap_or_default()
                    ),
                    None => format!(
                        "recommended: none: no speed within {} rpm of {} rpm is stable at {} mm",
                        r.window_rpm, r.near_rpm, r.depth_mm
                    ),
                }
            });
            StabilityOutput {
                csv: curve.to_csv(),
                note,
            }
        }
        StabilityRequest::Surface(input) => StabilityOutput {
            csv: compute_lobes_3d(&input).map_err(refused)?.to_csv(),
            note: None,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::run;

    const INPUT: &str = r#"{"method":"zoa","teeth":2,"ktc_n_mm2":600,"krc_n_mm2":200,
        "radial_immersion":1.0,"milling":"down",
        "modes_x":[{"freq_hz":922,"damping":0.011,"stiffness_n_m":1.34005e6}],"modes_y":[],
        "rpm":{"from":5000,"to":25000,"step":250},"steps_per_period":40}"#;

    #[test]
    fn prints_one_line_per_speed_and_names_bad_fields() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("input.json");
        std::fs::write(&path, INPUT).unwrap();
        let csv = run(&path).unwrap().csv;
        let mut lines = csv.lines();
        assert_eq!(lines.next(), Some("rpm,depth_mm"));
        let rows: Vec<(f64, f64)> = lines
            .map(|l| {
                let (r, a) = l.split_once(',').unwrap();
                (r.parse().unwrap(), a.parse().unwrap())
            })
            .collect();
        assert_eq!(rows.len(), 81);
        assert_eq!(rows[0].0, 5000.0);
        assert_eq!(rows[80].0, 25000.0);
        // Zero-order slot limit of the benchmark: 0.298 mm (docs/reference.md).
        let min = rows.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
        assert!((min - 0.298).abs() / 0.298 < 0.01, "{min}");

        // Semi-discretization, k = 40, around the slot minimum (reference: 0.323 mm at 15,750).
        let sdm = INPUT
            .replace("\"zoa\"", "\"sdm\"")
            .replace("\"from\":5000,\"to\":25000", "\"from\":15500,\"to\":16000");
        std::fs::write(&path, sdm).unwrap();
        let csv = run(&path).unwrap().csv;
        assert_eq!(csv.lines().count(), 4);
        let at_15750: f64 = csv
            .lines()
            .find_map(|l| l.strip_prefix("15750,"))
            .unwrap()
            .parse()
            .unwrap();
        assert!((at_15750 - 0.323).abs() / 0.323 < 0.03, "{at_15750}");

        std::fs::write(&path, INPUT.replace("\"teeth\":2", "\"teeth\":\"two\"")).unwrap();
        let err = run(&path).unwrap_err();
        assert!(err.contains("teeth"), "{err}");
        std::fs::write(&path, INPUT.replace("\"damping\":0.011", "\"damping\":-1")).unwrap();
        let err = run(&path).unwrap_err();
        assert!(err.contains("modes_x[0].damping"), "{err}");
        assert!(run(&dir.path().join("missing.json")).is_err());

        // The job's `recommend` too: the centre of the widest stable pocket near 15,000 rpm at
        // 0.5 mm (above the 0.298 mm floor: a pocket's speed, not any speed).
        let with = INPUT.replace(
            "\"steps_per_period\":40",
            "\"steps_per_period\":40,\"recommend\":{\"near_rpm\":15000,\"depth_mm\":0.5}",
        );
        std::fs::write(&path, with).unwrap();
        let out = run(&path).unwrap();
        let note = out.note.expect("a recommendation");
        assert!(note.starts_with("recommended: {"), "{note}");
        let rec: serde_json::Value =
            serde_json::from_str(note.strip_prefix("recommended: ").unwrap()).unwrap();
        let rpm = rec["rpm"].as_f64().unwrap();
        let depth_at = |csv: &str, at: f64| -> f64 {
            csv.lines()
                .skip(1)
                .map(|l| l.split_once(',').unwrap())
                .map(|(r, d)| (r.parse::<f64>().unwrap(), d.parse::<f64>().unwrap()))
                .min_by(|a, b| (a.0 - at).abs().total_cmp(&(b.0 - at).abs()))
                .unwrap()
                .1
        };
        assert!(depth_at(&out.csv, rpm) >= 0.5, "{note}");
        let bad = INPUT.replace(
            "\"steps_per_period\":40",
            "\"steps_per_period\":40,\"recommend\":{\"near_rpm\":-1,\"depth_mm\":0.5}",
        );
        std::fs::write(&path, bad).unwrap();
        let err = run(&path).unwrap_err();
        assert!(err.contains("recommend.near_rpm"), "{err}");
    }
}
