//! Identification from a program run on a dynamometer: the program is simulated once,
//! every cutting step kept (its line, tool, conditions, engagement and time weight), and
//! each line's mean force per unit coefficient is the time-weighted mean of its steps'
//! part-frame mean forces evaluated with that coefficient alone. The mean forces are linear
//! in the coefficients for fixed engagements, so the measured line means fit them by
//! [`fit_unit_forces`], as steady test cuts do.
//!
//! A line's mean force is over the time the line cuts (the steps that meet material), as
//! the simulate rows' `fx_mean_n` are, in the part frame: forces on the tool along the
//! machine's X, Y, Z (a table dynamometer measures the reaction: negate it).

use std::collections::BTreeMap;

use rayon::prelude::*;

use super::forces::cutting_conditions;
use super::rows::{MoveRow, SimulationOutput};
use super::spec::{SimulateError, SimulateSpec};
use super::step_totals::KeptStep;
use crate::engagement::{Engagement, PackedEngagement};
use crate::job::{CancelFlag, Progress};
use crate::nc::Move;
use crate::physics::identify::unit_coefficients;
use crate::physics::{
    fit_unit_forces, CuttingConditions, ForceLaw, ForceModel, ForceResult, ModelIdentification,
    PhysicsError, UnitForces,
};

/// Most measured lines one identification takes.
pub const MAX_LINES: usize = 10_000;

/// A line's measured mean force: forces on the tool in the part frame, N.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineForce {
    /// The source line (1-based), as the simulate rows number them.
    pub line: u32,
    pub force: [f64; 3],
}

/// One cutting step (or a run of identical ones, their weights added).
struct CutStep {
    line: u32,
    tool: u32,
    conditions: CuttingConditions,
    engagement: Box<PackedEngagement>,
    /// Time at the programmed feed, min (machine length over the machine feed).
    weight: f64,
}

/// What the pipeline keeps for identification.
pub(super) struct KeptCuts {
    steps: Vec<CutStep>,
    models: BTreeMap<u32, ForceModel>,
}

impl KeptCuts {
    pub(super) fn new(
        kept: Vec<KeptStep>,
        moves: &[Move],
        rows: &[MoveRow],
        models: BTreeMap<u32, ForceModel>,
    ) -> KeptCuts {
        let mut steps: Vec<CutStep> = Vec::new();
        for k in kept {
            let (m, row) = (&moves[k.move_index], &rows[k.move_index]);
            let Some(engagement) = k.engagement else {
                continue;
            };
            let flutes = models[&k.tool].table().flutes() as f64;
            let feed = k.tip_ratio * row.feed_mm_min;
            let Some(conditions) = cutting_conditions(m, k.cuts, feed, flutes) else {
                continue;
            };
            if row.feed_mm_min <= 0.0 || k.machine_length <= 0.0 {
                continue;
            }
            let weight = k.machine_length / row.feed_mm_min;
            // Steady cutting on the grid repeats a step: one evaluation serves the run.
            if let Some(last) = steps.last_mut() {
                if last.line == m.line
                    && last.tool == k.tool
                    && last.conditions == conditions
                    && last.engagement == engagement
                {
                    last.weight += weight;
                    continue;
                }
            }
            steps.push(CutStep {
                line: m.line,
                tool: k.tool,
                conditions,
                engagement,
                weight,
            });
        }
        KeptCuts { steps, models }
    }
}

/// A simulated program ready to fit measured line forces.
pub struct ProgramCuts {
    /// The simulation as `simulate` gives it (rows, summary, stock).
    pub output: SimulationOutput,
    steps: Vec<CutStep>,
    models: BTreeMap<u32, ForceModel>,
}

