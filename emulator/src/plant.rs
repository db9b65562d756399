//! The composed plant: one pure, seeded, deterministic step per control period, built from
//! the scene's active parts only.
//!
//! # Timing convention
//! Period k covers `[k Ta, (k+1) Ta)`, `Ta = 1 / control_rate_hz`. [`Plant::step`] with the
//! command `u_k`:
//! 1. integrates the dynamics over period k with the command of the previous step, `u_{k-1}`
//!    (zero for k = 0), held constant: this is eq. 4's `e^(-s Ta)`, exactly one period;
//! 2. latches `u_k`, which acts over period k+1;
//! 3. returns the angles sampled at `t = (k+1) Ta`, the end of period k (in the lockstep
//!    protocol, AngleReading(k); the controller uses it to compute `u_{k+1}`).
//!
//! So, as a map from the command sequence `u[k]` to the measurement sequence
//! `y[k] = angle(k Ta)`, the plant with only the `axes` part is exactly
//! `z^-1 * ZOH(K ws^2 / (s^2 + 2 zeta ws s + ws^2))`. The `amplifier` part adds its 10 kHz current
//! loop lag, `cross_talk` the coupling. The current limit and the power limit act on `u_{k-1}`
//! when it is applied (step 1). The triangulation sensor's samples whose instants fall in
//! `(k Ta, (k+1) Ta]` are returned by step k, with the mirror angles interpolated linearly
//! across the period.

use serde::Serialize;

use scanhil_protocol::plant_units::{ActuatorPair, RAD_PER_OUTPUT_UNIT, SensingPair};

use crate::amplifier::AmplifierConfig;
use crate::angle_sensor::{AngleSensor, Nonlinearity};
use crate::drive_model::{DriveModel, DriveParts};
use crate::drive_stepper::DriveStepper;
use crate::integrator::StabilityError;
use crate::latency::OutputLatency;
use crate::mirror::SensingAxis;
use crate::optics::Optics;
use crate::power::{PowerAction, PowerMonitor};
use crate::scene::{OpticalPathError, Part, Scene};
use crate::sensor::{Ild2300, IldSample, SensorError};
use scanhil_scene::surface::Surface;

/// Why the plant could not be built or stepped.
#[derive(Debug, thiserror::Error)]
pub enum PlantError {
    /// The scene's integrator and step are unstable on its plant.
    #[error("scene {scene}: {cause}")]
    Unstable {
        /// The scene's name.
        scene: String,
        /// The stability check's finding (in the message; not chained as a source).
        cause: StabilityError,
    },
    /// The scene's surface or optics could not be built (e.g. a height map file is unreadable).
    #[error("scene {scene}: {cause}")]
    OpticalPath {
        /// The scene's name.
        scene: String,
        /// What went wrong.
        cause: OpticalPathError,
    },
    /// The scene's sensor section is unusable.
    #[error("scene {scene}: sensor: {cause}")]
    Sensor {
        /// The scene's name.
        scene: String,
        /// What went wrong.
        cause: SensorError,
    },
    /// A coil current command was NaN or infinite; the plant state is unchanged.
    #[error("period {period_index}: coil current command is not finite (a = {a_a} A, b = {b_a} A)")]
    NonFiniteCommand {
        /// The period the command was given for.
        period_index: u64,
        /// The command on coil axis a, in A.
        a_a: f64,
        /// The command on coil axis b, in A.
        b_a: f64,
    },
}

/// Something a limit did in a period.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum PlantEvent {
    /// The amplifier clamped the command to its current limit.
    CurrentLimited {
        /// The command before the limit, in A.
        requested_a: ActuatorPair,
        /// The command after it, in A.
        limited_a: ActuatorPair,
    },
    /// The power limit scaled the currents down (`on_exceed: clamp`).
    PowerClamped {
        /// The power the currents would have dissipated this period, in W.
        requested_w: f64,
        /// The power allowed, in W.
        allowed_w: f64,
    },
    /// The power limit latched a fault (`on_exceed: fault`); currents are zero from now on.
    PowerFault {
        /// The window mean the currents would have reached, in W.
        mean_w: f64,
    },
    /// An amplifier's output stood at its supply's voltage limit in this period (part
    /// `current_loop`): the coil current lagged its command by more than the loop's own lag.
    VoltageLimited {
        /// Coil pair a saturated.
        a: bool,
        /// Coil pair b saturated.
        b: bool,
    },
}

