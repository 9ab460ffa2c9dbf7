//! Property tests: no panic and no hang on any input; lossless round trip; sane moves.

use millsim_engine::cl::read_cls;
use millsim_engine::nc::{interpret, Dialect, InterpretOptions, Program};
use proptest::prelude::*;

fn small_limits() -> InterpretOptions {
    InterpretOptions {
        max_moves: 2_000,
        max_blocks: 20_000,
        ..InterpretOptions::default()
    }
}

/// Characters that G-code is made of, plus some that it is not.
fn gcode_char() -> impl Strategy<Value = char> {
    prop_oneof![
        8 => prop::sample::select(vec![
            'G', 'M', 'X', 'Y', 'Z', 'A', 'B', 'C', 'I', 'J', 'K', 'R', 'P', 'Q', 'L', 'F', 'S', 'T',
            'H', 'D', 'N', 'O', 'o', 'g', 'x', '@', '^', '0', '1', '2', '3', '4', '5', '8', '9', '.', '-', '+',
            ' ', '\n', '[', ']', '#', '<', '>', '=', '(', ')', ';', '/', '*', ',', '%', '_',
        ]),
        1 => any::<char>(),
    ]
}

fn gcode_text() -> impl Strategy<Value = String> {
    prop::collection::vec(gcode_char(), 0..300).prop_map(|v| v.into_iter().collect())
}

