//! Calls to programs in other files (a program library): Fanuc `M98`/`G65` to programs kept
//! as files of their own or several to a file, nested calls between files, a call whose
//! number is computed, and the errors of library files placed at the call. End points are
//! hand-computed; the LinuxCNC side (`o<name> call` to `name.ngc`) is compared with LinuxCNC
//! in `nc_linuxcnc.rs`.

mod common;

use common::nc::xyz;
use millsim_engine::nc::{interpret, InterpretOptions, LibraryFile, ProgramLibrary};
use std::sync::Arc;

fn library() -> Arc<ProgramLibrary> {
    let files = [
        (
            "O1000.nc",
            "%\nO1000 (SQUARE, INCREMENTAL)\nG91 G1 X10 F500\nY10\nX-10\nY-10\nG90\nM99\n%\n",
        ),
        (
            "macros.nc",
            "O9010 (ROW OF #2 HOLES, PITCH #1)\n#3=0\nWHILE [#3 LT #2] DO1\nG0 X[#1*#3] Y0\nG1 Z-1 F100\nG0 Z1\n#3=#3+1\nEND1\nM99\nO9011\nG0 X#24 Y#25\nM99\n",
        ),
        ("O2000", "O2000\nG0 X100 Y100\nM98 P1000\nM99\n"),
        ("O6000.nc", "O6000\nG0 X-5 Y-5\nM123\nM99\n"),
        ("broken.nc", "O3000\nG1 X[1+\nM99\n"),
        ("broken2.nc", "O3100\nWHILE[#1 GT]DO1\nEND1\nM99\n"),
        ("O4000.nc", "G0 X5\nG1 X6 F100\n"),
        ("O5000.nc", "O5000\nG1 X1 Y1 Z1 F100\nG2 X0 Y0 R0.1\nM99\n"),
    ];
    Arc::new(ProgramLibrary::new(
        files
            .iter()
            .map(|(n, t)| LibraryFile {
                name: n.to_string(),
                text: t.to_string(),
            })
            .collect(),
    ))
}

fn opts() -> InterpretOptions {
    InterpretOptions {
        library: Some(library()),
        ..Default::default()
    }
}

#[test]
fn fanuc_calls_run_programs_of_the_library() {
    let main = "O0001\nG21 G90 G17 G54\nG0 X0 Y0 Z1\nM98 P1000 L2\nG65 P9010 A5 B3\nG65 P9011 X7 Y8\nM98 P2000\n#2=6000\nM98 P#2\nM30\n";
    let out = interpret(main, &opts()).unwrap_or_else(|e| panic!("{e}"));
    let square = |x: f64, y: f64| {
        vec![
            [x + 10.0, y, 1.0],
            [x + 10.0, y + 10.0, 1.0],
            [x, y + 10.0, 1.0],
            [x, y, 1.0],
        ]
    };
    let mut want = vec![[0.0, 0.0, 1.0]];
    want.extend(square(0.0, 0.0));
    want.extend(square(0.0, 0.0));
    for x in [0.0, 5.0, 10.0] {
        want.extend([[x, 0.0, 1.0], [x, 0.0, -1.0], [x, 0.0, 1.0]]);
    }
    want.push([7.0, 8.0, 1.0]);
    want.push([100.0, 100.0, 1.0]);
    want.extend(square(100.0, 100.0));
    want.push([-5.0, -5.0, 1.0]);
    assert_eq!(xyz(&out), want);

    // Each move is on the program's call line, with its own file and line.
    let files = &out.library_files;
    let at: Vec<(u32, Option<(&str, u32)>)> = out
        .moves
        .iter()
        .map(|m| {
            (
                m.line,
                m.source.map(|s| (files[s.file as usize].as_str(), s.line)),
            )
        })
        .collect();
    assert_eq!(at[0], (3, None));
    assert_eq!(at[1], (4, Some(("O1000.nc", 3))));
    assert_eq!(at[8], (4, Some(("O1000.nc", 6))));
    assert_eq!(at[9], (5, Some(("macros.nc", 4))));
    assert_eq!(at[10], (5, Some(("macros.nc", 5))));
    assert_eq!(at[18], (6, Some(("macros.nc", 11))));
    // Nested: O2000 calls O1000; both are attributed to the outermost call.
    assert_eq!(at[19], (7, Some(("O2000", 2))));
    assert_eq!(at[20], (7, Some(("O1000.nc", 3))));
    // P#2: found at run time (the run is made again with the file loaded).
    assert_eq!(at[24], (9, Some(("O6000.nc", 2))));
    assert!(out.moves.iter().all(|m| m.block == m.line as usize - 1));
    // The library file's warning is placed at the call, naming its file and line.
    let w = out
        .warnings
        .iter()
        .find(|w| w.message.contains("M123"))
        .expect("a warning for M123");
    assert_eq!(w.line, 9);
    assert!(
        w.message.contains("library file \"O6000.nc\", line 3"),
        "{}",
        w.message
    );
    // Every serialized row of a library move says where it comes from.
    let row = serde_json::to_value(&out.moves[1]).unwrap();
    let file = row["source_file"].as_u64().unwrap() as usize;
    assert_eq!(
        (files[file].as_str(), &row["source_line"]),
        ("O1000.nc", &3.into())
    );
    let plain = serde_json::to_value(&out.moves[0]).unwrap();
    assert!(plain.get("source_file").is_none() && plain.get("source_line").is_none());
}

