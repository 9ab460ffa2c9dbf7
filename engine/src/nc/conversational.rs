//! Programs in a control's conversational language rather than G-code, recognised by their
//! first line so that they are refused by name instead of by the first token the G-code
//! parser trips on (a Heidenhain Klartext program's line number `0` read as a stray number).

use super::{Diagnostic, Diagnostics};

/// Refuses a Heidenhain conversational (Klartext) program: its first line that is not
/// blank or a whole-line comment (`(…`, `;…`, `%`: a simulator's or a DNC sender's header)
/// reads `0 BEGIN PGM <name> MM|INCH` (the name may be missing).
pub(super) fn refuse_conversational(source: &str) -> Result<(), Diagnostics> {
    let Some((index, line)) = source.lines().enumerate().find(|(_, l)| {
        let l = l.trim();
        !(l.is_empty() || l.starts_with(['(', ';', '%']))
    }) else {
        return Ok(());
    };
    let words: Vec<&str> = line.split_whitespace().take(3).collect();
    let begins = match words.as_slice() {
        [n, b, p] if n.bytes().all(|c| c.is_ascii_digit()) => {
            b.eq_ignore_ascii_case("BEGIN") && p.eq_ignore_ascii_case("PGM")
        }
        [b, p, ..] => b.eq_ignore_ascii_case("BEGIN") && p.eq_ignore_ascii_case("PGM"),
        _ => false,
    };
    if !begins {
        return Ok(());
    }
    Err(Diagnostic::new(
        (index + 1).min(u32::MAX as usize) as u32,
        1,
        "a Heidenhain conversational (Klartext) program (BEGIN PGM) is not supported: post it \
         for an ISO G-code control (dialect fanuc or linuxcnc), or as APT/CLS",
    )
    .into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn klartext_is_refused_at_its_first_line_and_g_code_is_not() {
        let e = refuse_conversational("\n\n0 BEGIN PGM TEST MM\n1 L X+0 FMAX\n").unwrap_err();
        assert_eq!((e.0[0].line, e.0[0].col), (3, 1));
        assert!(e.0[0].message.contains("Heidenhain"), "{e}");
        assert!(refuse_conversational("begin pgm x mm\n").is_err());
        // After a header of comments, and without a name (a simulator's sample).
        let e = refuse_conversational("($Message(\"load the settings\"))\n; note\nBEGIN PGM  MM\n")
            .unwrap_err();
        assert_eq!(e.0[0].line, 3);
        for ok in [
            "",
            "G0 X0\n",
            "%\nO1000\nG0 X0\n",
            "(BEGIN PGM in a comment)\n",
            "0 BEGIN\n",
        ] {
            assert!(refuse_conversational(ok).is_ok(), "{ok:?}");
        }
    }
}
