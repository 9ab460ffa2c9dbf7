//! Evaluation of LinuxCNC `[expressions]` and parameter storage.

use super::program::{fanuc_precedence, reduce, BinOp, Expr, Func, ParamRef};
use std::collections::HashMap;

/// Highest numbered parameter (LinuxCNC: 5601 user-visible).
pub(crate) const MAX_PARAM: usize = 5601;
/// LinuxCNC's tolerance for EQ / NE.
const TOLERANCE_EQUAL: f64 = 1e-4;

/// Bits of the value that marks a vacant (null) Fanuc variable: a quiet NaN with a payload no
/// arithmetic produces. Only a Fanuc program holds it (LinuxCNC parameters start at 0 and
/// `#0` does not exist there); every operator reads it as 0, EQ/NE tell it from 0, and a word
/// whose value is vacant is left out of its block.
const VACANT_BITS: u64 = 0x7ff8_0000_0000_0bad;

/// The vacant value (Fanuc `#0`, a variable never set, an argument not given to G65).
pub(crate) fn vacant() -> f64 {
    f64::from_bits(VACANT_BITS)
}

pub(crate) fn is_vacant(v: f64) -> bool {
    v.to_bits() == VACANT_BITS
}

/// A value for a message: `vacant`, or the number without trailing zeros.
pub(crate) fn num_text(v: f64) -> String {
    if is_vacant(v) {
        "<vacant>".to_string()
    } else {
        format!("{v}")
    }
}

/// A whole number that fits an i64 exactly.
fn whole(v: f64) -> bool {
    v.fract() == 0.0 && v.abs() < 9.0e15
}

/// A vacant value as an operand: 0.
fn num(v: f64) -> f64 {
    if v.is_nan() {
        0.0
    } else {
        v
    }
}

/// Where parameter values come from during evaluation.
pub(crate) trait Env {
    fn numbered(&self, n: usize) -> Result<f64, String>;
    fn named(&self, name: &str) -> Result<f64, String>;
    fn exists(&self, name: &str) -> bool;
    /// Fanuc rules: `#0` exists (always vacant).
    fn fanuc(&self) -> bool {
        false
    }
}

/// Fanuc 30i-series extended common variables (#100000–#199999 and #500000–#999999, the
/// first non-volatile like #500–#999 on the machine): production macros keep their tables
/// there. Held sparsely (see [`Params::extended`]).
pub(crate) const FANUC_EXTENDED: [std::ops::RangeInclusive<usize>; 2] =
    [100_000..=199_999, 500_000..=999_999];

/// Parameter number from a value: an integer in 1..=5601, or with `fanuc` in the 30i's
/// extended common ranges.
pub(crate) fn param_index(v: f64, fanuc: bool) -> Result<usize, String> {
    let r = v.round();
    if !v.is_finite() || (v - r).abs() > 1e-4 {
        return Err(format!("parameter number {v} is not a whole number"));
    }
    let extended = fanuc && FANUC_EXTENDED.iter().any(|x| x.contains(&(r as usize)));
    if !extended && (r < 1.0 || r > MAX_PARAM as f64) {
        return Err(if fanuc {
            format!("variable number {r} out of range: 1..{MAX_PARAM}, 100000..199999 or 500000..999999")
        } else {
            format!("parameter number {r} out of range 1..{MAX_PARAM}")
        });
    }
    Ok(r as usize)
}

/// Resolve the index of a numbered parameter reference.
pub(crate) fn resolve_index(e: &Expr, env: &dyn Env) -> Result<usize, String> {
    let v = eval(e, env)?;
    if v == 0.0 && env.fanuc() {
        return Ok(0);
    }
    param_index(v, env.fanuc())
}

pub(crate) fn eval(e: &Expr, env: &dyn Env) -> Result<f64, String> {
    let v = eval_inner(e, env)?;
    if v.is_finite() || is_vacant(v) {
        Ok(v)
    } else {
        Err("expression result is not a finite number".to_string())
    }
}