/// Simulates `spec` (its material is not used for the fit: any one serves) keeping what
/// identification needs.
pub fn simulate_for_identification(
    spec: &SimulateSpec,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<ProgramCuts, SimulateError> {
    let (output, kept, _) = super::run(
        spec,
        super::DEFAULT_BATCH_STEPS,
        cancel,
        progress,
        true,
        None,
    )?;
    let kept = kept.expect("steps kept when asked");
    Ok(ProgramCuts {
        output,
        steps: kept.steps,
        models: kept.models,
    })
}

impl ProgramCuts {
    /// The lines that cut, in program order, each once.
    pub fn cutting_lines(&self) -> Vec<u32> {
        let mut lines: Vec<u32> = self.steps.iter().map(|s| s.line).collect();
        lines.sort_unstable();
        lines.dedup();
        lines
    }

    /// A line's time-weighted mean feed per tooth, mm (None: the line does not cut).
    pub fn feed_per_tooth(&self, line: u32) -> Option<f64> {
        let (mut sum, mut w) = (0.0, 0.0);
        for s in self.steps.iter().filter(|s| s.line == line) {
            sum += s.conditions.feed_per_tooth * s.weight;
            w += s.weight;
        }
        (w > 0.0).then(|| sum / w)
    }

    /// Identifies the coefficients of `law` from the measured mean forces of `lines`.
    /// A line that does not cut is refused, naming it (`lines[i]`).
    pub fn identify(
        &self,
        lines: &[LineForce],
        law: ForceLaw,
    ) -> Result<ModelIdentification, PhysicsError> {
        if lines.len() > MAX_LINES {
            return Err(PhysicsError::invalid(
                "lines",
                format!("at most {MAX_LINES} lines, got {}", lines.len()),
            ));
        }
        let mut groups: Vec<Vec<usize>> = Vec::with_capacity(lines.len());
        let mut feeds = Vec::with_capacity(lines.len());
        let mut by_line: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
        for (i, s) in self.steps.iter().enumerate() {
            by_line.entry(s.line).or_default().push(i);
        }
        for (i, l) in lines.iter().enumerate() {
            let Some(steps) = by_line.get(&l.line) else {
                return Err(PhysicsError::invalid(
                    format!("lines[{i}].line"),
                    format!(
                        "line {} does not cut material in the simulation: only cutting lines have a mean cutting force",
                        l.line
                    ),
                ));
            };
            groups.push(steps.clone());
            feeds.push(self.feed_per_tooth(l.line).expect("the line cuts"));
        }
        let measured: Vec<[f64; 3]> = lines.iter().map(|l| l.force).collect();
        let mut source = LineResponses {
            steps: &self.steps,
            models: &self.models,
            groups,
        };
        fit_unit_forces(&mut source, &measured, &feeds, law, "lines")
    }
}

struct LineResponses<'a> {
    steps: &'a [CutStep],
    models: &'a BTreeMap<u32, ForceModel>,
    groups: Vec<Vec<usize>>,
}

impl UnitForces for LineResponses<'_> {
    fn observations(&self) -> usize {
        self.groups.len()
    }

    fn column(&mut self, j: usize, exponent: f64) -> Result<Vec<[f64; 3]>, PhysicsError> {
        let k = unit_coefficients(j, exponent);
        // Each step's part-frame mean force, in parallel (each independent, results in
        // step order: the outcome does not depend on the thread count).
        let mut needed: Vec<usize> = self.groups.iter().flatten().copied().collect();
        needed.sort_unstable();
        needed.dedup();
        let evaluated: Vec<[f64; 3]> = needed
            .par_iter()
            .map_init(
                || {
                    (
                        self.models.clone(),
                        Engagement::default(),
                        ForceResult::default(),
                    )
                },
                |(models, scratch, out), &i| {
                    let s = &self.steps[i];
                    let model = models.get_mut(&s.tool).expect("a model per tool");
                    model.evaluate_into(s.engagement.view(scratch), &k, &s.conditions, out)?;
                    Ok([out.part[0].mean, out.part[1].mean, out.part[2].mean])
                },
            )
            .collect::<Result<_, PhysicsError>>()?;
        let mut means = vec![[0.0; 3]; self.steps.len()];
        for (&i, m) in needed.iter().zip(evaluated) {
            means[i] = m;
        }
        Ok(self
            .groups
            .iter()
            .map(|g| {
                let mut f = [0.0; 3];
                let mut w = 0.0;
                for &i in g {
                    let s = &self.steps[i];
                    for c in 0..3 {
                        f[c] += means[i][c] * s.weight;
                    }
                    w += s.weight;
                }
                f.map(|v| v / w)
            })
            .collect())
    }
}
