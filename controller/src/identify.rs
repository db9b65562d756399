//! A system analyser in software: stepped-sine ([`SteppedSine`]) or swept-sine
//! ([`SweptSinePlan`]) excitation of a sensing axis through a [`PlantLink`], and the frequency
//! response with its coherence, of the open-loop plant (coil command to angle, in the paper's
//! units) or of the closed loop (reference to angle).
//!
//! At each frequency the sine is first run for `settle_s` so transients die out, then for
//! `blocks` blocks of `cycles_per_block` whole periods. The frequency is adjusted so a block
//! holds a whole number of samples (no leakage). Per block, the Fourier coefficients `U_i`,
//! `Y_i` at that frequency give the H1 estimate `H = sum(Y U*) / sum(|U|^2)` and the
//! coherence `gamma^2 = |sum(Y U*)|^2 / (sum(|U|^2) sum(|Y|^2))`: 1 for a noise-free linear
//! plant, below 1 with noise or distortion.
//!
//! A plan's analysis is an [`Analyser`] fed one period at a time (the excitation, the response
//! and the other axis), so the same code measures through a link ([`identify_plans`]) and
//! re-analyses a recording of an earlier identification
//! ([`crate::identify_recording`]).

use nalgebra::Complex;
use scanhil_protocol::plant_units::{
    AMPS_PER_INPUT_UNIT, RAD_PER_OUTPUT_UNIT, SensingPair, actuator_from_sensing,
};

use crate::link::{LinkError, PlantLink};
use crate::scan_controller::ScanController;
use crate::trajectory::{SensingAxis, swept_sine_phase};

/// The stepped-sine plan.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SteppedSine {
    /// The excited sensing axis.
    pub axis: SensingAxis,
    /// The requested frequencies, Hz (each is adjusted to a whole number of samples per block).
    pub frequencies_hz: Vec<f64>,
    /// Open loop: coil command amplitude in input units (A at 1 A/V); closed loop: reference
    /// amplitude in rad.
    pub amplitude: f64,
    /// Settling time before measuring at each frequency, s.
    pub settle_s: f64,
    /// Whole periods per block.
    pub cycles_per_block: u32,
    /// Blocks averaged per frequency (the coherence needs at least two).
    pub blocks: u32,
}

impl SteppedSine {
    /// `points` frequencies spaced logarithmically from `from_hz` to `to_hz`.
    #[must_use]
    pub fn log_frequencies(from_hz: f64, to_hz: f64, points: usize) -> Vec<f64> {
        if points < 2 {
            return vec![from_hz];
        }
        let ratio = (to_hz / from_hz).ln();
        (0..points)
            .map(|i| from_hz * (ratio * i as f64 / (points - 1) as f64).exp())
            .collect()
    }

    /// Each frequency's schedule at `period_s`.
    fn segments(&self, period_s: f64) -> Vec<Segment> {
        let cycles = f64::from(self.cycles_per_block);
        self.frequencies_hz
            .iter()
            .map(|&requested| {
                let block_len = ((cycles / (requested * period_s)).round() as usize).max(2);
                let f_hz = cycles / (block_len as f64 * period_s);
                Segment {
                    f_hz,
                    w: std::f64::consts::TAU * f_hz * period_s,
                    settle: (self.settle_s / period_s).round() as usize,
                    block_len,
                }
            })
            .collect()
    }
}

/// One stepped frequency: the sine of `w` rad per period, settled for `settle` periods, then
/// blocks of `block_len`.
#[derive(Debug, Clone, Copy)]
struct Segment {
    f_hz: f64,
    w: f64,
    settle: usize,
    block_len: usize,
}

/// A logarithmic swept-sine plan: `sweeps` repetitions, each a sweep from `start_hz` to
/// `stop_hz` over `sweep_s` followed by `quiet_s` of zero excitation, so the response has died
/// out before the next sweep and each repetition's record holds the whole response. Then
/// `Y(f) = H(f) U(f)` holds exactly for the records' Fourier transforms at any frequency, and
/// the repetitions give the coherence.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SweptSinePlan {
    /// The excited sensing axis.
    pub axis: SensingAxis,
    /// Sweep start frequency, Hz.
    pub start_hz: f64,
    /// Sweep stop frequency, Hz.
    pub stop_hz: f64,
    /// Duration of one sweep, s.
    pub sweep_s: f64,
    /// Zero excitation after each sweep, s (several decay times of the plant or loop).
    pub quiet_s: f64,
    /// Repetitions (the coherence needs at least two).
    pub sweeps: u32,
    /// Amplitude, as for [`SteppedSine::amplitude`].
    pub amplitude: f64,
    /// The frequencies at which the response is estimated, Hz (inside the sweep's band).
    pub frequencies_hz: Vec<f64>,
}

