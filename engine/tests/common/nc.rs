//! Helpers the interpreter's tests share: run a program, take its first error, read the
//! motions' end points.

use millsim_engine::nc::{interpret, Dialect, InterpretOptions, Interpretation, Move, MoveKind};

pub fn dialect(d: Dialect) -> InterpretOptions {
    InterpretOptions {
        dialect: d,
        ..InterpretOptions::default()
    }
}

pub fn run(src: &str) -> Interpretation {
    run_with(src, &InterpretOptions::default())
}

pub fn run_with(src: &str, opts: &InterpretOptions) -> Interpretation {
    interpret(src, opts).unwrap_or_else(|e| panic!("{e}"))
}

/// The first error: (line, col, message).
pub fn fail(src: &str, opts: &InterpretOptions) -> (u32, u32, String) {
    let e = interpret(src, opts).expect_err("should fail");
    let d = &e.0[0];
    (d.line, d.col, d.message.clone())
}

/// Whether a warning on `line` says `text`.
pub fn warned(i: &Interpretation, line: u32, text: &str) -> bool {
    i.warnings
        .iter()
        .any(|w| w.line == line && w.message.contains(text))
}

/// The motions (tool changes and dwells left out).
pub fn motions(i: &Interpretation) -> Vec<&Move> {
    i.moves
        .iter()
        .filter(|m| !matches!(m.kind, MoveKind::ToolChange | MoveKind::Dwell))
        .collect()
}

/// X Y Z of every motion, rounded to 1e-9 mm so that hand-computed values compare exactly.
pub fn xyz(i: &Interpretation) -> Vec<[f64; 3]> {
    motions(i)
        .iter()
        .map(|m| {
            let r = |v: f64| (v * 1e9).round() / 1e9 + 0.0;
            [r(m.end[0]), r(m.end[1]), r(m.end[2])]
        })
        .collect()
}

pub fn close(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
}
