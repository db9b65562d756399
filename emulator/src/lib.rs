#![warn(missing_docs)]
//! The plant emulator: fast steering mirror, coil drive, optics, ILD 2300 sensor, scenes.
//!
//! A [`scene::Scene`] file lists the parts in play; [`plant::Plant::from_scene`] builds only
//! those and [`plant::Plant::step`] advances one control period (pure, seeded, deterministic;
//! the timing convention is in the [`plant`] module doc).
//!
//! # Layout
//! - [`scene`]: scene files and their parts list.
//! - [`plant`]: the composed per-period step and its timing convention.
//! - surfaces (what is in front of the sensor, with its ground truth) live in `scanhil-scene`,
//!   shared with the host.
//! - [`optics`]: from mirror angles to the laser spot on the surface, with shading and, as a
//!   scene option, a second bounce ([`optics::multipath`]).
//! - [`sensor`]: the ILD 2300-100 triangulation sensor on its own clock.
//! - [`sensor_faults`]: the sensor losing its peak (laser off, out of range, occlusion).
//! - [`mirror`]: eq. 4 per sensing axis, its parameters set per axis.
//! - [`mode_limits`]: the ranges a mechanical mode's frequency, damping and gain may take.
//! - [`latency`]: an axis's delay beyond one control period, on its measured angle.
//! - [`amplifier`], [`cross_talk`], [`power`], [`angle_sensor`]: the drive and the angle
//!   sensor.
//! - [`second_mode`], [`current_loop`]: the mirror's second mode; the amplifiers' current
//!   loop with the coil, back-EMF and voltage limit.
//! - [`drive_model`]: the composed linear dynamics of the active parts.
//! - [`drive_stepper`]: steps them over a period, switching to the saturated amplifier's model.
//! - [`part_cost`]: what each active part costs per control period, measured before a run.
//! - [`integrator`]: exact ZOH, RK4, trapezoid, Euler, and the stability check.
//! - [`precision`]: the integrators' error against run time (work-precision study).
//! - [`serve`]: the mirror and sensor nodes on real links (lockstep and real time).

pub mod amplifier;
pub mod angle_sensor;
pub mod cross_talk;
pub mod current_loop;
pub mod drive_model;
pub mod drive_stepper;
pub mod integrator;
pub mod latency;
pub mod mirror;
pub mod mode_limits;
pub mod optics;
pub mod part_cost;
pub mod plant;
pub mod power;
pub mod precision;
pub mod scene;
pub mod second_mode;
pub mod sensor;
pub mod sensor_faults;
pub mod serve;
