//! Lexer/parser: spans, all errors at once, lossless round trip, F-word rewriting.

mod common;

use millsim_engine::nc::{Expr, OKeyword, ParamRef, Program};
use std::path::Path;

const CORPUS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/corpus/gcode");

fn corpus_files() -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(CORPUS)
        .expect("corpus directory")
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    assert_eq!(v.len(), 7, "expected the 7 corpus programs");
    v
}

#[test]
fn corpus_round_trip_is_byte_identical() {
    if common::corpus_dir().is_none() {
        return;
    }
    for path in corpus_files() {
        let src = std::fs::read_to_string(&path).unwrap();
        let prog = Program::parse(&src).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        // Writing back gives the same bytes.
        assert_eq!(
            prog.to_string().as_bytes(),
            src.as_bytes(),
            "{}",
            path.display()
        );
        // The blocks tile the source exactly: nothing is lost between spans.
        let mut rebuilt = String::new();
        let mut pos = 0;
        for (i, b) in prog.blocks().iter().enumerate() {
            assert_eq!(
                b.span.start, pos,
                "block {i} starts where the previous ended"
            );
            assert_eq!(b.line as usize, i + 1);
            rebuilt.push_str(&src[b.span.start..b.end]);
            pos = b.end;
            // Every word's span is inside its block and starts with its letter (or comma).
            for w in &b.words {
                assert!(w.span.start >= b.span.start && w.span.end <= b.span.end);
                let t = prog.text(w.span);
                let first = t.chars().next().unwrap();
                assert!(
                    first.to_ascii_uppercase() == w.letter || (w.comma && first == ','),
                    "{t}"
                );
                assert!(w.value_span.end == w.span.end);
            }
        }
        assert_eq!(rebuilt, src);
        assert_eq!(
            prog.blocks().len(),
            src.lines().count(),
            "{}",
            path.display()
        );
        // with_feeds with no change is the identity too.
        assert_eq!(prog.with_feeds(&[]).unwrap(), src);
    }
}

#[test]
fn words_numbers_comments_and_case() {
    let src = "N10 g01x1.5Y-2 z.5 F#<feed> (a comment) ; rest\r\n/G0 X[1+2*3] #1=[#2+1]\n%\n";
    let p = Program::parse(src).unwrap();
    let b = &p.blocks()[0];
    assert_eq!(b.line_number.as_ref().unwrap().letter, 'N');
    let letters: String = b.words.iter().map(|w| w.letter).collect();
    assert_eq!(letters, "GXYZF");
    assert_eq!(p.text(b.words[1].span), "x1.5");
    assert_eq!(p.text(b.words[2].value_span), "-2");
    assert!(matches!(b.words[3].value, Expr::Number { value, has_point: true } if value == 0.5));
    assert!(matches!(&b.words[4].value, Expr::Param(p) if **p == ParamRef::Named("feed".into())));
    assert_eq!(b.comments.len(), 2);
    assert_eq!(b.comments[0].text, "a comment");
    // \r\n: the content excludes the terminator, the block end includes it.
    assert_eq!(
        &src[b.span.start..b.span.end],
        "N10 g01x1.5Y-2 z.5 F#<feed> (a comment) ; rest"
    );
    assert_eq!(b.end, b.span.end + 2);
    let b = &p.blocks()[1];
    assert!(b.block_delete);
    assert_eq!(b.assignments.len(), 1);
    assert!(p.blocks()[2].percent);
}

#[test]
fn o_words() {
    let src = "o100 sub\no<my sub> call [1] [2+3] [#1]\no101 while [#1 LT 3]\nO123 (program number)\no100 endsub [42]\n";
    let p = Program::parse(src).unwrap();
    let kw: Vec<OKeyword> = p
        .blocks()
        .iter()
        .map(|b| b.o_word.as_ref().unwrap().keyword)
        .collect();
    assert_eq!(
        kw,
        vec![
            OKeyword::Sub,
            OKeyword::Call,
            OKeyword::While,
            OKeyword::ProgramNumber,
            OKeyword::EndSub
        ]
    );
    assert_eq!(p.blocks()[1].o_word.as_ref().unwrap().args.len(), 3);
    assert_eq!(p.blocks()[4].o_word.as_ref().unwrap().args.len(), 1);
}

