//! [`BlockForces`]: the force results of one block's steps aggregated, with a down-sampled
//! trace of [`TracePoint`]s for plotting.

use serde::{Deserialize, Serialize};

use super::stats::{AxisStats, ForceResult, MagnitudeStats};

/// One point of a block's down-sampled force trace: the steps it stands for and their
/// extremes, for plotting.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TracePoint {
    /// First step (0-based within the block) and number of steps merged into this point.
    pub first_step: usize,
    pub steps: usize,
    /// Largest peak |F| among them, N.
    pub peak_force: f64,
    /// Average of their mean |F|, N.
    pub mean_force: f64,
    /// Largest peak power, W.
    pub peak_power: f64,
}

/// Aggregates of the force results of one block's steps plus a down-sampled trace of at
/// most `capacity` points (adjacent points merge pairwise when it fills; extremes survive).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockForces {
    pub steps: usize,
    pub air_steps: usize,
    /// Part-frame X, Y, Z: mean over steps, extremes over all samples.
    pub part: [AxisStats; 3],
    pub force: MagnitudeStats,
    pub torque: MagnitudeStats,
    pub power: MagnitudeStats,
    pub max_chip_thickness: f64,
    pub trace: Vec<TracePoint>,
    capacity: usize,
    stride: usize,
    pending: Option<TracePoint>,
}

impl BlockForces {
    pub fn new(capacity: usize) -> BlockForces {
        BlockForces {
            steps: 0,
            air_steps: 0,
            part: [AxisStats {
                mean: 0.0,
                min: f64::INFINITY,
                max: f64::NEG_INFINITY,
            }; 3],
            force: MagnitudeStats::default(),
            torque: MagnitudeStats::default(),
            power: MagnitudeStats::default(),
            max_chip_thickness: 0.0,
            trace: Vec::new(),
            capacity: capacity.max(2),
            stride: 1,
            pending: None,
        }
    }

    /// Adds the next step (steps are taken as equally long).
    pub fn push(&mut self, r: &ForceResult) {
        let i = self.steps;
        self.steps += 1;
        if r.is_air() {
            self.air_steps += 1;
        }
        let w = 1.0 / self.steps as f64;
        let run = |m: &mut f64, x: f64| *m += (x - *m) * w;
        for c in 0..3 {
            let a = &mut self.part[c];
            run(&mut a.mean, r.part[c].mean);
            a.min = a.min.min(r.part[c].min);
            a.max = a.max.max(r.part[c].max);
        }
        run(&mut self.force.mean, r.force.mean);
        run(&mut self.torque.mean, r.torque.mean);
        run(&mut self.power.mean, r.power.mean);
        self.force.peak = self.force.peak.max(r.force.peak);
        self.torque.peak = self.torque.peak.max(r.torque.peak);
        self.power.peak = self.power.peak.max(r.power.peak);
        self.max_chip_thickness = self.max_chip_thickness.max(r.max_chip_thickness);
        let point = TracePoint {
            first_step: i,
            steps: 1,
            peak_force: r.force.peak,
            mean_force: r.force.mean,
            peak_power: r.power.peak,
        };
        let merged = match self.pending.take() {
            Some(p) => merge(p, point),
            None => point,
        };
        if merged.steps >= self.stride {
            self.trace.push(merged);
            if self.trace.len() >= self.capacity {
                self.trace = self
                    .trace
                    .chunks(2)
                    .map(|c| {
                        if c.len() == 2 {
                            merge(c[0], c[1])
                        } else {
                            c[0]
                        }
                    })
                    .collect();
                self.stride *= 2;
            }
        } else {
            self.pending = Some(merged);
        }
    }

    /// The trace including a partly filled last point.
    pub fn finish(mut self) -> BlockForces {
        if let Some(p) = self.pending.take() {
            self.trace.push(p);
        }
        if self.steps == 0 {
            self.part = [AxisStats::default(); 3];
        }
        self
    }
}

fn merge(a: TracePoint, b: TracePoint) -> TracePoint {
    let steps = a.steps + b.steps;
    TracePoint {
        first_step: a.first_step,
        steps,
        peak_force: a.peak_force.max(b.peak_force),
        mean_force: (a.mean_force * a.steps as f64 + b.mean_force * b.steps as f64) / steps as f64,
        peak_power: a.peak_power.max(b.peak_power),
    }
}
