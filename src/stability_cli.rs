//! `millsim stability INPUT.json`: stability lobes offline. Reads the same JSON object the
//! `stability` job takes ([`millsim_engine::physics::stability::StabilityInput`]) and returns
//! the CSV `rpm,depth_mm` (critical axial depth per spindle speed) for stdout.

use std::path::Path;

use millsim_engine::physics::stability::{compute_lobes, StabilityInput};

/// Reads INPUT.json, computes the lobes with the chosen method and returns the CSV text.
/// Errors name the file and, for bad input, the offending field.
pub fn run(path: &Path) -> Result<String, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let de = &mut serde_json::Deserializer::from_str(&text);
    let input: StabilityInput = serde_path_to_error::deserialize(de)
        .map_err(|e| format!("{}: field `{}`: {}", path.display(), e.path(), e.inner()))?;
    let curve = compute_lobes(&input).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(curve.to_csv())
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
        let csv = run(&path).unwrap();
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
        // Zero-order slot limit of the benchmark: 0.298 mm (REFERENCE.md).
        let min = rows.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
        assert!((min - 0.298).abs() / 0.298 < 0.01, "{min}");

        std::fs::write(&path, INPUT.replace("\"teeth\":2", "\"teeth\":\"two\"")).unwrap();
        let err = run(&path).unwrap_err();
        assert!(err.contains("teeth"), "{err}");
        std::fs::write(&path, INPUT.replace("\"damping\":0.011", "\"damping\":-1")).unwrap();
        let err = run(&path).unwrap_err();
        assert!(err.contains("modes_x[0].damping"), "{err}");
        assert!(run(&dir.path().join("missing.json")).is_err());
    }
}