/// Blocks that are mostly valid, so the interpreter (not just the parser) gets exercised.
fn block() -> impl Strategy<Value = String> {
    let num = || (-50i32..50, 0u32..4).prop_map(|(i, d)| format!("{}.{}", i, d));
    prop_oneof![
        (
            prop::sample::select(vec!["G0", "G1", "G2", "G3"]),
            num(),
            num(),
            num()
        )
            .prop_map(|(g, x, y, z)| format!("{g} X{x} Y{y} Z{z} F100")),
        (
            prop::sample::select(vec!["G2", "G3"]),
            num(),
            num(),
            num(),
            num()
        )
            .prop_map(|(g, x, y, i, j)| format!("{g} X{x} Y{y} I{i} J{j} F50")),
        (prop::sample::select(vec!["G2", "G3"]), num(), num(), num())
            .prop_map(|(g, x, y, r)| format!("{g} X{x} Y{y} R{r} F50")),
        (
            prop::sample::select(vec!["G81", "G82", "G83", "G73", "G85", "G86", "G89"]),
            num(),
            num(),
            num(),
            1u32..4
        )
            .prop_map(|(g, x, y, z, l)| format!(
                "M3 S1000\n{g} X{x} Y{y} Z-{z} R5 P0.1 Q0.5 L{l} F100"
            )),
        prop::sample::select(vec![
            "G17",
            "G18",
            "G19",
            "G20",
            "G21",
            "G90",
            "G91",
            "G90.1",
            "G91.1",
            "G93",
            "G94",
            "G95",
            "G98",
            "G99",
            "G80",
            "G54",
            "G55",
            "G59.3",
            "G92 X1 Y2",
            "G92.1",
            "G92.2",
            "G92.3",
            "G10 L2 P3 X5 Y-5",
            "G10 L20 P1 Z3",
            "G28",
            "G28 Z1",
            "G30 X0",
            "G53 G0 Z0",
            "G43 H1",
            "G49",
            "T2 M6",
            "M3 S500",
            "M5",
            "G4 P0.5",
            "#1 = [#1 + 1]",
            "#<_a> = [SIN[#1] * 3]",
            "o1 if [#1 GT 2]\nG0 X#1\no1 else\nG1 Y#1 F10\no1 endif",
            "o2 repeat [3]\nG91 G1 X1 F10\no2 endrepeat\nG90",
            "o3 while [#3 LT 4]\n#3 = [#3 + 1]\no3 endwhile",
            "o4 while [1]\no4 endwhile",
            "o<s> sub\nG0 X#1\no<s> endsub\no<s> call [7]",
            "O100",
            "G0 X1 ,R2",
            "G1 X1 ,C1 F10\nY5",
            "#1=#2*3+1",
            "#2=#1 MOD 3-#0",
            "IF [#1 GT 2] GOTO 10",
            "N10 G0 X#1",
            "IF [#1 LT 5] THEN #1=#1+1",
            "WHILE [#1 LT 3] DO1\n#1=#1+1\nEND1",
            "DO2\nIF [#1 GT 4] GOTO 10\n#1=#1+1\nEND2",
            "GOTO 10",
            "M98 P100 L2",
            "M98 P20100",
            "M99",
            "M99 P10",
            "G65 P100 A1 X2 Y#1",
            "O100",
            "O200\nG91 G1 X1 F50\nG90\nM99",
            "DPRNT[X#1[53]]",
            "POPEN",
            "#3000=1 (ALARM)",
            "G41.1 D2",
            "G42.1 D3",
            "G40",
            "G41.1 D1 G1 X10 Y0 F100\nG3 X0 Y10 R10\nG1 X-5\nG40 G1 X0 Y0",
            "G10 L1 P1 Z5 R1.5\nG41 D1",
            "G38.2 Z-20 F50",
            "M123",
            ":77",
            "G10 L2 P1 X3 Y-2 R30",
            "G10 L2 P2 R-45",
            "G52 X2 Y-1",
            "G0 @5 ^30",
            "G1 ^120 F20",
            "G91 G1 @1 ^-15 F20",
            "G81 @8 ^45 Z-1 R2 F30",
            "G68 X1 Y2 R30",
            "G69",
            "G51 X0 Y0 P1500",
            "G51 X0 Y0 I2000 J-1000",
            "G50",
            "G51.1 X3",
            "G50.1 X0",
            "G16",
            "G15",
            "G5 X3 Y4 I1 J0 P0 Q-1 F40",
            "G5 X6 Y1 P1 Q1",
            "G5.1 X-2 Y3 I1 J2 F40",
            "G5.2 X1 Y1 P1 L4\nX2 Y3 P2\nX4 Y1 P0.5\nX5 Y5 P1\nG5.3",
            "G5.3",
            "G66 P100 R2 Z-1",
            "G67",
            "G18 G41.1 D2 G1 X5 Z-1 F50\nG1 Z-5\nG2 X9 Z-9 R4\nG40 G1 X12\nG17",
            "G65 P100 I1 J2 K3 I4 K5",
            "G53 G0 Z0 H0",
            "G43 H1 D2\nG0 Z1 H0",
            "WH[#1LT3]DO1\n#1=#1+1\nEN1",
            "IF[#1GT2]GO10",
            "IF[#1LT5]TH#1=#1+1",
            "T2 D2 M6",
            "G81 X1 Y1 Z-1 R1 F20 A30",
            "G91 A15",
            "G80\nZ3",
            // Issue 14, interp5: cycle data kept across codes, extended offsets, nested G66,
            // G16 in G91 cycles, Fanuc start-up, lines with errors in branches not taken.
            "G82 X2 Y2 Z-1 F20",
            "G83 X3 Z-2 Q0.5",
            "G54.1 P3",
            "G154 P12",
            "G10 L20 P3 X5 Y-5",
            "G91 G10 L20 P12 Z1",
            "G66 P200\nG66 P100",
            "G91 G81 Y30 R-1 Z-2 K3 F20",
            "G91 G41 D1 X-5 F50\nG3 X0 Y0 I5 J0 Z-1\nG90 G40 G1 X0 Y0",
            "GOTO 10\nGG1 X$\nN10",
            "o7 if [0]\nG1 X[1+\no7 endif",
            "M52 P1",
        ])
        .prop_map(|s| s.to_string()),
    ]
}