#[test]
fn all_errors_reported_at_once_with_positions() {
    // An unclosed comment and an O-word line's error fail the parse, all of them at once.
    let src = "G1 X1\nG1 X(unclosed\nG1 Y[1+\no1 if [1+\nG1 X1 &\no2 while\n";
    let e = Program::parse(src).unwrap_err();
    let pos: Vec<(u32, u32)> = e.0.iter().map(|d| (d.line, d.col)).collect();
    assert_eq!(pos, vec![(2, 5), (4, 10), (6, 9)], "{e}");
    assert!(e.0[0].message.contains("comment is not closed"));
    // Display: one "LINE:COL: message" per line.
    let text = e.to_string();
    assert_eq!(text.lines().count(), 3);
    assert!(text.starts_with("2:5: "));
    // Any other line's error is kept for when the line runs, with its position.
    let p = Program::parse("G1 X1\nG1 Y[1+\nG1 Z1\nG1 X1 &\n").unwrap();
    let deferred: Vec<(u32, u32)> = p.deferred_errors().map(|d| (d.line, d.col)).collect();
    assert_eq!(deferred, vec![(2, 8), (4, 7)]);
    assert!(p
        .deferred_errors()
        .nth(1)
        .unwrap()
        .message
        .contains("unexpected character '&'"));
    // A grbl sender's commands are named as such where they stand.
    let p = Program::parse("$H\nG21\nG0 X1 ~\n").unwrap();
    let d: Vec<_> = p.deferred_errors().collect();
    assert_eq!((d[0].line, d[0].col, d[1].line, d[1].col), (1, 1, 3, 7));
    assert!(d.iter().all(|d| d.message.contains("grbl")), "{d:?}");
}

#[test]
fn columns_count_characters_not_bytes() {
    let p = Program::parse("(é) G1 X$\n").unwrap();
    let e = p.deferred_errors().next().unwrap();
    assert_eq!((e.line, e.col), (1, 9));
}

#[test]
fn expression_precedence_is_linuxcnc() {
    use millsim_engine::nc::{interpret, InterpretOptions};
    // 2 + 3*2**2 = 14 ; comparisons below arithmetic; AND lowest; MOD is positive.
    let src = "G0 X[2+3*2**2] Y[1 + 1 EQ 2] Z[-7 MOD 3]\nG0 X[1 GT 0 AND 2 LT 1] Y[ATAN[1]/[1]] Z[ABS[-2]+SQRT[16]+FIX[-1.5]+FUP[1.2]+ROUND[2.5]]\n";
    let i = interpret(src, &InterpretOptions::default()).unwrap();
    assert_eq!(&i.moves[0].end[..3], &[14.0, 1.0, 2.0]);
    assert_eq!(i.moves[1].end[0], 0.0);
    assert!((i.moves[1].end[1] - 45.0).abs() < 1e-12);
    assert_eq!(i.moves[1].end[2], 2.0 + 4.0 - 2.0 + 2.0 + 3.0);
}

#[test]
fn with_feeds_changes_or_inserts_only_f_words() {
    let src = "N1 G1 X1 F100 (cut)\nN2 X2\n  N3 Y3 ; note\n(comment only)\nG1 X4 F12.5\n";
    let p = Program::parse(src).unwrap();
    let out = p
        .with_feeds(&[(0, 250.0), (1, 80.5), (2, 90.0), (4, 12.0)])
        .unwrap();
    assert_eq!(
        out,
        "N1 G1 X1 F250 (cut)\nN2 X2 F80.5\n  N3 Y3 F90 ; note\n(comment only)\nG1 X4 F12.\n"
    );
    // Re-parsing the output gives the same blocks with the new feeds.
    let q = Program::parse(&out).unwrap();
    assert_eq!(q.blocks().len(), p.blocks().len());
    // Errors: O-word line, bad feed, unknown block.
    let p2 = Program::parse("o1 sub\nG1 X1\no1 endsub\n").unwrap();
    assert!(p2.with_feeds(&[(0, 10.0)]).is_err());
    assert!(p2.with_feeds(&[(1, -1.0)]).is_err());
    assert!(p2.with_feeds(&[(9, 10.0)]).is_err());
    // Comment-only block: F goes first.
    let p3 = Program::parse("(x)\n").unwrap();
    assert_eq!(p3.with_feeds(&[(0, 5.0)]).unwrap(), "F5 (x)\n");
}