/// What one control period produced.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlantStep {
    /// k.
    pub period_index: u64,
    /// `(k+1) Ta`: when the angles were sampled, in s.
    pub t_end_s: f64,
    /// The angle sensor's output, in rad: the true angles, delayed on an axis whose
    /// `mirror.delay_s` exceeds one period, with the `angle_sensor_noise` part's imperfections.
    pub measured_angles_rad: SensingPair,
    /// The mechanical angles, in rad.
    pub true_angles_rad: SensingPair,
    /// The coil current commands that acted during period k (delayed, limited), in A.
    pub applied_currents_a: ActuatorPair,
    /// `I^2 R` of this period over both coil axes, in W.
    pub coil_power_w: f64,
    /// The mean power over the thermal window (only with `power_limit`), in W.
    pub mean_power_w: Option<f64>,
    /// What the limits did.
    pub events: Vec<PlantEvent>,
    /// Whether a power fault holds the currents at zero.
    pub faulted: bool,
    /// The triangulation sensor's samples whose instants fall in `(k Ta, (k+1) Ta]` (only with
    /// the `sensor` part).
    #[serde(serialize_with = "serialize_samples")]
    pub sensor_samples: Vec<IldSample>,
}

/// Writes ILD samples as JSON objects (`t_s`, `counter`, `value`, `true_distance_mm`).
fn serialize_samples<S: serde::Serializer>(
    samples: &[IldSample],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct SampleJson {
        t_s: f64,
        counter: u32,
        value: scanhil_protocol::ild::IldValue,
        true_distance_mm: Option<f64>,
    }
    serializer.collect_seq(samples.iter().map(|s| SampleJson {
        t_s: s.t_s,
        counter: s.counter,
        value: s.value,
        true_distance_mm: s.true_distance_mm,
    }))
}

/// The optical path and, optionally, the triangulation sensor behind it.
#[derive(Debug, Clone)]
struct OpticalChain {
    optics: Optics,
    sensor: Option<Ild2300>,
}

impl OpticalChain {
    /// Builds the chain if the scene lists `optics` (validation made sure a surface is there).
    fn from_scene(scene: &Scene) -> Result<Option<OpticalChain>, PlantError> {
        if !scene.has(Part::Optics) {
            return Ok(None);
        }
        let name = || scene.name.clone();
        let optics = scene
            .optical_path()
            .map_err(|cause| PlantError::OpticalPath {
                scene: name(),
                cause,
            })?;
        let sensor = scene
            .has(Part::Sensor)
            .then(|| scene.triangulation_sensor())
            .transpose()
            .map_err(|cause| PlantError::Sensor {
                scene: name(),
                cause,
            })?;
        Ok(Some(OpticalChain { optics, sensor }))
    }

    /// The sensor's samples in `(start_s, end_s]`, with the mirror angles interpolated
    /// linearly between their values at the two ends.
    fn samples(
        &mut self,
        start_s: f64,
        end_s: f64,
        start_rad: SensingPair,
        end_rad: SensingPair,
    ) -> Vec<IldSample> {
        let Some(sensor) = &mut self.sensor else {
            return Vec::new();
        };
        let instants: Vec<_> = sensor.sample_instants(start_s, end_s).collect();
        // Linear in the period; an exposure reaching back before its start goes on the same
        // line (the angles of the period before are not kept).
        let angles_at = |t_s: f64| {
            let f = (t_s - start_s) / (end_s - start_s);
            SensingPair {
                alpha: start_rad.alpha + f * (end_rad.alpha - start_rad.alpha),
                beta: start_rad.beta + f * (end_rad.beta - start_rad.beta),
            }
        };
        instants
            .into_iter()
            .map(|instant| {
                let outcome = if sensor.exposure_s() > 0.0 {
                    Ild2300::exposed(
                        sensor
                            .exposure_instants(instant.t_s)
                            .map(|t_s| self.optics.observe(angles_at(t_s)).outcome),
                    )
                } else {
                    self.optics.observe(angles_at(instant.t_s)).outcome
                };
                sensor.measure(instant, &outcome)
            })
            .collect()
    }
}

/// The plant.
#[derive(Debug, Clone)]
pub struct Plant {
    scene_name: String,
    period_s: f64,
    active_parts: Vec<Part>,
    model: DriveModel,
    stepper: Option<DriveStepper>,
    state: Vec<f64>,
    /// Each axis's delay beyond one period, on its measured angle (`[alpha, beta]`).
    latencies: [Option<OutputLatency>; 2],
    /// The state at the start of the period being stepped (only kept for the latencies).
    start_state: Vec<f64>,
    fixed_angles_rad: SensingPair,
    amplifier: Option<AmplifierConfig>,
    power: Option<PowerMonitor>,
    resistance_ohm: f64,
    nonlinearity: Option<Nonlinearity>,
    angle_sensor: Option<AngleSensor>,
    optical: Option<OpticalChain>,
    pending_a: ActuatorPair,
    period_index: u64,
}

