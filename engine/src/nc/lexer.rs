//! Tokens of one source line. The lexer has two modes because letters mean different things:
//! outside brackets each letter is a word address (`G1X2`), inside brackets letters form
//! names (`SIN`, `MOD`, `GT`).

use super::program::Span;

#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Tok {
    /// A word address, upper-cased (word mode).
    Letter(char),
    /// An alphabetic run, upper-cased (expression mode, O-word keywords).
    Ident(String),
    Number {
        value: f64,
        has_point: bool,
    },
    Plus,
    Minus,
    Star,
    StarStar,
    Slash,
    LBracket,
    RBracket,
    Hash,
    /// `<name>` after `#` or `o`: lower-cased, blanks removed.
    Name(String),
    Equals,
    Comma,
    Comment(String),
    Percent,
    End,
}

impl LexError {
    /// The same error, marked as one of an O-word or macro statement line.
    #[cold]
    pub(crate) fn in_control_line(mut self) -> Self {
        self.control = true;
        self
    }
}

/// Start of the message of a `(` without its `)`.
pub(crate) const UNCLOSED_COMMENT: &str = "comment is not closed";

pub(crate) struct LexError {
    pub pos: usize,
    pub message: String,
    /// The error is in an O-word or macro statement line (set on the error path only).
    pub control: bool,
}

#[derive(Clone)]
pub(crate) struct Lexer<'a> {
    src: &'a str,
    pub pos: usize,
    end: usize,
}

impl<'a> Lexer<'a> {
    /// Lex `src[start..end]` (one line without its terminator).
    pub fn new(src: &'a str, start: usize, end: usize) -> Self {
        Lexer {
            src,
            pos: start,
            end,
        }
    }

    #[inline]
    pub fn byte(&self, i: usize) -> Option<u8> {
        if i < self.end {
            Some(self.src.as_bytes()[i])
        } else {
            None
        }
    }

    /// The number literal at `start` when it takes the fast path of [`scan_decimal`]: value,
    /// whether it has a point, end. None for anything else, including errors.
    #[inline]
    pub fn simple_number_at(&self, start: usize) -> Option<(f64, bool, usize)> {
        let scan = scan_decimal(&self.src.as_bytes()[..self.end], start);
        match scan.value {
            Some(value) if scan.digits > 0 => Some((value, scan.has_point, scan.end)),
            _ => None,
        }
    }

    /// First position at or after `i` that is not a blank.
    #[inline]
    pub fn after_blanks(&self, mut i: usize) -> usize {
        while matches!(self.byte(i), Some(b' ' | b'\t' | b'\r')) {
            i += 1;
        }
        i
    }

    /// Whether the upper-case `kw` is written at `i` (in any case) as a whole alphabetic run.
    pub fn keyword_at(&self, i: usize, kw: &str) -> bool {
        kw.bytes()
            .enumerate()
            .all(|(k, c)| self.byte(i + k).map(|b| b.to_ascii_uppercase()) == Some(c))
            && !self
                .byte(i + kw.len())
                .is_some_and(|b| b.is_ascii_alphabetic())
    }

    pub fn skip_ws(&mut self) {
        self.pos = self.after_blanks(self.pos);
    }

    /// Next non-blank byte without consuming it.
    pub fn peek_byte(&mut self) -> Option<u8> {
        self.skip_ws();
        self.byte(self.pos)
    }

    /// Upper-cased alphabetic run starting at the next non-blank byte (not consumed).
    pub fn peek_ident(&mut self) -> String {
        self.skip_ws();
        let mut i = self.pos;
        let mut s = String::new();
        while let Some(b) = self.byte(i) {
            if b.is_ascii_alphabetic() {
                s.push(b.to_ascii_uppercase() as char);
                i += 1;
            } else {
                break;
            }
        }
        s
    }

    fn err<T>(&self, pos: usize, message: impl Into<String>) -> Result<T, LexError> {
        Err(LexError {
            pos,
            message: message.into(),
            control: false,
        })
    }