/// A plan of either excitation (`"excitation": "stepped"` or `"swept"` in a recording's
/// `identify.json`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "excitation", rename_all = "snake_case")]
pub enum Plan {
    /// One sine per frequency.
    Stepped(SteppedSine),
    /// Repeated logarithmic sweeps.
    Swept(SweptSinePlan),
}

impl Plan {
    /// The excited axis.
    #[must_use]
    pub fn axis(&self) -> SensingAxis {
        match self {
            Plan::Stepped(p) => p.axis,
            Plan::Swept(p) => p.axis,
        }
    }

    /// The blocks (or sweeps) each point averages.
    #[must_use]
    pub fn blocks(&self) -> u32 {
        match self {
            Plan::Stepped(p) => p.blocks,
            Plan::Swept(p) => p.sweeps,
        }
    }

    /// The same plan on another axis.
    #[must_use]
    pub fn on_axis(&self, axis: SensingAxis) -> Plan {
        let mut plan = self.clone();
        match &mut plan {
            Plan::Stepped(p) => p.axis = axis,
            Plan::Swept(p) => p.axis = axis,
        }
        plan
    }

    /// A fresh analysis of this plan at `period_s`.
    #[must_use]
    pub fn analyser(&self, period_s: f64) -> Analyser {
        let state = match self {
            Plan::Stepped(plan) => State::Stepped {
                segments: plan.segments(period_s),
                amplitude: plan.amplitude,
                blocks: plan.blocks as usize,
                segment: 0,
                n: 0,
                k: 0,
                block: Block::default(),
                sums: SpectralSums::default(),
            },
            Plan::Swept(plan) => {
                let sweep_len = (plan.sweep_s / period_s).round() as usize;
                let record_len = sweep_len + (plan.quiet_s / period_s).round() as usize;
                State::Swept {
                    plan: plan.clone(),
                    period_s,
                    sweep_len,
                    record: Vec::with_capacity(record_len),
                    record_len,
                    done: 0,
                    sums: plan
                        .frequencies_hz
                        .iter()
                        .map(|_| SpectralSums::default())
                        .collect(),
                }
            }
        };
        Analyser {
            state,
            points: Vec::new(),
        }
    }

    /// The periods the plan runs at `period_s`.
    #[must_use]
    pub fn periods(&self, period_s: f64) -> usize {
        match self {
            Plan::Stepped(plan) => plan
                .segments(period_s)
                .iter()
                .map(|s| s.settle + plan.blocks as usize * s.block_len)
                .sum(),
            Plan::Swept(plan) => {
                let record = ((plan.sweep_s / period_s).round() + (plan.quiet_s / period_s).round())
                    as usize;
                record * plan.sweeps as usize
            }
        }
    }
}

/// What is measured.
#[derive(Debug)]
pub enum Target {
    /// The plant: the excitation is the coil command on the axis, the response that axis'
    /// angle (both in the paper's units: output V per input V).
    OpenLoop,
    /// The closed loop with this controller: the excitation is the reference, the response
    /// the measured angle (T).
    ClosedLoop(Box<ScanController>),
}

/// One measured frequency.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ResponsePoint {
    /// The frequency actually used, Hz.
    pub f_hz: f64,
    /// |H|.
    pub magnitude: f64,
    /// |H| in dB.
    pub magnitude_db: f64,
    /// arg H, degrees in (-180, 180].
    pub phase_deg: f64,
    /// Coherence gamma^2 between excitation and response, 0..1.
    pub coherence: f64,
    /// H1 estimate of the other axis' response to this axis' excitation, dB (cross-talk).
    pub cross_axis_db: f64,
    /// Its phase, degrees.
    pub cross_axis_phase_deg: f64,
    /// The coherence between the excitation and the other axis' response.
    pub cross_axis_coherence: f64,
    /// Samples in each averaged block (or sweep record).
    pub samples_per_block: usize,
    /// The rms over the blocks of the excitation's Fourier coefficient at this frequency
    /// (`amplitude x samples / 2` for a stepped sine): what a reading's resolution is
    /// measured against.
    pub excitation_dft: f64,
}

impl ResponsePoint {
    /// The response as a complex number.
    #[must_use]
    pub fn response(&self) -> Complex<f64> {
        Complex::from_polar(self.magnitude, self.phase_deg.to_radians())
    }

