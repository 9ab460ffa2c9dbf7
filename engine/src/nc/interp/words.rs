//! The words of one block, evaluated: letters, G and M codes (checked against their modal
//! groups), Fanuc corner words, and the block's parameter assignments.

use super::modal::{g_group, g_name, g_refusal, m_group};
use super::{Interp, R};
use crate::nc::expr::is_vacant;
use crate::nc::program::Expr;
use crate::nc::view::BlockView;

pub(super) const AXES: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

pub(super) fn letter_index(c: char) -> usize {
    (c as u8 - b'A') as usize
}

/// The evaluated words of one block.
pub(super) struct Words {
    pub(super) vals: [Option<(f64, usize)>; 26],
    pub(super) used: [bool; 26],
    /// G codes times ten (G43.1 -> 431) with the word index.
    pub(super) gs: Vec<(u16, usize)>,
    pub(super) ms: Vec<(u32, usize)>,
    pub(super) corner_r: Option<(f64, usize)>,
    pub(super) corner_c: Option<(f64, usize)>,
    /// Polar radius and angle (LinuxCNC `@` `^`; Fanuc G16 moves the plane's axis words
    /// here), and whether a motion took them.
    pub(super) polar_r: Option<(f64, usize)>,
    pub(super) polar_a: Option<(f64, usize)>,
    /// Polar words are in the block (`polar_any`) and no motion has taken them yet
    /// (`polar_open`).
    pub(super) polar_any: bool,
    pub(super) polar_open: bool,
    /// A G code of Fanuc's transform groups or G67 is in the block.
    pub(super) transform: bool,
    /// A machine accuracy/look-ahead mode code (G5.1 Q1, G187 P1 E..) is in the block: its
    /// P, Q, R and E words are its settings.
    pub(super) machine_mode: bool,
}

impl Words {
    pub(super) fn get(&self, c: char) -> Option<f64> {
        self.vals[letter_index(c)].map(|v| v.0)
    }
    pub(super) fn take(&mut self, c: char) -> Option<f64> {
        let i = letter_index(c);
        if self.vals[i].is_some() {
            self.used[i] = true;
        }
        self.vals[i].map(|v| v.0)
    }
    pub(super) fn has(&self, c: char) -> bool {
        self.vals[letter_index(c)].is_some()
    }
    /// Axis words not yet used by an earlier step of the block (G4 X, G43.1 Z).
    #[inline]
    pub(super) fn has_axis(&self) -> bool {
        AXES.iter()
            .any(|&c| self.has(c) && !self.used[letter_index(c)])
            || self.polar_open
    }
    pub(super) fn g(&self, code: u16) -> Option<usize> {
        self.gs.iter().find(|g| g.0 == code).map(|g| g.1)
    }
    pub(super) fn m(&self, code: u32) -> Option<usize> {
        self.ms.iter().find(|m| m.0 == code).map(|m| m.1)
    }
}