    /// The number literal at `start` (digits with at most one '.'), without consuming it:
    /// its value, whether it has a point, and where it ends.
    #[inline]
    pub fn number_at(&self, start: usize) -> Result<(f64, bool, usize), LexError> {
        let scan = scan_decimal(&self.src.as_bytes()[..self.end], start);
        if scan.digits == 0 {
            return self.err(start, "'.' is not a number");
        }
        let value = match scan.value {
            Some(v) => v,
            None => {
                let text = &self.src[start..scan.end];
                match text.parse() {
                    Ok(v) => v,
                    Err(_) => return self.err(start, format!("bad number '{text}'")),
                }
            }
        };
        Ok((value, scan.has_point, scan.end))
    }

    /// Next token; `names` selects expression mode (alphabetic runs are one token).
    pub fn next(&mut self, names: bool) -> Result<(Tok, Span), LexError> {
        self.skip_ws();
        let start = self.pos;
        let Some(b) = self.byte(start) else {
            return Ok((Tok::End, Span::new(start, start)));
        };
        let tok = match b {
            b'(' => {
                let body = start + 1;
                let mut i = body;
                // Nested parentheses are balanced (simulator directives such as
                // `($SetPartSize(100, 100, 20, 1) )` use them); LinuxCNC would refuse them.
                let mut depth = 1;
                loop {
                    match self.byte(i) {
                        Some(b')') => {
                            depth -= 1;
                            if depth == 0 {
                                break;
                            }
                            i += 1;
                        }
                        Some(b'(') => {
                            depth += 1;
                            i += 1;
                        }
                        Some(_) => i += 1,
                        None => return self.err(start, format!("{UNCLOSED_COMMENT}: missing ')'")),
                    }
                }
                self.pos = i + 1;
                Tok::Comment(self.src[body..i].to_string())
            }
            b';' => {
                self.pos = self.end;
                Tok::Comment(self.src[start + 1..self.end].to_string())
            }
            b'0'..=b'9' | b'.' => {
                let (value, has_point, end) = self.number_at(start)?;
                self.pos = end;
                Tok::Number { value, has_point }
            }
            b'+' => {
                self.pos += 1;
                Tok::Plus
            }
            b'-' => {
                self.pos += 1;
                Tok::Minus
            }
            b'*' => {
                if self.byte(start + 1) == Some(b'*') {
                    self.pos += 2;
                    Tok::StarStar
                } else {
                    self.pos += 1;
                    Tok::Star
                }
            }
            b'/' => {
                self.pos += 1;
                Tok::Slash
            }
            b'[' => {
                self.pos += 1;
                Tok::LBracket
            }
            b']' => {
                self.pos += 1;
                Tok::RBracket
            }
            b'#' => {
                self.pos += 1;
                Tok::Hash
            }
            b'=' => {
                self.pos += 1;
                Tok::Equals
            }
            b',' => {
                self.pos += 1;
                Tok::Comma
            }
            b'%' => {
                self.pos += 1;
                Tok::Percent
            }
            b'<' => {
                let mut i = start + 1;
                let mut name = String::new();
                loop {
                    match self.byte(i) {
                        Some(b'>') => break,
                        Some(c) if c == b' ' || c == b'\t' => i += 1,
                        Some(c) if c.is_ascii() && !c.is_ascii_control() => {
                            name.push(c.to_ascii_lowercase() as char);
                            i += 1;
                        }
                        Some(_) => return self.err(i, "bad character in a <name>"),
                        None => return self.err(start, "name is not closed: missing '>'"),
                    }
                }
                if name.is_empty() {
                    return self.err(start, "empty <name>");
                }
                self.pos = i + 1;
                Tok::Name(name)
            }
            c if c.is_ascii_alphabetic() => {
                if names {
                    let s = self.peek_ident();
                    self.pos = start + s.len();
                    Tok::Ident(s)
                } else {
                    self.pos += 1;
                    Tok::Letter(c.to_ascii_uppercase() as char)
                }
            }
            // LinuxCNC's polar words: radius and angle.
            b'@' | b'^' if !names => {
                self.pos += 1;
                Tok::Letter(b as char)
            }
            // A Fanuc program number `:1234` only starts a line (often a typo for ';').
            b':' => {
                return self.err(
                    start,
                    "unexpected ':' (a program number :1234 stands at the start of its line; a block ends with ';' or the line end)",
                );
            }
            // grbl's system commands (`$H` homing, `$X` unlock, `$J=` jog) and real-time
            // commands (`~` resume, `!` hold, `?` status) go to the controller, not the program.
            b'$' | b'~' | b'!' | b'?' => {
                let ch = b as char;
                return self.err(
                    start,
                    format!("'{ch}' starts a grbl system or real-time command (`$H` homing, `$X` unlock, `$J=` jog, `~` resume, `!` feed hold), which a sender gives the controller: not G-code and not supported; remove the line"),
                );
            }
            _ => {
                let ch = self.src[start..].chars().next().unwrap_or('?');
                return self.err(start, format!("unexpected character '{ch}'"));
            }
        };
        Ok((tok, Span::new(start, self.pos)))
    }
}