#[test]
fn the_older_m98_form_repeats_a_library_program() {
    // P21000 without L: O1000 twice (there is no program O21000).
    let main = "O0001\nG0 X0 Y0 Z1\nM98 P21000\nM30\n";
    let out = interpret(main, &opts()).unwrap();
    assert_eq!(xyz(&out).len(), 9);
    assert_eq!(xyz(&out)[8], [0.0, 0.0, 1.0]);
}

fn error(main: &str) -> (u32, String) {
    let e = interpret(main, &opts()).expect_err("should fail");
    (e.0[0].line, e.0[0].message.clone())
}

#[test]
fn errors_in_library_files_are_placed_at_the_call_and_name_the_file() {
    let (line, msg) = error("O0001\nG0 X0 Y0 Z0\nM98 P5000\nM30\n");
    assert_eq!(line, 3);
    assert!(
        msg.starts_with("in library file \"O5000.nc\", line 3, column "),
        "{msg}"
    );
    assert!(msg.contains("radius"), "{msg}");

    // A syntax error on a plain line fails when the line runs, placed at the call.
    let (line, msg) = error("O0001\nG0 X0\nG0 Y0\nM98 P3000\nM30\n");
    assert_eq!(line, 4);
    assert!(
        msg.starts_with("in library file \"broken.nc\", line 2, column 8: expected a value"),
        "{msg}"
    );
    // One on a macro statement line: the file does not read at all.
    let (line, msg) = error("O0001\nG0 X0\nM98 P3100\nM30\n");
    assert_eq!(line, 3);
    assert!(
        msg.contains("program O3100: library file \"broken2.nc\" does not read: 2:"),
        "{msg}"
    );

    let (line, msg) = error("O0001\nM98 P4000\nM30\n");
    assert_eq!(line, 2);
    assert!(msg.contains("\"O4000.nc\""), "{msg}");
    assert!(msg.contains("ends without M99"), "{msg}");

    let (line, msg) = error("O0001\nG0 X0\nM98 P7777\nM30\n");
    assert_eq!(line, 3);
    assert!(
        msg.contains("program O7777 is not in this file nor in its program library"),
        "{msg}"
    );
}

#[test]
fn without_a_library_a_call_to_another_file_is_an_error_naming_the_program() {
    let e = interpret("O0001\nM98 P1000\nM30\n", &InterpretOptions::default()).unwrap_err();
    assert_eq!(e.0[0].line, 2);
    assert!(e.0[0].message.contains("program O1000 is not in this file"));
    assert!(
        !e.0[0].message.contains("control keeps"),
        "{}",
        e.0[0].message
    );
    // A call to a macro the control keeps resident (a Renishaw probing cycle) says so.
    let e = interpret(
        "O0001\nG65 P9810 Z5. F1000.\nM30\n",
        &InterpretOptions::default(),
    )
    .unwrap_err();
    let msg = &e.0[0].message;
    assert_eq!(e.0[0].line, 2);
    assert!(msg.contains("program O9810 is not in this file"), "{msg}");
    assert!(msg.contains("control keeps in its own memory"), "{msg}");
    assert!(msg.contains("Renishaw"), "{msg}");
}

#[test]
fn a_program_in_the_file_wins_over_the_library() {
    let main = "O0001\nG0 X0 Y0 Z1\nM98 P1000\nM30\nO1000\nG0 X42\nM99\n";
    let out = interpret(main, &opts()).unwrap();
    assert_eq!(xyz(&out), [[0.0, 0.0, 1.0], [42.0, 0.0, 1.0]]);
    assert!(out.moves.iter().all(|m| m.source.is_none()));
}

