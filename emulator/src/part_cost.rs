//! What each active part of a scene costs per control period, measured in process once, before
//! a run: "leave out what a scene does not need", with the price of each part shown.
//!
//! A part's cost is its marginal cost: the plant's time per period with the part and the
//! parts before it, minus the time without it. The parts are added one at a time in
//! dependency order (a part after the part it needs: `sensor_noise` after `sensor`), each
//! plant built from the scene with only those parts, and every plant is stepped through the
//! same open-loop drive (the paper's Lissajous currents at half range, [`crate::precision`])
//! for [`CostTiming::periods`] periods, [`CostTiming::repetitions`] times, interleaved, the
//! fastest repetition kept. Costs below the timing's resolution come out as 0 (a difference
//! of two noisy times is never reported negative). Nothing of this touches the plant that
//! runs: its state and random streams are its own.
//!
//! A new part is costed by this without more code: add it to [`Part`] (with what it
//! requires) and build it in [`Plant::from_scene`].

use std::time::Instant;

use serde::Serialize;

use scanhil_protocol::plant_units::ActuatorPair;

use crate::plant::{Plant, PlantError};
use crate::precision::lissajous_drive_a;
use crate::scene::{Part, Scene};

/// How long the cost of each part is timed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CostTiming {
    /// Control periods stepped per timing.
    pub periods: usize,
    /// Timings of each plant; the fastest is kept.
    pub repetitions: usize,
}

impl Default for CostTiming {
    /// 400 periods (20 ms of plant at 20 kHz), 5 repetitions: tens of milliseconds for the
    /// Duplo scene, less than one for the mirror alone.
    fn default() -> Self {
        CostTiming {
            periods: 400,
            repetitions: 5,
        }
    }
}

/// One active part and its measured cost.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartCost {
    /// The part.
    pub part: Part,
    /// Its marginal wall time per control period, in microseconds (0 below the resolution).
    pub us_per_period: f64,
}

/// The active parts of a scene with their costs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartCosts {
    /// The active parts in dependency order, each with its cost.
    pub parts: Vec<PartCost>,
    /// The whole plant's wall time per control period, in microseconds.
    pub plant_us_per_period: f64,
    /// The plant's time per period with no part at all (the step's own bookkeeping), in
    /// microseconds.
    pub bare_us_per_period: f64,
    /// Periods stepped per timing.
    pub periods_timed: usize,
}

impl PartCosts {
    /// `name cost` pairs for a line of text: `axes 0.08 us, cross_talk 0.01 us`.
    #[must_use]
    pub fn describe(&self) -> String {
        if self.parts.is_empty() {
            return "none".into();
        }
        self.parts
            .iter()
            .map(|p| format!("{} {:.3} us", p.part, p.us_per_period))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// The active parts of `scene` in dependency order: each after the part it requires.
#[must_use]
pub fn dependency_order(scene: &Scene) -> Vec<Part> {
    fn place(part: Part, order: &mut Vec<Part>) {
        if order.contains(&part) {
            return;
        }
        if let Some(needed) = part.requires() {
            place(needed, order);
        }
        order.push(part);
    }
    let mut order = Vec::new();
    for part in scene.active_parts() {
        place(part, &mut order);
    }
    order
}

/// Measures the cost of each active part of `scene` (see the module doc).
///
/// # Errors
/// A plant of the scene with some of its parts that cannot be built (it is built with all of
/// them first, so this is the full scene's own error).
pub fn measure(scene: &Scene, timing: CostTiming) -> Result<PartCosts, PlantError> {
    let order = dependency_order(scene);
    let mut plants = Vec::with_capacity(order.len() + 1);
    for count in 0..=order.len() {
        let mut partial = scene.clone();
        partial.parts = order[..count].to_vec();
        plants.push(Plant::from_scene(&partial)?);
    }
    let drive: Vec<ActuatorPair> =
        lissajous_drive_a(&scene.mirror, scene.period_s(), timing.periods.max(1))
            .into_iter()
            .map(|[a, b]| ActuatorPair {
                a: 0.5 * a,
                b: 0.5 * b,
            })
            .collect();
    let mut best_s = vec![f64::INFINITY; plants.len()];
    for _ in 0..timing.repetitions.max(1) {
        for (plant, best) in plants.iter().zip(&mut best_s) {
            *best = best.min(time_steps(plant.clone(), &drive));
        }
    }
    let per_period_us = |s: f64| s / drive.len() as f64 * 1e6;
    let parts = order
        .iter()
        .zip(best_s.windows(2))
        .map(|(&part, pair)| PartCost {
            part,
            us_per_period: per_period_us((pair[1] - pair[0]).max(0.0)),
        })
        .collect();
    Ok(PartCosts {
        parts,
        plant_us_per_period: per_period_us(best_s[best_s.len() - 1]),
        bare_us_per_period: per_period_us(best_s[0]),
        periods_timed: drive.len(),
    })
}

/// The wall time of stepping `plant` through `drive`, in s.
fn time_steps(mut plant: Plant, drive: &[ActuatorPair]) -> f64 {
    let start = Instant::now();
    for &command in drive {
        // The drive is finite, so a step cannot fail.
        std::hint::black_box(plant.step(command).ok());
    }
    start.elapsed().as_secs_f64()
}