impl Plant {
    /// Builds the listed parts of `scene` (nothing else) and checks the integrators'
    /// stability (every model the current loop's voltage limit can switch to included).
    pub fn from_scene(scene: &Scene) -> Result<Plant, PlantError> {
        let period_s = scene.period_s();
        let resistance_ohm = scene.coil_resistance_ohm();
        let model = DriveModel::build(&DriveParts::of_scene(scene));
        let stepper = if model.states() > 0 {
            let stepper =
                DriveStepper::new(&model, period_s, scene.integrator).map_err(|cause| {
                    PlantError::Unstable {
                        scene: scene.name.clone(),
                        cause,
                    }
                })?;
            Some(stepper)
        } else {
            None
        };
        let init = scene.mirror.initial_angles_rad;
        let state = model.initial_state([init.alpha, init.beta]);
        let mut latencies = [None, None];
        for ((latency, row), axis) in latencies
            .iter_mut()
            .zip(&model.measured_rows)
            .zip(SensingAxis::BOTH)
        {
            let extra_s = scene.mirror.axis(axis).extra_delay_s(period_s);
            if let Some(row) = row
                && extra_s > period_s * 1e-9
            {
                let initial = row.value(&state, [0.0, 0.0, 1.0]);
                *latency = Some(OutputLatency::new(&model, row, extra_s, period_s, initial));
            }
        }
        let amplifier = scene.has(Part::Amplifier).then(|| scene.amplifier.clone());
        Ok(Plant {
            scene_name: scene.name.clone(),
            period_s,
            active_parts: scene.active_parts(),
            start_state: state.clone(),
            state,
            latencies,
            model,
            stepper,
            fixed_angles_rad: init,
            amplifier,
            power: scene
                .has(Part::PowerLimit)
                .then(|| PowerMonitor::new(&scene.power_limit, resistance_ohm, period_s)),
            resistance_ohm,
            nonlinearity: scene
                .has(Part::AngleSensorNonlinearity)
                .then(|| Nonlinearity::new(scene.angle_sensor.nonlinearity_percent)),
            angle_sensor: scene
                .has(Part::AngleSensorNoise)
                .then(|| AngleSensor::new(&scene.angle_sensor, scene.seed)),
            optical: OpticalChain::from_scene(scene)?,
            pending_a: ActuatorPair::default(),
            period_index: 0,
        })
    }

    /// The scene's name.
    #[must_use]
    pub fn scene_name(&self) -> &str {
        &self.scene_name
    }

    /// The control period Ta, in s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Periods stepped so far.
    #[must_use]
    pub fn period_index(&self) -> u64 {
        self.period_index
    }

    /// The parts that are built and stepped, in canonical order.
    #[must_use]
    pub fn active_parts(&self) -> &[Part] {
        &self.active_parts
    }

    /// The coil resistance per actuator axis in use, in ohm.
    #[must_use]
    pub fn coil_resistance_ohm(&self) -> f64 {
        self.resistance_ohm
    }

    /// The integrator in use as `(method, sub-steps)`, if anything is integrated.
    #[must_use]
    pub fn integrator(&self) -> Option<(crate::integrator::Method, u32)> {
        self.stepper
            .as_ref()
            .map(|s| (s.linear().method(), s.linear().substeps()))
    }

    /// The mechanical angles now (at `period_index * Ta`), in rad.
    #[must_use]
    pub fn true_angles_rad(&self) -> SensingPair {
        let angle = |axis: SensingAxis| {
            self.model
                .angle_rad(&self.state, axis)
                .unwrap_or_else(|| axis.of(self.fixed_angles_rad))
        };
        SensingPair {
            alpha: angle(SensingAxis::Alpha),
            beta: angle(SensingAxis::Beta),
        }
    }

    /// The true surface (ground truth for scoring a scan), when the `optics` part is active.
    #[must_use]
    pub fn surface(&self) -> Option<&Surface> {
        self.optical.as_ref().map(|chain| chain.optics.surface())
    }

    /// The optical path, when the `optics` part is active.
    #[must_use]
    pub fn optics(&self) -> Option<&Optics> {
        self.optical.as_ref().map(|chain| &chain.optics)
    }