fn eval_inner(e: &Expr, env: &dyn Env) -> Result<f64, String> {
    Ok(match e {
        Expr::Number { value, .. } => *value,
        Expr::Param(p) => match p.as_ref() {
            ParamRef::Numbered(ix) => env.numbered(resolve_index(ix, env)?)?,
            ParamRef::Named(n) => env.named(n)?,
        },
        Expr::Neg(x) => -num(eval(x, env)?),
        Expr::Mixed(m) => {
            let prec = if env.fanuc() {
                fanuc_precedence
            } else {
                BinOp::precedence
            };
            eval(&reduce(m.0.clone(), m.1.clone(), prec), env)?
        }
        Expr::Exists(n) => {
            if env.exists(n) {
                1.0
            } else {
                0.0
            }
        }
        Expr::Atan(y, x) => {
            let (y, x) = (num(eval(y, env)?), num(eval(x, env)?));
            y.atan2(x).to_degrees()
        }
        Expr::Func(f, x) => {
            let x = num(eval(x, env)?);
            match f {
                Func::Abs => x.abs(),
                Func::Acos => {
                    if !(-1.0..=1.0).contains(&x) {
                        return Err(format!("ACOS argument {x} out of range -1..1"));
                    }
                    x.acos().to_degrees()
                }
                Func::Asin => {
                    if !(-1.0..=1.0).contains(&x) {
                        return Err(format!("ASIN argument {x} out of range -1..1"));
                    }
                    x.asin().to_degrees()
                }
                Func::Cos => x.to_radians().cos(),
                Func::Sin => x.to_radians().sin(),
                Func::Tan => x.to_radians().tan(),
                Func::Exp => x.exp(),
                Func::Fix => x.floor(),
                Func::Fup => x.ceil(),
                Func::Round => x.round(),
                Func::Ln => {
                    if x <= 0.0 {
                        return Err(format!("LN of zero or a negative number ({x})"));
                    }
                    x.ln()
                }
                Func::Sqrt => {
                    if x < 0.0 {
                        return Err(format!("SQRT of a negative number ({x})"));
                    }
                    x.sqrt()
                }
            }
        }
        Expr::Binary(op, l, r) => {
            let (a, b) = (eval(l, env)?, eval(r, env)?);
            let t = |c: bool| if c { 1.0 } else { 0.0 };
            if matches!(op, BinOp::Eq | BinOp::Ne) && (is_vacant(a) || is_vacant(b)) {
                // Fanuc: vacant equals only vacant.
                let same = is_vacant(a) && is_vacant(b);
                return Ok(t(same == (*op == BinOp::Eq)));
            }
            let (a, b) = (num(a), num(b));
            match op {
                BinOp::Pow => {
                    if a < 0.0 && b.fract() != 0.0 {
                        return Err(format!(
                            "cannot raise negative number {a} to non-integer power {b}"
                        ));
                    }
                    a.powf(b)
                }
                BinOp::Mul => a * b,
                BinOp::Div => {
                    if b == 0.0 {
                        // Fanuc: a vacant divisor counts as 0; in a macro run on its own
                        // (not called with G65 and its arguments) that is the usual cause.
                        let vacant_divisor = match r.as_ref() {
                            Expr::Param(p) => match p.as_ref() {
                                ParamRef::Numbered(ix) if is_vacant(eval(r, env)?) => {
                                    Some(resolve_index(ix, env)?)
                                }
                                _ => None,
                            },
                            _ => None,
                        };
                        return Err(match vacant_divisor {
                            Some(n) => format!(
                                "division by zero: the divisor #{n} is vacant (a macro argument not given? run the macro through its G65 call)"
                            ),
                            None => "division by zero".to_string(),
                        });
                    }
                    a / b
                }
                BinOp::Mod => {
                    if b == 0.0 {
                        return Err("MOD by zero".to_string());
                    }
                    let m = a % b;
                    if m < 0.0 {
                        m + b.abs()
                    } else {
                        m
                    }
                }
                BinOp::Add => a + b,
                BinOp::Sub => a - b,
                BinOp::Eq => t((a - b).abs() < TOLERANCE_EQUAL),
                BinOp::Ne => t((a - b).abs() >= TOLERANCE_EQUAL),
                BinOp::Gt => t(a > b),
                BinOp::Ge => t(a >= b),
                BinOp::Lt => t(a < b),
                BinOp::Le => t(a <= b),
                // Fanuc: bit by bit on whole numbers (the same as LinuxCNC's logic on 0/1).
                BinOp::And | BinOp::Or | BinOp::Xor if env.fanuc() && whole(a) && whole(b) => {
                    let (x, y) = (a as i64, b as i64);
                    (match op {
                        BinOp::And => x & y,
                        BinOp::Or => x | y,
                        _ => x ^ y,
                    }) as f64
                }
                BinOp::And => t(a != 0.0 && b != 0.0),
                BinOp::Or => t(a != 0.0 || b != 0.0),
                BinOp::Xor => t((a != 0.0) != (b != 0.0)),
            }
        }
    })
}

/// Numbered and named parameters with subroutine scoping: `#1`-`#30` and names without a
/// leading `_` are local to a call; `_names` are global.
#[derive(Clone, Debug)]
pub(crate) struct Params {
    pub numbered: Vec<f64>,
    /// The Fanuc extended common variables that were set (the rest are vacant): sparse,
    /// since 800,000 of them would be 6.4 MB per interpreter; at most that many entries.
    pub extended: HashMap<usize, f64>,
    pub globals: HashMap<String, f64>,
    /// One scope per active call level; index 0 is the main program.
    pub locals: Vec<HashMap<String, f64>>,
}

impl Params {
    pub fn new() -> Self {
        Params {
            numbered: vec![0.0; MAX_PARAM + 1],
            extended: HashMap::new(),
            globals: HashMap::new(),
            locals: vec![HashMap::new()],
        }
    }

    /// Fanuc: local (#1-#33) and common (#100-#199, #500-#999) variables start vacant, and #0
    /// is always vacant.
    pub fn init_fanuc(&mut self) {
        for r in [0..=33, 100..=199, 500..=999] {
            self.numbered[r].fill(vacant());
        }
    }

    /// A numbered parameter's value (an extended one never set is vacant).
    pub fn get(&self, n: usize) -> f64 {
        match self.numbered.get(n) {
            Some(&v) => v,
            None => self.extended.get(&n).copied().unwrap_or_else(vacant),
        }
    }

    pub fn set(&mut self, n: usize, v: f64) {
        match self.numbered.get_mut(n) {
            Some(x) => *x = v,
            None => {
                self.extended.insert(n, v);
            }
        }
    }

    pub fn get_named(&self, name: &str) -> Option<f64> {
        if name.starts_with('_') {
            self.globals.get(name).copied()
        } else {
            self.locals.last().and_then(|m| m.get(name).copied())
        }
    }

    pub fn set_named(&mut self, name: &str, v: f64) {
        if name.starts_with('_') {
            self.globals.insert(name.to_string(), v);
        } else if let Some(m) = self.locals.last_mut() {
            m.insert(name.to_string(), v);
        }
    }
}
