//! The program at the chosen speed: every S word set to it and every F word scaled with it
//! (the feed per tooth held), every other byte as it was.
//!
//! F words are scaled in the mode in force where they stand (source order, as the feed
//! rewrite reads units): per minute (G94) and inverse time (G93) by chosen/programmed, per
//! revolution (G95) not at all. A per-minute F that would pass the machine's max feed is
//! written at the max feed (counted; one already over it as programmed stays as it was). A
//! program without an S word is refused rather than given one: the feed per tooth it means is
//! unknown, so there is nothing to hold (the choice needs the programmed speed). F words written
//! as expressions (`F#1`) are refused: their value is not the program's text to scale; an S
//! word, whatever it was written as, is set to the chosen speed.

use super::SpindleError;
use crate::nc::{Expr, Program};

/// The rewritten text and what changed.
#[derive(Clone, Debug, PartialEq)]
pub struct SpeedRewrite {
    pub text: String,
    pub s_words: usize,
    pub f_words: usize,
    /// F words held to the machine's max feed.
    pub f_words_at_max_feed: usize,
}

fn literal(e: &Expr) -> Option<f64> {
    match e {
        Expr::Number { value, .. } => Some(*value),
        Expr::Neg(x) => literal(x).map(|v| -v),
        _ => None,
    }
}

/// `program` with its S words at `chosen_rpm` and its F words scaled by
/// chosen/programmed; `max_feed_mm_min` caps per-minute feeds (in the block's units).
pub fn at_spindle_speed(
    program: &Program,
    programmed_rpm: f64,
    chosen_rpm: f64,
    max_feed_mm_min: f64,
) -> Result<SpeedRewrite, SpindleError> {
    let ratio = chosen_rpm / programmed_rpm;
    let (mut unit, mut mode) = (1.0, 94);
    let mut edits: Vec<(usize, usize, String)> = Vec::new();
    let (mut s_words, mut f_words, mut capped) = (0, 0, 0);
    for b in program.blocks() {
        // Modal words first: a block's own G20/G95 applies to its own F.
        for w in b.words.iter().filter(|w| w.letter == 'G') {
            match literal(&w.value) {
                Some(20.0) => unit = 25.4,
                Some(21.0) => unit = 1.0,
                Some(v) if v == 93.0 || v == 94.0 || v == 95.0 => mode = v as i32,
                Some(96.0) => {
                    return Err(SpindleError::new(
                        "choose",
                        format!("line {}: G96 (constant surface speed) sets the speed from the diameter; choose a speed only for a program in G97 (S in rpm)", b.line),
                    ))
                }
                _ => {}
            }
        }
        for w in b.words.iter().filter(|w| !w.comma) {
            match w.letter {
                'S' => {
                    edits.push((
                        w.value_span.start,
                        w.value_span.end,
                        format!("{}", chosen_rpm.round() as i64),
                    ));
                    s_words += 1;
                }
                'F' => {
                    let Some(f) = literal(&w.value) else {
                        return Err(SpindleError::new(
                            "choose",
                            format!("line {}: `{}` is an expression: its feed cannot be scaled to hold the feed per tooth; write the feed as a number", b.line, program.text(w.span)),
                        ));
                    };
                    if mode == 95 {
                        continue;
                    }
                    let mut v = f * ratio;
                    let cap = max_feed_mm_min / unit;
                    // Never above the machine's max feed, nor above the programmed feed where
                    // that already was (the control clamps it; the rewrite does not raise it).
                    if mode == 94 && max_feed_mm_min > 0.0 && v > cap {
                        let held = cap.max(v.min(f));
                        if held < v {
                            v = held;
                            capped += 1;
                        }
                    }
                    // Down to 4 decimals, as the feed rewrite writes them.
                    let v = ((v * 1e4) * (1.0 + 1e-12)).floor() / 1e4;
                    let had_point = program.text(w.value_span).contains('.');
                    edits.push((
                        w.value_span.start,
                        w.value_span.end,
                        crate::nc::format_feed(v, had_point),
                    ));
                    f_words += 1;
                }
                _ => {}
            }
        }
    }
    if s_words == 0 {
        return Err(SpindleError::new(
            "choose",
            "the program sets no spindle speed (no S word): the feed per tooth it means is unknown, so no speed can be chosen for it; program the speed (S) it was written for",
        ));
    }
    edits.sort_by_key(|e| (e.0, e.1));
    let source = program.source();
    let mut text = String::with_capacity(source.len() + 16);
    let mut pos = 0;
    for (s, e, t) in edits {
        text.push_str(&source[pos..s]);
        text.push_str(&t);
        pos = e;
    }
    text.push_str(&source[pos..]);
    Ok(SpeedRewrite {
        text,
        s_words,
        f_words,
        f_words_at_max_feed: capped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn s_and_f_words_change_and_nothing_else() {
        let src = "%\nO1 (speed test)\nN10 G21 G90 G94 S10000 M3\nN20 G1 X10. F1200. ; cut\nN30 X20\nG95 F0.1\nG1 X30\nG94 F600\n%\n";
        let p = Program::parse(src).unwrap();
        let r = at_spindle_speed(&p, 10_000.0, 15_000.0, 10_000.0).unwrap();
        assert_eq!(
            r.text,
            "%\nO1 (speed test)\nN10 G21 G90 G94 S15000 M3\nN20 G1 X10. F1800. ; cut\nN30 X20\nG95 F0.1\nG1 X30\nG94 F900\n%\n"
        );
        assert_eq!((r.s_words, r.f_words, r.f_words_at_max_feed), (1, 2, 0));
        // Held to the machine's max feed.
        let r = at_spindle_speed(&p, 10_000.0, 15_000.0, 1500.0).unwrap();
        assert!(r.text.contains("F1500."), "{}", r.text);
        assert_eq!(r.f_words_at_max_feed, 1);
        // A feed already over the max stays as programmed; a slower speed lowers it.
        let r = at_spindle_speed(&p, 10_000.0, 15_000.0, 1000.0).unwrap();
        assert!(r.text.contains("F1200."), "{}", r.text);
        let r = at_spindle_speed(&p, 10_000.0, 5_000.0, 1000.0).unwrap();
        assert!(
            r.text.contains("F600.") && r.text.contains("F300\n"),
            "{}",
            r.text
        );
        // Inch programs: the cap in inches per minute.
        let p = Program::parse("G20 G94 S1000 M3\nG1 X1 F50\n").unwrap();
        let r = at_spindle_speed(&p, 1000.0, 2000.0, 2540.0).unwrap();
        assert!(r.text.ends_with("F100\n"), "{}", r.text);
        let r = at_spindle_speed(&p, 1000.0, 2000.0, 1270.0).unwrap();
        assert!(r.text.ends_with("F50\n"), "{}", r.text);
    }

    #[test]
    fn no_s_word_and_expressions_are_refused() {
        let p = Program::parse("G1 X1 F100\n").unwrap();
        let e = at_spindle_speed(&p, 1000.0, 2000.0, 1e4).unwrap_err();
        assert!(e.to_string().contains("no S word"), "{e}");
        let p = Program::parse("S1000 M3\n#1=100\nG1 X1 F#1\n").unwrap();
        let e = at_spindle_speed(&p, 1000.0, 2000.0, 1e4).unwrap_err();
        assert!(e.to_string().contains("line 3"), "{e}");
    }
}