    /// The triangulation sensor, when the `sensor` part is active.
    #[must_use]
    pub fn sensor(&self) -> Option<&Ild2300> {
        self.optical
            .as_ref()
            .and_then(|chain| chain.sensor.as_ref())
    }

    /// Clears a latched power fault.
    pub fn reset_fault(&mut self) {
        if let Some(power) = &mut self.power {
            power.reset_fault();
        }
    }

    /// What the angle sensor sees at the end of a period stepped with `commands`: the measured
    /// outputs of the drive model (the second mode, the pickup, the sensor's bandwidth), each
    /// delayed by its axis's latency; an axis that does not move reports its fixed angle.
    fn reported_angles_rad(&mut self, commands: [f64; 2]) -> SensingPair {
        let u = [commands[0], commands[1], 1.0];
        let mut reported = self.fixed_angles_rad;
        let [alpha, beta] = &mut self.latencies;
        for ((row, latency), value) in self
            .model
            .measured_rows
            .iter()
            .zip([alpha, beta])
            .zip([&mut reported.alpha, &mut reported.beta])
        {
            let Some(row) = row else { continue };
            let units = match latency {
                Some(latency) => latency.step(&self.start_state, u, &self.state),
                None => row.value(&self.state, u),
            };
            *value = units * RAD_PER_OUTPUT_UNIT;
        }
        reported
    }

    /// Advances one control period with the command `coil_currents_a` (see the module doc for
    /// when it acts). A NaN or infinite command is refused and changes nothing.
    pub fn step(&mut self, coil_currents_a: ActuatorPair) -> Result<PlantStep, PlantError> {
        if !(coil_currents_a.a.is_finite() && coil_currents_a.b.is_finite()) {
            return Err(PlantError::NonFiniteCommand {
                period_index: self.period_index,
                a_a: coil_currents_a.a,
                b_a: coil_currents_a.b,
            });
        }
        let mut events = Vec::new();
        let mut applied = std::mem::replace(&mut self.pending_a, coil_currents_a);
        if let Some(amp) = &self.amplifier {
            let (limited, clamped) = amp.limit(applied);
            if clamped {
                events.push(PlantEvent::CurrentLimited {
                    requested_a: applied,
                    limited_a: limited,
                });
            }
            applied = limited;
        }
        let mut mean_power_w = None;
        let mut faulted = false;
        if let Some(power) = &mut self.power {
            let (admitted, action) = power.admit(applied);
            match action {
                PowerAction::Pass | PowerAction::HeldByFault => {}
                PowerAction::Clamped {
                    requested_w,
                    allowed_w,
                } => events.push(PlantEvent::PowerClamped {
                    requested_w,
                    allowed_w,
                }),
                PowerAction::Faulted { mean_w } => events.push(PlantEvent::PowerFault { mean_w }),
            }
            applied = admitted;
            mean_power_w = Some(power.mean_w());
            faulted = power.faulted();
        }
        let start_rad = self.true_angles_rad();
        let delayed = self.latencies.iter().any(Option::is_some);
        if delayed {
            self.start_state.copy_from_slice(&self.state);
        }
        let commands = [applied.a, applied.b];
        if let Some(stepper) = &mut self.stepper {
            let [a, b] = stepper.step(&mut self.state, commands);
            if a || b {
                events.push(PlantEvent::VoltageLimited { a, b });
            }
        }
        let true_angles_rad = self.true_angles_rad();
        let reported_rad = self.reported_angles_rad(commands);
        let start_s = self.period_index as f64 * self.period_s;
        let end_s = (self.period_index + 1) as f64 * self.period_s;
        let sensor_samples = match &mut self.optical {
            Some(chain) => chain.samples(start_s, end_s, start_rad, true_angles_rad),
            None => Vec::new(),
        };
        let reported_rad = match &self.nonlinearity {
            Some(nonlinearity) => nonlinearity.apply(reported_rad),
            None => reported_rad,
        };
        let measured_angles_rad = match &mut self.angle_sensor {
            Some(sensor) => sensor.measure(reported_rad),
            None => reported_rad,
        };
        let period_index = self.period_index;
        self.period_index += 1;
        Ok(PlantStep {
            period_index,
            t_end_s: end_s,
            measured_angles_rad,
            true_angles_rad,
            applied_currents_a: applied,
            coil_power_w: self.resistance_ohm * (applied.a * applied.a + applied.b * applied.b),
            mean_power_w,
            events,
            faulted,
            sensor_samples,
        })
    }
}