mod property {
    use super::*;
    use proptest::prelude::*;

    /// One block of a subprogram body: a move, or a call to a program numbered below it.
    #[derive(Clone, Debug)]
    enum Line {
        Move {
            rapid: bool,
            incremental: bool,
            x: i32,
            y: i32,
        },
        Call {
            to: usize,
            times: u32,
            macro_call: bool,
        },
    }

    fn line() -> impl Strategy<Value = Line> {
        prop_oneof![
            3 => (any::<bool>(), any::<bool>(), -50i32..50, -50i32..50)
                .prop_map(|(rapid, incremental, x, y)| Line::Move { rapid, incremental, x, y }),
            1 => (0usize..4, 1u32..3, any::<bool>())
                .prop_map(|(to, times, macro_call)| Line::Call { to, times, macro_call }),
        ]
    }

    fn text(number: usize, body: &[Line]) -> String {
        let mut s = format!("O{}\n", 1000 + number);
        for l in body {
            match l {
                Line::Move {
                    rapid,
                    incremental,
                    x,
                    y,
                } => {
                    s += &format!(
                        "{} {} X{x} Y{y} F300\n",
                        if *incremental { "G91" } else { "G90" },
                        if *rapid { "G0" } else { "G1" }
                    )
                }
                // Only programs numbered below this one: calls cannot recurse.
                Line::Call {
                    to,
                    times,
                    macro_call,
                } if *to < number => {
                    s += &if *macro_call {
                        format!("G65 P{} L{times}\n", 1000 + to)
                    } else {
                        format!("M98 P{} L{times}\n", 1000 + to)
                    }
                }
                Line::Call { .. } => {}
            }
        }
        s + "M99\n"
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Programs in library files run exactly as the same programs in the file do.
        #[test]
        fn library_programs_run_as_programs_in_the_file(
            bodies in prop::collection::vec(prop::collection::vec(line(), 0..6), 1..5),
            main_calls in prop::collection::vec((0usize..5, 1u32..3), 1..4),
        ) {
            let n = bodies.len();
            let mut main = "O0001\nG21 G90 G0 X0 Y0 Z1\n".to_string();
            for (to, times) in &main_calls {
                main += &format!("M98 P{} L{times}\n", 1000 + to % n);
            }
            main += "M30\n";
            let subs: Vec<String> = bodies.iter().enumerate().map(|(i, b)| text(i, b)).collect();
            let one_file = format!("{main}{}", subs.concat());
            let together = interpret(&one_file, &InterpretOptions::default()).unwrap();
            let library = ProgramLibrary::new(
                subs.iter()
                    .enumerate()
                    .map(|(i, t)| LibraryFile { name: format!("O{}.nc", 1000 + i), text: t.clone() })
                    .collect(),
            );
            let opts = InterpretOptions { library: Some(Arc::new(library)), ..Default::default() };
            let apart = interpret(&main, &opts).unwrap();
            prop_assert_eq!(xyz(&together), xyz(&apart));
            let main_lines = main.lines().count() as u32;
            for (a, b) in together.moves.iter().zip(&apart.moves) {
                prop_assert_eq!(a.kind, b.kind);
                // In one file, a subprogram's move is on its own line (after the main
                // program); from the library, on the main program's call line.
                prop_assert_eq!(a.line > main_lines, b.source.is_some());
                prop_assert!(b.line <= main_lines);
            }
        }
    }
}

#[test]
fn the_optimizer_refuses_moves_of_library_programs_naming_the_call() {
    use millsim_engine::nc::Program;
    use millsim_engine::optimize::{rewrite_program, FeedSchedule, RewriteOptions};
    let main = "O0001\nG0 X0 Y0 Z1\nM98 P1000\nM30\n";
    let out = interpret(main, &opts()).unwrap();
    let schedule = FeedSchedule {
        moves: Vec::new(),
        blocks: Vec::new(),
        best_constant_feed: 0.0,
        evaluations: 0,
    };
    let e = rewrite_program(
        &Program::parse(main).unwrap(),
        &out.moves,
        &schedule,
        &RewriteOptions::default(),
    )
    .unwrap_err();
    assert_eq!(e.0[0].line, 3);
    assert!(
        e.0[0].message.contains("program library"),
        "{}",
        e.0[0].message
    );
}
