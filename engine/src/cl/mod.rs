//! APT/CLS cutter-location files (NX, CATIA) into the same [`Move`]s as G-code, in the part
//! frame, with tool-axis vectors.
//!
//! Records: `GOTO/x,y,z[,i,j,k]`, `RAPID`, `FEDRAT/[MMPM|IPM|MMPR|IPR,]f`, `LOADTL/n`,
//! `CUTTER/d[,r,...]`, `TLAXIS/i,j,k`, `CIRCLE/xc,yc,zc,i,j,k,r[,...]` (the next GOTO is the
//! arc's end), `SPINDL/[RPM,]s[,CLW|CCLW]`, `SPINDL/OFF`, `MULTAX[/ON|OFF]`, `UNITS/MM|INCHES`,
//! `DELAY/s`, `$` continuation, `$$` comments. Records that carry no motion (PPRINT, PAINT,
//! COOLNT, TLDATA, MSYS, ...) are accepted; any other record is an error naming its line.

use crate::nc::{
    ArcGeometry, Diagnostic, Diagnostics, FeedMode, Interpretation, Move, MoveKind, SpindleDir,
};

/// Records that do not move the tool or change what a move means.
const NO_MOTION: &[&str] = &[
    "PPRINT",
    "PAINT",
    "COOLNT",
    "TLDATA",
    "MSYS",
    "TOOL PATH",
    "END-OF-PATH",
    "FINI",
    "PARTNO",
    "MACHIN",
    "CLRSRF",
    "INSERT",
    "OPSKIP",
    "DISPLY",
    "TLON",
    "SELECT",
    "OPERATION",
    "OPNAME",
    "CUTCOM",
    "TOLER",
    "INTOL",
    "OUTTOL",
    "AUTOPS",
    "PLABEL",
    "CYCLE",
    "NCDATA",
    "TRANS",
    "LINTOL",
    "TPRINT",
    "OPSTOP",
    "STOP",
    "END",
    "CHECK",
    "PART",
    "COMMENT",
    "TITLE",
    "CATIA0",
    "ORIGIN",
];

struct Reader {
    moves: Vec<Move>,
    warnings: Vec<Diagnostic>,
    pos: [f64; 3],
    axis: [f64; 3],
    unit: f64,
    feed: f64,
    feed_mode: FeedMode,
    rapid_next: bool,
    /// CIRCLE record waiting for its end point: centre, axis, radius, line.
    circle_next: Option<([f64; 3], [f64; 3], f64, u32)>,
    spindle: f64,
    spindle_dir: SpindleDir,
    tool: u32,
}

/// Read a CLS file. All malformed records are reported.
pub fn read_cls(source: &str) -> Result<Interpretation, Diagnostics> {
    let mut r = Reader {
        moves: Vec::new(),
        warnings: Vec::new(),
        pos: [0.0; 3],
        axis: [0.0, 0.0, 1.0],
        unit: 1.0,
        feed: 0.0,
        feed_mode: FeedMode::PerMin,
        rapid_next: false,
        circle_next: None,
        spindle: 0.0,
        spindle_dir: SpindleDir::Off,
        tool: 0,
    };
    let mut errors = Vec::new();
    let lines: Vec<&str> = source.lines().collect();
    let mut i = 0;
    while i < lines.len() {
        let first = i;
        // Join `$` continuations (a single trailing `$`, not a `$$` comment).
        let mut text = strip_comment(lines[i]).trim_end().to_string();
        while text.ends_with('$') && i + 1 < lines.len() {
            text.pop();
            i += 1;
            text.push_str(strip_comment(lines[i]).trim());
        }
        i += 1;
        let line = first as u32 + 1;
        if text.trim().is_empty() {
            continue;
        }
        if let Err(msg) = r.record(text.trim(), first, line) {
            let col = lines[first].len() - lines[first].trim_start().len() + 1;
            errors.push(Diagnostic::new(line, col as u32, msg));
        }
    }
    if let Some((_, _, _, l)) = r.circle_next {
        errors.push(Diagnostic::new(
            l,
            1,
            "CIRCLE is not followed by a GOTO (its end point)",
        ));
    }
    if errors.is_empty() {
        Ok(Interpretation {
            moves: r.moves,
            warnings: r.warnings,
            block_count: lines.len(),
            selected_tools: Vec::new(),
            library_files: Vec::new(),
        })
    } else {
        Err(Diagnostics(errors))
    }
}

/// Text before a `$$` comment.
fn strip_comment(s: &str) -> &str {
    match s.find("$$") {
        Some(p) => &s[..p],
        None => s,
    }
}

fn numbers(args: &[&str], what: &str) -> Result<Vec<f64>, String> {
    args.iter()
        .map(|a| {
            a.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("{what}: '{}' is not a number", a.trim()))
        })
        .collect()
}