/// Digits with at most one '.' from `start`, read in one pass.
struct DecimalScan {
    end: usize,
    digits: usize,
    has_point: bool,
    /// The value when Clinger's fast path applies: at most 15 significant digits and 22
    /// decimals make it one correctly rounded division of two exact doubles, so it equals
    /// `str::parse` bit for bit. None: use the general parser.
    value: Option<f64>,
}

#[inline]
fn scan_decimal(bytes: &[u8], start: usize) -> DecimalScan {
    const POW10: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
        1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
    ];
    let mut mantissa: u64 = 0;
    // Leading zeros do not count towards the 15 digits.
    let mut significant = 0;
    let mut digits = 0;
    let mut decimals = 0;
    let mut has_point = false;
    let mut i = start;
    while let Some(&b) = bytes.get(i) {
        if b.is_ascii_digit() {
            if mantissa != 0 || b != b'0' {
                significant += 1;
            }
            // Wraps only past 19 digits, when the value is not used.
            mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(b - b'0'));
            digits += 1;
            decimals += usize::from(has_point);
        } else if b == b'.' && !has_point {
            has_point = true;
        } else {
            break;
        }
        i += 1;
    }
    let value = (significant <= 15 && decimals < POW10.len()).then(|| {
        // Whole numbers (N, G, M words) are exact as they are; skip the slow division.
        if decimals == 0 {
            mantissa as f64
        } else {
            mantissa as f64 / POW10[decimals]
        }
    });
    DecimalScan {
        end: i,
        digits,
        has_point,
        value,
    }
}

#[cfg(test)]
mod tests {
    /// The fast-path value of a whole literal.
    fn fast_decimal(s: &[u8]) -> Option<f64> {
        let scan = super::scan_decimal(s, 0);
        if scan.end == s.len() && scan.digits > 0 {
            scan.value
        } else {
            None
        }
    }

    #[test]
    fn fast_decimal_matches_std_parse() {
        let mut x: u64 = 0x2545_F491_4F6C_DD1D;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let int = x % 100_000;
            let frac = (x >> 20) % 10_000_000;
            let w = ((x >> 50) % 8) as usize;
            let s = format!("{int}.{frac:0w$}", w = w.max(1));
            let s = &s[..s.len().min(18)];
            let fast = fast_decimal(s.as_bytes());
            let std: f64 = s.parse().unwrap();
            if let Some(f) = fast {
                assert_eq!(f.to_bits(), std.to_bits(), "{s}");
            }
        }
        for s in [
            "0",
            "0.",
            ".5",
            "75.",
            "-0",
            "0000.0001",
            "123456789012345",
            "1234567890123456",
        ] {
            if let (Some(f), Ok(p)) = (fast_decimal(s.as_bytes()), s.parse::<f64>()) {
                assert_eq!(f.to_bits(), p.to_bits(), "{s}");
            }
        }
    }
}