    /// The other axis' response as a complex number.
    #[must_use]
    pub fn cross_response(&self) -> Complex<f64> {
        Complex::from_polar(
            10f64.powf(self.cross_axis_db / 20.0),
            self.cross_axis_phase_deg.to_radians(),
        )
    }
}

/// Drives the sensing axes through the link, one period per call, in either target mode.
struct Exciter<'a> {
    link: &'a mut dyn PlantLink,
    target: &'a mut Target,
    measured: SensingPair,
}

impl Exciter<'_> {
    /// Applies `excitation` to `axis` for one period; returns this period's measured response
    /// on the excited and on the other axis (paper output units open loop, rad closed loop).
    fn period(&mut self, axis: SensingAxis, excitation: f64) -> Result<(f64, f64), LinkError> {
        let measured = self.measured;
        let (command, scale) = match self.target {
            Target::OpenLoop => (
                actuator_from_sensing(axis.pair(excitation * AMPS_PER_INPUT_UNIT)),
                1.0 / RAD_PER_OUTPUT_UNIT,
            ),
            Target::ClosedLoop(controller) => {
                (controller.step(axis.pair(excitation), measured), 1.0)
            }
        };
        self.measured = self.link.exchange(command)?;
        Ok((axis.of(measured) * scale, axis.other().of(measured) * scale))
    }
}

/// Sums of cross and auto spectra over blocks, at one frequency.
#[derive(Debug, Default)]
struct SpectralSums {
    syu: Complex<f64>,
    sxu: Complex<f64>,
    suu: f64,
    syy: f64,
    sxx: f64,
    blocks: usize,
}

impl SpectralSums {
    /// Adds one block's Fourier coefficients of excitation, response and other axis.
    fn add(&mut self, u: Complex<f64>, y: Complex<f64>, x: Complex<f64>) {
        self.syu += y * u.conj();
        self.sxu += x * u.conj();
        self.suu += u.norm_sqr();
        self.syy += y.norm_sqr();
        self.sxx += x.norm_sqr();
        self.blocks += 1;
    }

    fn point(&self, f_hz: f64, samples_per_block: usize) -> ResponsePoint {
        let h = self.syu / self.suu;
        let cross = self.sxu / self.suu;
        ResponsePoint {
            f_hz,
            magnitude: h.norm(),
            magnitude_db: 20.0 * h.norm().log10(),
            phase_deg: h.arg().to_degrees(),
            coherence: self.syu.norm_sqr() / (self.suu * self.syy),
            cross_axis_db: 20.0 * cross.norm().log10(),
            cross_axis_phase_deg: cross.arg().to_degrees(),
            cross_axis_coherence: self.sxu.norm_sqr() / (self.suu * self.sxx),
            samples_per_block,
            excitation_dft: (self.suu / self.blocks.max(1) as f64).sqrt(),
        }
    }
}

/// One block's Fourier coefficients so far.
#[derive(Debug, Clone, Copy, Default)]
struct Block {
    u: Complex<f64>,
    y: Complex<f64>,
    x: Complex<f64>,
}

/// Where an analysis is.
#[derive(Debug)]
enum State {
    Stepped {
        segments: Vec<Segment>,
        amplitude: f64,
        blocks: usize,
        /// The frequency being measured.
        segment: usize,
        /// Periods into it.
        n: usize,
        /// Periods since the plan began (the sines' phase runs on).
        k: usize,
        block: Block,
        sums: SpectralSums,
    },
    Swept {
        plan: SweptSinePlan,
        period_s: f64,
        sweep_len: usize,
        /// This sweep's (excitation, response, other axis) so far.
        record: Vec<(f64, f64, f64)>,
        record_len: usize,
        /// Sweeps done.
        done: u32,
        sums: Vec<SpectralSums>,
    },
}

/// One plan's analysis, fed one period at a time in the order the plan runs.
#[derive(Debug)]
pub struct Analyser {
    state: State,
    points: Vec<ResponsePoint>,
}

impl Analyser {
    /// The excitation of the next period (`None`: the plan is done).
    #[must_use]
    pub fn excitation(&self) -> Option<f64> {
        match &self.state {
            State::Stepped {
                segments,
                amplitude,
                segment,
                k,
                ..
            } => segments
                .get(*segment)
                .map(|s| amplitude * (s.w * *k as f64).sin()),
            State::Swept {
                plan,
                period_s,
                sweep_len,
                record,
                done,
                ..
            } => (*done < plan.sweeps).then(|| {
                let k = record.len();
                if k < *sweep_len {
                    let t_s = k as f64 * period_s;
                    plan.amplitude
                        * swept_sine_phase(plan.start_hz, plan.stop_hz, plan.sweep_s, t_s).sin()
                } else {
                    0.0
                }
            }),
        }
    }