fn unit_vec(v: [f64; 3], what: &str) -> Result<[f64; 3], String> {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if !(n > 1e-9) {
        return Err(format!("{what}: zero vector"));
    }
    Ok([v[0] / n, v[1] / n, v[2] / n])
}

impl Reader {
    fn base(&self, kind: MoveKind, block: usize, line: u32, end: [f64; 3]) -> Move {
        let p6 = |p: [f64; 3]| [p[0], p[1], p[2], 0.0, 0.0, 0.0];
        Move {
            block,
            line,
            kind,
            end: p6(end),
            feed: self.feed,
            feed_mode: self.feed_mode,
            spindle: self.spindle,
            tool: self.tool,
            tool_tip: false,
            center: None,
            normal: None,
            clockwise: None,
            tool_length: None,
            seconds: None,
            tool_axis: Some(self.axis),
            start: p6(self.pos),
            spindle_dir: self.spindle_dir,
            arc: None,
            source: None,
        }
    }

    fn record(&mut self, text: &str, block: usize, line: u32) -> Result<(), String> {
        let (major, rest) = match text.find('/') {
            Some(p) => (text[..p].trim().to_ascii_uppercase(), Some(&text[p + 1..])),
            None => (text.trim().to_ascii_uppercase(), None),
        };
        let args: Vec<&str> = rest.map(|r| r.split(',').collect()).unwrap_or_default();
        let word = |k: usize| {
            args.get(k)
                .map(|s| s.trim().to_ascii_uppercase())
                .unwrap_or_default()
        };
        match major.as_str() {
            "GOTO" => {
                let v = numbers(&args, "GOTO")?;
                if v.len() != 3 && v.len() != 6 {
                    return Err(format!(
                        "GOTO needs x,y,z or x,y,z,i,j,k (got {} values)",
                        v.len()
                    ));
                }
                let p = [v[0] * self.unit, v[1] * self.unit, v[2] * self.unit];
                if v.len() == 6 {
                    self.axis = unit_vec([v[3], v[4], v[5]], "GOTO tool axis")?;
                }
                if let Some((c, n, radius, _)) = self.circle_next.take() {
                    self.arc(block, line, p, c, n, radius)?;
                } else {
                    let rapid = std::mem::take(&mut self.rapid_next);
                    if !rapid && self.feed <= 0.0 {
                        return Err("feed move before any FEDRAT".into());
                    }
                    let kind = if rapid {
                        MoveKind::Rapid
                    } else {
                        MoveKind::Linear
                    };
                    let m = self.base(kind, block, line, p);
                    self.moves.push(m);
                }
                self.pos = p;
            }
            "RAPID" => self.rapid_next = true,
            "FEDRAT" => {
                let mut feed = None;
                let mut mode = (FeedMode::PerMin, 1.0);
                for a in &args {
                    let a = a.trim().to_ascii_uppercase();
                    match a.as_str() {
                        "MMPM" => mode = (FeedMode::PerMin, 1.0),
                        "IPM" => mode = (FeedMode::PerMin, 25.4),
                        "MMPR" => mode = (FeedMode::PerRev, 1.0),
                        "IPR" => mode = (FeedMode::PerRev, 25.4),
                        _ => feed = Some(numbers(&[a.as_str()], "FEDRAT")?[0]),
                    }
                }
                let f = feed.ok_or("FEDRAT without a value")?;
                if f <= 0.0 {
                    return Err(format!("FEDRAT {f} is not positive"));
                }
                self.feed = f * mode.1;
                self.feed_mode = mode.0;
                self.rapid_next = false;
            }
            "LOADTL" => {
                let v = numbers(&args[..args.len().min(1)], "LOADTL")?;
                let t = *v.first().ok_or("LOADTL without a tool number")?;
                if t < 0.0 || t.fract() != 0.0 {
                    return Err(format!("LOADTL {t} is not a tool number"));
                }
                self.tool = t as u32;
                let m = self.base(MoveKind::ToolChange, block, line, self.pos);
                self.moves.push(m);
            }
            "CUTTER" => {
                let v = numbers(&args, "CUTTER")?;
                if v.first().map(|d| *d <= 0.0).unwrap_or(true) {
                    return Err("CUTTER needs a positive diameter".into());
                }
            }
            "TLAXIS" => {
                let v = numbers(&args, "TLAXIS")?;
                if v.len() < 3 {
                    return Err("TLAXIS needs i,j,k".into());
                }
                self.axis = unit_vec([v[0], v[1], v[2]], "TLAXIS")?;
            }
            "MULTAX" => {}
            "CIRCLE" => {
                let v = numbers(&args, "CIRCLE")?;
                if v.len() < 7 {
                    return Err("CIRCLE needs xc,yc,zc,i,j,k,r".into());
                }
                let c = [v[0] * self.unit, v[1] * self.unit, v[2] * self.unit];
                let n = unit_vec([v[3], v[4], v[5]], "CIRCLE axis")?;
                if v[6] <= 0.0 {
                    return Err("CIRCLE radius must be positive".into());
                }
                self.circle_next = Some((c, n, v[6] * self.unit, line));
            }
            "SPINDL" => {
                let w0 = word(0);
                if w0 == "OFF" {
                    self.spindle_dir = SpindleDir::Off;
                } else if w0 == "ON" {
                    if self.spindle_dir == SpindleDir::Off {
                        self.spindle_dir = SpindleDir::Cw;
                    }
                } else {
                    let mut dir = SpindleDir::Cw;
                    let mut speed = None;
                    for a in &args {
                        let a = a.trim().to_ascii_uppercase();
                        match a.as_str() {
                            "RPM" => {}
                            "CLW" => dir = SpindleDir::Cw,
                            "CCLW" => dir = SpindleDir::Ccw,
                            "SFM" | "SMM" => {
                                return Err(format!(
                                    "SPINDL/{a}: constant surface speed is not supported"
                                ))
                            }
                            _ => speed = Some(numbers(&[a.as_str()], "SPINDL")?[0]),
                        }
                    }
                    self.spindle = speed.ok_or("SPINDL without a speed")?;
                    self.spindle_dir = dir;
                }
            }
            "UNITS" => {
                self.unit = match word(0).as_str() {
                    "MM" => 1.0,
                    "INCHES" | "INCH" => 25.4,
                    w => return Err(format!("UNITS/{w}: expected MM or INCHES")),
                }
            }
            "DELAY" => {
                let v = numbers(&args[..args.len().min(1)], "DELAY")?;
                let s = *v.first().ok_or("DELAY without a time")?;
                let mut m = self.base(MoveKind::Dwell, block, line, self.pos);
                m.seconds = Some(s);
                self.moves.push(m);
            }
            m if NO_MOTION.contains(&m) || m.starts_with("TOOL PATH") => {}
            m => return Err(format!("unsupported CLS record {m}")),
        }
        Ok(())
    }