impl<'p> Interp<'p> {
    /// Evaluate the block's words into `w` (filled in place: it is large to move around).
    pub(super) fn read_words(&mut self, b: &BlockView<'p>, w: &mut Words) -> R<Vec<f64>> {
        let implied = self.opts.fanuc_implied_decimal;
        for (i, word) in b.words.iter().enumerate() {
            let mut v = match word.value {
                // Most words are plain numbers: skip the expression evaluator.
                Expr::Number { value, .. } if value.is_finite() => value,
                ref e => {
                    let v = self.eval(e, word.value_span.start)?;
                    if is_vacant(v) {
                        // Fanuc: a word whose value is vacant is not in the block.
                        continue;
                    }
                    v
                }
            };
            let c = word.letter;
            if implied
                && matches!(
                    c,
                    'X' | 'Y'
                        | 'Z'
                        | 'A'
                        | 'B'
                        | 'C'
                        | 'I'
                        | 'J'
                        | 'K'
                        | 'R'
                        | 'Q'
                        | 'U'
                        | 'V'
                        | 'W'
                )
            {
                if let Expr::Number {
                    has_point: false, ..
                } = strip_neg(&word.value)
                {
                    let inc = if matches!(c, 'A' | 'B' | 'C') || self.modal.metric {
                        1000.0
                    } else {
                        10000.0
                    };
                    v /= inc;
                }
            }
            let pos = word.span.start;
            if word.comma {
                if !self.fanuc {
                    return Err(self.err_at(
                        pos,
                        format!(",{c} is Fanuc corner syntax; not valid with dialect linuxcnc"),
                    ));
                }
                let slot = if c == 'R' {
                    &mut w.corner_r
                } else {
                    &mut w.corner_c
                };
                if slot.is_some() {
                    return Err(self.err_at(pos, format!("two ,{c} words in one block")));
                }
                *slot = Some((v, i));
                continue;
            }
            match c {
                'G' => {
                    let code = (v * 10.0).round();
                    if (v * 10.0 - code).abs() > 1e-6 || !(0.0..=9999.0).contains(&code) {
                        return Err(self.err_at(pos, format!("G{v} is not a G code")));
                    }
                    let code = code as u16;
                    // Haas's tool-centre-point control (UMC) is Fanuc's G43.4, cancelled by G49
                    // alike; LinuxCNC has no G234.
                    let code = if code == 2340 && self.opts.dialect != crate::nc::Dialect::LinuxCnc
                    {
                        434
                    } else {
                        code
                    };
                    if let Some(what) = matches!(code, 50 | 51 | 80 | 90 | 1030 | 1870)
                        .then(|| self.machine_mode_code(code))
                        .flatten()
                    {
                        // Warned once per code: the path is as programmed, only the control's
                        // smoothing/look-ahead differs.
                        if self.out.warned_m_codes.insert(100_000 + u32::from(code)) {
                            self.out.warnings.push(self.err_at(
                                pos,
                                format!("{} ({what}) makes no motion: ignored; the path is simulated as programmed", g_name(code)),
                            ));
                        }
                        w.machine_mode = true;
                        continue;
                    }
                    // G76 is Fanuc's fine boring cycle, LinuxCNC's lathe threading; G31 is
                    // Fanuc's skip (probing) move.
                    let Some(group) =
                        g_group(code).filter(|_| !matches!(code, 760 | 310) || self.fanuc)
                    else {
                        return Err(
                            self.err_at(pos, format!("{} {}", g_name(code), g_refusal(code)))
                        );
                    };
                    // G80 beside another motion code just cancels the cycle first (Fanuc
                    // programs write `G00 ... G80`; LinuxCNC accepts it too).
                    if let Some(&(other, _)) = w.gs.iter().find(|g| {
                        g_group(g.0) == Some(group) && !(group == 1 && (g.0 == 800 || code == 800))
                    }) {
                        return Err(self.err_at(
                            pos,
                            format!(
                                "{} and {} are in the same modal group; only one per block",
                                g_name(other),
                                g_name(code)
                            ),
                        ));
                    }
                    // Fanuc's scaling, rotation, polar, mirror and modal call groups.
                    w.transform |= matches!(group, 11 | 16 | 17 | 22 | 23);
                    w.gs.push((code, i));
                }
                'M' => {
                    if v.fract() != 0.0 || !(0.0..=99999.0).contains(&v) {
                        return Err(self.err_at(pos, format!("M{v} is not an M code")));
                    }
                    let code = v as u32;
                    // Passthrough codes each get a group of their own, above every real one
                    // (u32: M codes run into the thousands).
                    if matches!(code, 97..=99) && !self.fanuc {
                        return Err(self.err_at(
                            pos,
                            format!("M{code}: Fanuc/Haas subprogram call/return; not valid with dialect linuxcnc (use o-word call/endsub)"),
                        ));
                    }
                    let group = match m_group(code) {
                        Some(g) => u32::from(g),
                        None if self.opts.passthrough_m_codes.contains(&code) => 1000 + code,
                        // Fanuc/Haas rigid tapping (`M29 S500` before G84): the tap's path is the
                        // cycle's either way, nothing to warn of.
                        None if code == 29 && self.fanuc => 1000 + code,
                        None if self.opts.strict_m_codes => {
                            let why = match code {
                                100..=199 => "user M codes run external programs; list it in passthrough_m_codes if it does not move the machine".to_string(),
                                62..=68 => "digital/analog output codes are not supported".to_string(),
                                _ => "is not supported (list it in passthrough_m_codes if it does not move the machine)".to_string(),
                            };
                            return Err(self.err_at(pos, format!("M{code}: {why}")));
                        }
                        None => {
                            // A machine's own M code (coolant variants, clamps, outputs, user
                            // macros): assumed to move nothing, said once per code.
                            if self.out.warned_m_codes.insert(code) {
                                self.out.warnings.push(self.err_at(
                                    pos,
                                    format!("M{code} is not a standard M code: assumed to make no motion and ignored (strict_m_codes refuses it; passthrough_m_codes silences this)"),
                                ));
                            }
                            1000 + code
                        }
                    };
                    if let Some(&(other, _)) = w.ms.iter().find(|m| {
                        let og = m_group(m.0).map(u32::from).unwrap_or(1000 + m.0);
                        og == group
                            && !(group == 8
                                && (m.0 == 7 || m.0 == 8)
                                && (code == 7 || code == 8)
                                && m.0 != code)
                    }) {
                        return Err(self.err_at(pos, format!("M{other} and M{code} are in the same modal group; only one per block")));
                    }
                    if w.ms.len() >= 4 {
                        return Err(self.err_at(pos, "more than four M words in one block"));
                    }
                    w.ms.push((code, i));
                }
                'N' | 'O' => {
                    return Err(self.err_at(pos, format!("{c} word in the middle of a block")))
                }
                'U' | 'V' | 'W' => {
                    return Err(self.err_at(
                        pos,
                        format!("{c} axis is not supported (axes are X Y Z A B C)"),
                    ))
                }
                // Haas G187 E: the smoothing tolerance.
                'E' if w.machine_mode => {
                    w.vals[letter_index('E')] = Some((v, i));
                    w.used[letter_index('E')] = true;
                }
                '@' | '^' => {
                    let slot = if c == '@' {
                        &mut w.polar_r
                    } else {
                        &mut w.polar_a
                    };
                    if slot.is_some() {
                        return Err(self.err_at(pos, format!("two {c} words in one block")));
                    }
                    *slot = Some((v, i));
                    w.polar_any = true;
                    w.polar_open = true;
                }
                _ => {
                    let li = letter_index(c);
                    if w.vals[li].is_some() {
                        return Err(self.err_at(pos, format!("two {c} words in one block")));
                    }
                    w.vals[li] = Some((v, i));
                }
            }
        }
        // Parameter assignments are evaluated with the values from before the block and take
        // effect after all of the block's words are read (LinuxCNC rule).
        let mut vals = Vec::with_capacity(b.assignments.len());
        for a in b.assignments {
            vals.push(self.eval(&a.value, a.span.start)?);
        }
        Ok(vals)
    }
}

