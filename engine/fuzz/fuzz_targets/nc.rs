//! Any input: the parser round-trips what it accepts, and nothing panics or hangs.
#![no_main]

use libfuzzer_sys::fuzz_target;
use millsim_engine::cl::read_cls;
use millsim_engine::nc::{interpret, Dialect, InterpretOptions, Program};

fuzz_target!(|data: &[u8]| {
    let Ok(src) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(p) = Program::parse(src) {
        assert_eq!(p.to_string(), src);
    }
    for (dialect, implied) in [(Dialect::Auto, false), (Dialect::Fanuc, true)] {
        let opts = InterpretOptions {
            dialect,
            fanuc_implied_decimal: implied,
            fanuc_corners_without_comma: implied,
            passthrough_m_codes: vec![428, 429, 100_000],
            max_moves: 10_000,
            max_blocks: 100_000,
            ..InterpretOptions::default()
        };
        if let Ok(i) = interpret(src, &opts) {
            for m in &i.moves {
                assert!(m.end.iter().all(|v| v.is_finite()));
            }
        }
    }
    let _ = read_cls(src);
});