#[test]
fn with_feeds_on_corpus_changes_nothing_else() {
    if common::corpus_dir().is_none() {
        return;
    }
    let src =
        std::fs::read_to_string(Path::new(CORPUS).join("fusion360_2d_pocket_contour_bore_1099.nc"))
            .unwrap();
    let p = Program::parse(&src).unwrap();
    let changes: Vec<(usize, f64)> = (0..p.blocks().len())
        .filter(|&i| !p.blocks()[i].words.is_empty())
        .step_by(7)
        .map(|i| (i, 777.0))
        .collect();
    let out = p.with_feeds(&changes).unwrap();
    let q = Program::parse(&out).unwrap();
    for (a, b) in p.blocks().iter().zip(q.blocks()) {
        let strip = |prog: &Program, blk: &millsim_engine::nc::Block| {
            let mut s = prog.text(blk.span).to_string();
            for w in blk.words.iter().rev().filter(|w| w.letter == 'F') {
                s.replace_range(
                    w.span.start - blk.span.start..w.span.end - blk.span.start,
                    "",
                );
            }
            s.trim_end().to_string()
        };
        assert_eq!(strip(&p, a), strip(&q, b));
    }
    for &(i, _) in &changes {
        let f = q.blocks()[i]
            .words
            .iter()
            .find(|w| w.letter == 'F')
            .unwrap();
        // A literal written with a decimal point keeps one ("F333.3" -> "F777.").
        assert!(
            matches!(q.text(f.span), "F777" | "F777."),
            "{}",
            q.text(f.span)
        );
    }
}

#[test]
fn tool_table_format() {
    use millsim_engine::nc::parse_tool_table;
    let t = parse_tool_table("T1 P1 D6.0 Z+50.0 ;flat 6\n\n; only a comment\nT2 P2 Z-12.5 D3 X0.1 ;\nt15 p15 z40.4 d14\n").unwrap();
    let e = t.get(1).unwrap();
    assert_eq!(
        (e.pocket, e.z_offset, e.diameter, e.comment.as_str()),
        (Some(1), 50.0, Some(6.0), "flat 6")
    );
    assert_eq!(t.get(2).unwrap().z_offset, -12.5);
    assert_eq!(t.get(15).unwrap().diameter, Some(14.0));
    let err = parse_tool_table("T1 Z1\nP2 Z3\nT3 Zx\nT1 Z2\nT4 Q1 K5\n").unwrap_err();
    let lines: Vec<u32> = err.0.iter().map(|d| d.line).collect();
    assert_eq!(lines, vec![2, 3, 4, 5], "{err}");
    assert!(err.0[1].message.contains("'Zx'"));
    assert_eq!(err.0[1].col, 4);
}

#[test]
fn dialect_serde_names() {
    use millsim_engine::nc::Dialect;
    for (d, s) in [
        (Dialect::Auto, "\"auto\""),
        (Dialect::Fanuc, "\"fanuc\""),
        (Dialect::LinuxCnc, "\"linuxcnc\""),
    ] {
        assert_eq!(serde_json::to_string(&d).unwrap(), s);
        assert_eq!(serde_json::from_str::<Dialect>(s).unwrap(), d);
    }
}

/// A ':' or '/' inside a block says what it could have meant.
#[test]
fn stray_colon_and_slash_name_their_use() {
    let p = Program::parse("O1\n#1=#1-#11:\n//comment\nN10 /G1 X1\n").unwrap();
    let e: Vec<(u32, u32, String)> = p
        .deferred_errors()
        .map(|d| (d.line, d.col, d.message.clone()))
        .collect();
    assert_eq!(
        e.iter().map(|e| (e.0, e.1)).collect::<Vec<_>>(),
        vec![(2, 10), (3, 2), (4, 5)]
    );
    assert!(e[0].2.contains("program number :1234"), "{}", e[0].2);
    assert!(
        e[1].2.contains("block delete '/' only starts a block"),
        "{}",
        e[1].2
    );
    assert!(e[2].2.contains("block delete"), "{}", e[2].2);
}