pub(super) fn strip_neg(e: &Expr) -> &Expr {
    match e {
        Expr::Neg(x) => strip_neg(x),
        other => other,
    }
}

impl Interp<'_> {
    /// Codes that set how a control smooths or looks ahead, without motion of their own; what
    /// each is, or None. Fanuc's G5 P.., G5.1 Q.., G8 P.. share their numbers with LinuxCNC's
    /// splines and lathe mode, so only with the Fanuc dialect; Haas's G103 and G187 exist on
    /// no LinuxCNC, so with any but an explicit linuxcnc dialect.
    fn machine_mode_code(&self, code: u16) -> Option<&'static str> {
        match code {
            50 if self.fanuc => Some("Fanuc high-precision contour control"),
            51 if self.fanuc => Some("Fanuc AI contour control"),
            80 if self.fanuc => Some("Fanuc look-ahead control"),
            90 if self.opts.dialect != crate::nc::Dialect::LinuxCnc => {
                Some("exact stop check for this block")
            }
            1030 | 1870 if self.opts.dialect != crate::nc::Dialect::LinuxCnc => {
                Some(if code == 1030 {
                    "Haas block look-ahead limit"
                } else {
                    "Haas smoothness and corner tolerance"
                })
            }
            _ => None,
        }
    }
}
