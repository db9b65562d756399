#![warn(missing_docs)]
//! The scanhil host: trajectories, PID and dual-tone control, controller analysis,
//! identification, the loop over real links, reconstruction and imaging.
//!
//! # Layout
//! Control (all f64, pure per-period steps, no clock):
//! - [`trajectory`]: Lissajous, raster, step, sine and swept-sine references (rad) and the
//!   frame rate and line spacing derived from their definition.
//! - [`continuous`]: continuous transfer functions as factors, grouped into second-order
//!   sections.
//! - [`discretise`]: per-section discretisation (Tustin, prewarped Tustin, zero-order hold,
//!   matched pole-zero, forward and backward Euler).
//! - [`sos`]: discrete sections, their cascade (direct form II transposed) and state space.
//! - [`eigen`]: eigenvalues (poles) of a state matrix, balanced first so extreme gains give
//!   their true poles.
//! - [`pid`]: Table II PID (series and parallel readings) with limit and anti-windup.
//! - [`dual_tone`]: eq. 5 with Table I, optionally with the tones moved onto the drive
//!   frequencies.
//! - [`plant_model`]: eq. 4, ZOH-discretised, with the one-period command delay.
//! - [`plant_source`]: a design's plant from a file: a scene's mirror, a controller's plant.
//! - [`loop_analysis`]: the nominal closed loop: poles, margins, bandwidth, T.
//! - [`design`]: controllers designed for a plant and a rate: the paper's alpha-tuned PID and
//!   a dual-tone rule (resonant tones on the equalised plant), checked against stated margins.
//! - [`steady_state`]: the steady-state tracking error the nominal loop predicts for a
//!   periodic reference.
//! - [`rig`]: the rig description: control rate, scanner geometry and calibration, sensor.
//! - [`power_budget`]: a trajectory's steady-state mean coil power from the plant model, the
//!   nominal loop and the rig's coils.
//! - [`settings`]: controller files, discretised and checked for stability on load.
//! - [`scan_controller`]: the per-period controller the loop calls (rad in, coil A out).
//! - [`link`]: the [`link::PlantLink`] trait and the in-process nominal plant.
//! - [`identify`]: stepped-sine and swept-sine frequency response with coherence.
//! - [`identify_recording`]: an identification's recording analysed again, without the device.
//! - [`fit`]: eq. 4 (and richer models, chosen by BIC) fitted to a measured response, with
//!   uncertainties, and the cross-talk.
//! - [`accuracy`]: tone placement and tracking error per discretisation method.
//!
//! The loop and imaging:
//! - [`run`]: the loop runner behind `scanhil scan`: scenarios, the links to both nodes,
//!   lockstep and real-time loops, pairing distances with angles, the output folder.
//! - [`imaging`]: reconstruction, recordings, PLY, gridding, filling, RANSAC, feature height,
//!   progressive imaging.
//! - [`decode`]: candump logs, SLCAN and ILD byte streams decoded into JSON lines
//!   (`scanhil decode`).

pub mod accuracy;
pub mod closed_loop_figures;
pub mod continuous;
pub mod decode;
pub mod design;
pub mod discretise;
pub mod dual_tone;
pub mod eigen;
pub mod fit;
pub mod identify;
pub mod identify_recording;
pub mod imaging;
pub mod link;
pub mod loop_analysis;
pub mod pid;
pub mod plant_model;
pub mod plant_source;
pub mod power_budget;
pub mod rig;
pub mod run;
pub mod scan_controller;
pub mod settings;
pub mod sos;
pub mod steady_state;
pub mod trajectory;