/// Fragments of Fanuc macro B lines, joined at random: mostly broken syntax, some valid.
fn macro_text() -> impl Strategy<Value = String> {
    prop::collection::vec(
        prop::sample::select(vec![
            "IF", "WHILE", "GOTO", "END", "DO", "THEN", "DPRNT", "POPEN", "[", "]", "#", "#1",
            "WH", "GO", "EN", "TH", "#0", "#100", "#3000", "#5001", "=", "+", "-", "*", "/", "MOD",
            "AND", "OR", "XOR", "EQ", "NE", "GT", "LT", "1", "2", "10", "2.5", " ", "\n", "\nN10 ",
            "N10", "M98", "M99", "P", "P10", "L", "L3", "G65", "O10\n", "O1\n", "G0 X", "G1 Y",
            "F100", "(C)",
        ]),
        0..60,
    )
    .prop_map(|v| v.concat())
}

fn program() -> impl Strategy<Value = String> {
    prop::collection::vec(block(), 0..25).prop_map(|v| v.join("\n") + "\n")
}

proptest! {
    // A case that takes over 10 s counts as a hang.
    #![proptest_config(ProptestConfig { cases: 2000, timeout: 10_000, ..ProptestConfig::default() })]

    #[test]
    fn parser_never_panics_and_round_trips(src in gcode_text()) {
        if let Ok(p) = Program::parse(&src) {
            prop_assert_eq!(p.to_string(), src.clone());
            let mut pos = 0;
            for b in p.blocks() {
                prop_assert_eq!(b.span.start, pos);
                pos = b.end;
            }
            prop_assert_eq!(pos, src.len());
        }
        let _ = interpret(&src, &small_limits());
        let _ = read_cls(&src);
    }

    #[test]
    fn macro_syntax_never_panics_round_trips_and_is_deterministic(src in macro_text(), fanuc in any::<bool>()) {
        if let Ok(p) = Program::parse(&src) {
            prop_assert_eq!(p.to_string(), src.clone());
        }
        let opts = InterpretOptions {
            dialect: if fanuc { Dialect::Fanuc } else { Dialect::Auto },
            ..small_limits()
        };
        let a = interpret(&src, &opts);
        let b = interpret(&src, &opts);
        prop_assert_eq!(format!("{:?}", a), format!("{:?}", b));
        if let Ok(i) = a {
            prop_assert!(i.moves.iter().all(|m| m.end.iter().all(|v| v.is_finite())));
        }
    }

    #[test]
    fn any_options_never_panic(
        src in program(),
        fanuc in any::<bool>(),
        implied in any::<bool>(),
        ccr in any::<bool>(),
        block_delete in any::<bool>(),
        pass in prop::collection::vec(prop_oneof![Just(0u32), Just(6), Just(428), Just(999), Just(70_000), any::<u32>()], 0..4),
    ) {
        let opts = InterpretOptions {
            dialect: if fanuc { Dialect::Fanuc } else { Dialect::LinuxCnc },
            fanuc_implied_decimal: implied,
            fanuc_corners_without_comma: ccr,
            block_delete,
            passthrough_m_codes: pass.clone(),
            ..small_limits()
        };
        let with_m: String = pass.iter().map(|m| format!("M{m}\n")).collect::<String>() + &src;
        let _ = interpret(&with_m, &opts);
    }

    #[test]
    fn interpreter_never_panics_and_moves_are_finite(src in program()) {
        let a = interpret(&src, &small_limits());
        if let Ok(i) = &a {
            prop_assert!(i.moves.len() <= 2_000);
            for m in &i.moves {
                prop_assert!(m.end.iter().all(|v| v.is_finite()), "{:?}", m);
                prop_assert!(m.start.iter().all(|v| v.is_finite()));
                prop_assert!(m.feed.is_finite());
                if let Some(arc) = &m.arc {
                    prop_assert!(arc.sweep.is_finite() && arc.sweep != 0.0);
                }
            }
            // Each move starts where the previous ended; only a tool length change (G43/G49)
            // moves the controlled point without motion.
            if !src.contains("G43") && !src.contains("G49") {
                for w in i.moves.windows(2) {
                    for k in 0..6 {
                        prop_assert!((w[0].end[k] - w[1].start[k]).abs() < 1e-6, "{:?} then {:?}", w[0], w[1]);
                    }
                }
            }
        }
        // Deterministic: same input, same output.
        let b = interpret(&src, &small_limits());
        prop_assert_eq!(format!("{:?}", a), format!("{:?}", b));
    }
}
