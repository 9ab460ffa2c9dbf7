//! `millsim interpret`'s rows: one JSON object per move, the bytes `serde_json` writes for a
//! [`Move`] (same fields, order, skipped fields and number formatters), written directly:
//! on a large program the generic serializer (its map of escaped keys) took a third of the
//! command's time.

use millsim_engine::nc::{FeedMode, Move, MoveKind};

/// Appends `m` as one JSON line.
pub fn write_row(out: &mut Vec<u8>, m: &Move) {
    out.extend_from_slice(b"{\"block\":");
    int(out, m.block as u64);
    out.extend_from_slice(b",\"line\":");
    int(out, u64::from(m.line));
    out.extend_from_slice(match m.kind {
        MoveKind::Rapid => b",\"kind\":\"rapid\",\"end\":",
        MoveKind::Linear => b",\"kind\":\"linear\",\"end\":",
        MoveKind::Arc => b",\"kind\":\"arc\",\"end\":",
        MoveKind::Dwell => b",\"kind\":\"dwell\",\"end\":",
        MoveKind::ToolChange => b",\"kind\":\"tool_change\",\"end\":",
    });
    floats(out, &m.end);
    out.extend_from_slice(b",\"feed\":");
    float(out, m.feed);
    out.extend_from_slice(match m.feed_mode {
        FeedMode::PerMin => b",\"feed_mode\":\"per_min\",\"spindle\":",
        FeedMode::InverseTime => b",\"feed_mode\":\"inverse_time\",\"spindle\":",
        FeedMode::PerRev => b",\"feed_mode\":\"per_rev\",\"spindle\":",
    });
    float(out, m.spindle);
    out.extend_from_slice(b",\"tool\":");
    int(out, u64::from(m.tool));
    if let Some(c) = &m.center {
        out.extend_from_slice(b",\"center\":");
        floats(out, c);
    }
    if let Some(n) = &m.normal {
        out.extend_from_slice(b",\"normal\":");
        floats(out, n);
    }
    if let Some(cw) = m.clockwise {
        out.extend_from_slice(if cw {
            b",\"clockwise\":true"
        } else {
            b",\"clockwise\":false"
        });
    }
    if let Some(v) = m.tool_length {
        out.extend_from_slice(b",\"tool_length\":");
        float(out, v);
    }
    if let Some(v) = m.seconds {
        out.extend_from_slice(b",\"seconds\":");
        float(out, v);
    }
    if let Some(a) = &m.tool_axis {
        out.extend_from_slice(b",\"tool_axis\":");
        floats(out, a);
    }
    if m.tool_tip {
        out.extend_from_slice(b",\"tool_tip\":true");
    }
    if let Some(s) = &m.source {
        out.extend_from_slice(b",\"source_file\":");
        int(out, u64::from(s.file));
        out.extend_from_slice(b",\"source_line\":");
        int(out, u64::from(s.line));
    }
    out.extend_from_slice(b"}\n");
}

fn int(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(itoa::Buffer::new().format(v).as_bytes());
}

/// As serde_json: the shortest round-trip form (zmij), `null` when not finite.
fn float(out: &mut Vec<u8>, v: f64) {
    if v.is_finite() {
        out.extend_from_slice(zmij::Buffer::new().format_finite(v).as_bytes());
    } else {
        out.extend_from_slice(b"null");
    }
}

fn floats(out: &mut Vec<u8>, vs: &[f64]) {
    out.push(b'[');
    for (i, &v) in vs.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        float(out, v);
    }
    out.push(b']');
}

#[cfg(test)]
mod tests {
    use super::*;
    use millsim_engine::nc::{interpret, InterpretOptions, MoveSource};

    fn assert_as_serde(m: &Move) {
        let mut row = Vec::new();
        write_row(&mut row, m);
        let mut expected = serde_json::to_vec(m).unwrap();
        expected.push(b'\n');
        assert_eq!(
            String::from_utf8(row).unwrap(),
            String::from_utf8(expected).unwrap()
        );
    }

    #[test]
    fn rows_are_the_bytes_serde_writes() {
        // Every kind, feed mode and optional field, odd numbers included.
        let src = "G21 G90 T2 M6\nG0 X1 Y-0 Z1\nG1 X0.1 Y0.2 F123.456 S1000 M3\n\
                   G2 X2 Y0 I0.95 J-0.1\nG93 G1 X3 A10 F2\nG94\nG95 G1 X4 F0.1\nG4 P0.5\n";
        let i = interpret(src, &InterpretOptions::default()).unwrap();
        assert!(i.moves.len() >= 7);
        for m in &i.moves {
            assert_as_serde(m);
        }
        let mut m = i.moves[2].clone();
        m.tool_axis = Some([0.0, -0.0, 1.0]);
        m.tool_tip = true;
        m.seconds = Some(1.5e-7);
        m.feed = f64::NAN;
        m.end[0] = f64::INFINITY;
        m.end[1] = 1e300;
        m.source = Some(MoveSource { file: 3, line: 77 });
        m.block = usize::MAX;
        assert_as_serde(&m);
        m.clockwise = Some(false);
        m.tool_length = Some(-12.5);
        assert_as_serde(&m);
        // A real program's rows, where the corpus is.
        let corpus = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shared/corpus/gcode/linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc"
        );
        match std::fs::read_to_string(corpus) {
            Ok(text) => {
                for m in interpret(&text, &InterpretOptions::default())
                    .unwrap()
                    .moves
                {
                    assert_as_serde(&m);
                }
            }
            Err(e) => eprintln!(
                "SKIPPED: the corpus part of rows_are_the_bytes_serde_writes needs {corpus} ({e})"
            ),
        }
    }
}