    /// Takes the next period: the excitation applied, the excited axis' response and the
    /// other axis'.
    pub fn push(&mut self, excitation: f64, response: f64, other: f64) {
        match &mut self.state {
            State::Stepped {
                segments,
                blocks,
                segment,
                n,
                k,
                block,
                sums,
                ..
            } => {
                let Some(s) = segments.get(*segment).copied() else {
                    return;
                };
                if *n >= s.settle {
                    let basis = Complex::from_polar(1.0, -s.w * *k as f64);
                    block.u += basis * excitation;
                    block.y += basis * response;
                    block.x += basis * other;
                    if (*n - s.settle + 1) % s.block_len == 0 {
                        sums.add(block.u, block.y, block.x);
                        *block = Block::default();
                    }
                }
                *n += 1;
                *k += 1;
                if *n == s.settle + *blocks * s.block_len {
                    self.points.push(sums.point(s.f_hz, s.block_len));
                    *sums = SpectralSums::default();
                    *segment += 1;
                    *n = 0;
                }
            }
            State::Swept {
                plan,
                period_s,
                record,
                record_len,
                done,
                sums,
                ..
            } => {
                if *done >= plan.sweeps {
                    return;
                }
                record.push((excitation, response, other));
                if record.len() == *record_len {
                    for (sum, &f_hz) in sums.iter_mut().zip(&plan.frequencies_hz) {
                        let w = std::f64::consts::TAU * f_hz * *period_s;
                        sum.add(
                            dft_at(record.iter().map(|r| r.0), w),
                            dft_at(record.iter().map(|r| r.1), w),
                            dft_at(record.iter().map(|r| r.2), w),
                        );
                    }
                    record.clear();
                    *done += 1;
                    if *done == plan.sweeps {
                        self.points = sums
                            .iter()
                            .zip(&plan.frequencies_hz)
                            .map(|(s, &f)| s.point(f, *record_len))
                            .collect();
                    }
                }
            }
        }
    }

    /// The measured points (complete once [`Self::excitation`] is `None`).
    #[must_use]
    pub fn finish(self) -> Vec<ResponsePoint> {
        self.points
    }
}

/// Runs `plans` one after the other through `link` (the plant is not rested between them:
/// each plan's settling takes the previous one's motion) and returns each plan's points.
///
/// # Errors
/// The link's first failure.
pub fn identify_plans(
    link: &mut dyn PlantLink,
    plans: &[Plan],
    target: &mut Target,
) -> Result<Vec<Vec<ResponsePoint>>, LinkError> {
    let period_s = link.period_s();
    let mut exciter = Exciter {
        link,
        target,
        measured: SensingPair::default(),
    };
    let mut out = Vec::with_capacity(plans.len());
    for plan in plans {
        let mut analyser = plan.analyser(period_s);
        while let Some(excitation) = analyser.excitation() {
            let (response, other) = exciter.period(plan.axis(), excitation)?;
            analyser.push(excitation, response, other);
        }
        out.push(analyser.finish());
    }
    Ok(out)
}

/// Runs the stepped-sine plan through `link` and returns one point per frequency.
///
/// # Errors
/// The link's first failure.
pub fn identify(
    link: &mut dyn PlantLink,
    plan: &SteppedSine,
    target: &mut Target,
) -> Result<Vec<ResponsePoint>, LinkError> {
    let mut points = identify_plans(link, &[Plan::Stepped(plan.clone())], target)?;
    Ok(points.remove(0))
}

/// Runs the swept-sine plan through `link` and returns one point per analysis frequency.
///
/// # Errors
/// The link's first failure.
pub fn identify_swept(
    link: &mut dyn PlantLink,
    plan: &SweptSinePlan,
    target: &mut Target,
) -> Result<Vec<ResponsePoint>, LinkError> {
    let mut points = identify_plans(link, &[Plan::Swept(plan.clone())], target)?;
    Ok(points.remove(0))
}

/// The Fourier transform of `samples` at `w` rad per sample.
fn dft_at(samples: impl Iterator<Item = f64>, w: f64) -> Complex<f64> {
    samples
        .enumerate()
        .map(|(k, v)| Complex::from_polar(v, -w * k as f64))
        .sum()
}
