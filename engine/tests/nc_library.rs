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
    assert_eq!(row["source"]["line"], 3);
    assert!(serde_json::to_value(&out.moves[0]).unwrap().get("source").is_none());
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

    let (line, msg) = error("O0001\nG0 X0\nG0 Y0\nM98 P3000\nM30\n");
    assert_eq!(line, 4);
    assert!(
        msg.contains("program O3000: library file \"broken.nc\" does not read: 2:"),
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
}

#[test]
fn a_program_in_the_file_wins_over_the_library() {
    let main = "O0001\nG0 X0 Y0 Z1\nM98 P1000\nM30\nO1000\nG0 X42\nM99\n";
    let out = interpret(main, &opts()).unwrap();
    assert_eq!(xyz(&out), [[0.0, 0.0, 1.0], [42.0, 0.0, 1.0]]);
    assert!(out.moves.iter().all(|m| m.source.is_none()));
}