    /// Arc from the current point to `end` about centre `c`, counterclockwise about the axis
    /// `n` (APT convention). Only axis-aligned circles are supported.
    fn arc(
        &mut self,
        block: usize,
        line: u32,
        end: [f64; 3],
        c: [f64; 3],
        n: [f64; 3],
        radius: f64,
    ) -> Result<(), String> {
        if self.feed <= 0.0 {
            return Err("circular move before any FEDRAT".into());
        }
        let (k, sign) = (0..3)
            .find(|&k| (n[k].abs() - 1.0).abs() < 1e-9)
            .map(|k| (k, n[k].signum()))
            .ok_or("CIRCLE with an axis not parallel to X, Y or Z is not supported")?;
        let axes = match k {
            2 => [0, 1, 2],
            1 => [2, 0, 1],
            _ => [1, 2, 0],
        };
        let [a, b, _] = axes;
        let start = self.pos;
        let r1 = (start[a] - c[a]).hypot(start[b] - c[b]);
        let r2 = (end[a] - c[a]).hypot(end[b] - c[b]);
        let tol = 1e-3f64.max(radius * 1e-4);
        if (r1 - radius).abs() > tol || (r2 - radius).abs() > tol {
            return Err(format!("CIRCLE radius {radius} does not match its start ({r1:.4}) and end ({r2:.4}) points"));
        }
        let cw = sign < 0.0;
        let a0 = (start[b] - c[b]).atan2(start[a] - c[a]);
        let a1 = (end[b] - c[b]).atan2(end[a] - c[a]);
        let same = (end[a] - start[a]).abs() < 1e-9 && (end[b] - start[b]).abs() < 1e-9;
        let tau = std::f64::consts::TAU;
        let mut sweep = if same { 0.0 } else { a1 - a0 };
        if cw {
            if sweep >= 0.0 {
                sweep -= tau;
            }
        } else if sweep <= 0.0 {
            sweep += tau;
        }
        let mut center = c;
        center[k] = start[k];
        let normal = {
            let mut v = [0.0; 3];
            v[k] = 1.0;
            v
        };
        let mut m = self.base(MoveKind::Arc, block, line, end);
        m.center = Some(center);
        m.normal = Some(normal);
        m.clockwise = Some(cw);
        m.arc = Some(Box::new(ArcGeometry {
            start: m.start,
            end: m.end,
            center,
            normal,
            axes,
            sweep,
            start_radius: r1,
            end_radius: r2,
            clockwise: cw,
            turns: 1,
        }));
        self.moves.push(m);
        Ok(())
    }
}
