//! Parameters and expressions: numbered and named parameters, the system parameters that
//! mirror the live state, evaluation and assignment.

use super::modal::{Motion, Plane};
use super::{Interp, R};
use crate::nc::expr::{self, Env};
use crate::nc::program::{Assignment, Expr, ParamRef};
use crate::nc::{FeedMode, SpindleDir};

/// Read-only view used while evaluating expressions.
pub(super) struct EnvView<'a> {
    pub(super) it: &'a Interp<'a>,
}

impl Env for EnvView<'_> {
    fn numbered(&self, n: usize) -> Result<f64, String> {
        Ok(self.it.read_numbered(n))
    }
    fn named(&self, name: &str) -> Result<f64, String> {
        if let Some(v) = self.it.read_special(name) {
            return Ok(v);
        }
        self.it
            .params
            .get_named(name)
            .ok_or_else(|| format!("named parameter #<{name}> is not defined"))
    }
    fn exists(&self, name: &str) -> bool {
        self.it.read_special(name).is_some() || self.it.params.get_named(name).is_some()
    }
    fn fanuc(&self) -> bool {
        self.it.fanuc
    }
}

impl Interp<'_> {
    // ----- parameters -----

    pub(super) fn offset_param(&self, v: f64, linear: bool) -> f64 {
        if linear {
            v / self.unit()
        } else {
            v
        }
    }

    /// Numbered parameters; the 5xxx system parameters reflect the live state.
    pub(super) fn read_numbered(&self, n: usize) -> f64 {
        if self.fanuc && (4001..=5046).contains(&n) {
            if let Some(v) = self.fanuc_system(n) {
                return v;
            }
        }
        let axis = |base: usize| -> Option<usize> {
            if n > base && n <= base + 6 {
                Some(n - base - 1)
            } else {
                None
            }
        };
        if let Some(i) = axis(5160) {
            return self.offset_param(self.coords.g28[i], i < 3);
        }
        if let Some(i) = axis(5180) {
            return self.offset_param(self.coords.g30[i], i < 3);
        }
        if n == 5210 {
            return if self.coords.g92_applied && self.coords.g92.iter().any(|&v| v != 0.0) {
                1.0
            } else {
                0.0
            };
        }
        if let Some(i) = axis(5210) {
            return self.offset_param(self.coords.g92[i], i < 3);
        }
        if n == 5220 {
            return (self.modal.cs + 1) as f64;
        }
        if (5221..=5400).contains(&n) {
            let k = (n - 5221) / 20;
            let i = (n - 5221) % 20;
            if k < 9 && i < 6 {
                return self.offset_param(self.coords.g5x[k][i], i < 3);
            }
            if k < 9 && i == 9 {
                return self.coords.rot_xy[k];
            }
        }
        if n == 5400 {
            return self.tool.current as f64;
        }
        if n == 5403 {
            return self.tool.tlo.unwrap_or(0.0) / self.unit();
        }
        // #5420-#5428: the current position, X first (#5420 is X, not an offset count).
        if let Some(i) = axis(5419) {
            return self.cur[i];
        }
        self.params.get(n)
    }

    /// Fanuc system variables that reflect the live state: modal information (#4001-#4120)
    /// and positions (#5001-#5006 block end, #5021-#5026 machine, #5041-#5046 current), in
    /// program units. None: an ordinary variable.
    fn fanuc_system(&self, n: usize) -> Option<f64> {
        let m = &self.modal;
        let b = |c: bool, yes: f64, no: f64| if c { yes } else { no };
        Some(match n {
            4001 => match self.motion.mode {
                None => 80.0,
                Some(Motion::Rapid) => 0.0,
                Some(Motion::Linear) => 1.0,
                Some(Motion::Arc { cw: true }) => 2.0,
                Some(Motion::Arc { cw: false }) => 3.0,
                Some(Motion::RigidTap) => 84.0,
                Some(Motion::Probe(g)) => f64::from(g) / 10.0,
                Some(Motion::Cycle(g)) => f64::from(g),
                Some(Motion::Spline { cubic: true }) => 5.0,
                Some(Motion::Spline { cubic: false }) => 5.1,
                Some(Motion::Nurbs) => 5.2,
            },
            4002 => match m.plane {
                Plane::XY => 17.0,
                Plane::XZ => 18.0,
                Plane::YZ => 19.0,
            },
            4003 => b(m.absolute, 90.0, 91.0),
            4005 => match m.feed_mode {
                FeedMode::InverseTime => 93.0,
                FeedMode::PerMin => 94.0,
                FeedMode::PerRev => 95.0,
            },
            4006 => b(m.metric, 21.0, 20.0),
            4008 => b(self.tool.tlo.is_some(), 43.0, 49.0),
            4010 => b(m.retract_r_plane, 99.0, 98.0),
            4014 => [54.0, 55.0, 56.0, 57.0, 58.0, 59.0, 59.1, 59.2, 59.3]
                .get(m.cs)
                .copied()
                .unwrap_or(54.1),
            // The P number of G54.1 / G154 (0 in G54..G59).
            4130 => m.cs.saturating_sub(8) as f64,
            4109 => m.feed_word,
            4119 => m.speed,
            4120 => f64::from(self.tool.current),
            5001..=5006 | 5041..=5046 => self.cur[(n - 1) % 20],
            5021..=5026 => {
                let i = n - 5021;
                let machine = self.to_machine(self.cur)[i];
                self.offset_param(machine, i < 3)
            }
            _ => return None,
        })
    }

    pub(super) fn read_special(&self, name: &str) -> Option<f64> {
        let b = |c: bool| if c { 1.0 } else { 0.0 };
        Some(match name {
            "_x" => self.cur[0],
            "_y" => self.cur[1],
            "_z" => self.cur[2],
            "_a" => self.cur[3],
            "_b" => self.cur[4],
            "_c" => self.cur[5],
            "_metric" => b(self.modal.metric),
            "_imperial" => b(!self.modal.metric),
            "_absolute" => b(self.modal.absolute),
            "_incremental" => b(!self.modal.absolute),
            "_inverse_time" => b(self.modal.feed_mode == FeedMode::InverseTime),
            "_units_per_minute" => b(self.modal.feed_mode == FeedMode::PerMin),
            "_units_per_rev" => b(self.modal.feed_mode == FeedMode::PerRev),
            "_feed" => self.modal.feed_word,
            "_rpm" => self.modal.speed,
            "_current_tool" => self.tool.current as f64,
            "_selected_tool" => self.tool.selected.map(|t| t as f64).unwrap_or(-1.0),
            "_coord_system" => [
                540.0, 550.0, 560.0, 570.0, 580.0, 590.0, 591.0, 592.0, 593.0,
            ][self.modal.cs],
            "_line" => self.cur_line as f64,
            "_spindle_on" => b(self.modal.spindle != SpindleDir::Off),
            "_spindle_cw_dir" => b(self.modal.spindle == SpindleDir::Cw),
            "_retract_r_plane" => b(self.modal.retract_r_plane),
            "_retract_old_z" => b(!self.modal.retract_r_plane),
            "_plane" => match self.modal.plane {
                Plane::XY => 170.0,
                Plane::XZ => 180.0,
                Plane::YZ => 190.0,
            },
            "_motion_mode" => match self.motion.mode {
                None => 800.0,
                Some(Motion::Rapid) => 0.0,
                Some(Motion::Linear) => 10.0,
                Some(Motion::Arc { cw: true }) => 20.0,
                Some(Motion::Arc { cw: false }) => 30.0,
                Some(Motion::RigidTap) => 331.0,
                Some(Motion::Probe(g)) => f64::from(g),
                Some(Motion::Cycle(g)) => g as f64 * 10.0,
                Some(Motion::Spline { cubic: true }) => 50.0,
                Some(Motion::Spline { cubic: false }) => 51.0,
                Some(Motion::Nurbs) => 52.0,
            },
            _ => return None,
        })
    }

    pub(super) fn eval(&self, e: &Expr, pos: usize) -> R<f64> {
        let env = EnvView { it: self };
        expr::eval(e, &env).map_err(|m| self.err_at(pos, m))
    }

    pub(super) fn assign(&mut self, a: &Assignment, v: f64) -> R<()> {
        if a.bare && !self.fanuc {
            return Err(self.err_at(
                a.span.start,
                "expression without brackets is Fanuc macro B syntax; write [..] around it with dialect linuxcnc",
            ));
        }
        match &a.target {
            ParamRef::Named(n) => {
                if self.read_special(n).is_some() {
                    return Err(self.err_at(a.span.start, format!("#<{n}> is read-only")));
                }
                self.params.set_named(n, v);
            }
            ParamRef::Numbered(e) => {
                let env = EnvView { it: self };
                let n = expr::resolve_index(e, &env).map_err(|m| self.err_at(a.span.start, m))?;
                if self.fanuc {
                    self.fanuc_system_write(a, n, v)?;
                }
                if (5161..=5166).contains(&n)
                    || (5181..=5186).contains(&n)
                    || (5210..=5400).contains(&n)
                    || n == 5403
                    || (5420..=5425).contains(&n)
                {
                    return Err(self.err_at(
                        a.span.start,
                        format!("parameter #{n} holds machine state (offsets, home positions, tool) and cannot be assigned here; use G10/G92/G28.1"),
                    ));
                }
                self.params.set(n, v);
            }
        }
        Ok(())
    }

    /// Fanuc variables that cannot hold a value: #0 (always vacant), #3000 (alarm: stops the
    /// program with its message), #4001-#4120 and the positions (read only).
    fn fanuc_system_write(&mut self, a: &Assignment, n: usize, v: f64) -> R<()> {
        let at = a.span.start;
        match n {
            0 => Err(self.err_at(at, "#0 is always vacant (null) and cannot be set")),
            3000 => {
                let message = self.block_comment();
                Err(self.err_at(
                    at,
                    format!(
                        "macro alarm #3000={}{message}: the program stops here",
                        expr::num_text(v)
                    ),
                ))
            }
            3006 => {
                let message = self.block_comment();
                self.out.warnings.push(self.err_at(
                    at,
                    format!("#3006 program stop{message}: simulated as going on"),
                ));
                Ok(())
            }
            4001..=4120 | 5001..=5006 | 5021..=5026 | 5041..=5046 => Err(self.err_at(
                at,
                format!("Fanuc system variable #{n} (modal state or position) is read only"),
            )),
            _ => Ok(()),
        }
    }

    /// The first comment of the current block, as ` (text)`, or nothing.
    fn block_comment(&self) -> String {
        let b = self.prog.block(self.cur_block);
        let text = self.prog.text(b.span);
        match (text.find('('), text.rfind(')')) {
            (Some(s), Some(e)) if e > s => format!(" ({})", &text[s + 1..e]),
            _ => String::new(),
        }
    }
}
