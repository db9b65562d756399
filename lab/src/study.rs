//! Studies: one scenario run many times with parameters varied (seeds, noise, distance,
//! controller, discretisation), as one table.
//!
//! A study file (`fixtures/studies/*.json`) names a base scenario and either a `grid` (every
//! combination of the listed values) or a `list` (one set of values per variant). A key
//! addresses a field of one of the scenario's documents by a dotted path:
//! `scenario.seed`, `scene.sensor.noise_rms_um`, `scene.surface.top_distance_mm`,
//! `controller.discretisation.method`, `rig.scanner.calibration.alpha_gain`. The path fields
//! `scenario.rig`, `scenario.scene`, `scenario.truth` and `scenario.controller` take file
//! paths, relative to the study file.
//!
//! Every variant is written out as files first ([`plan`]): `variants/NNNN/scenario.json`,
//! with its own `scene.json`, `controller.json` or `rig.json` beside it where the study
//! changes them, all paths absolute. The same files serve both ways of running:
//! - in this process, across every core ([`run`]), each variant's output folder written by
//!   the one-process loop;
//! - past one machine, by any batch system that runs `scanhil scan variants/NNNN/scenario.json
//!   --out variants/NNNN/result` (GNU parallel, a Slurm job array, a Kubernetes Job).
//!
//! Either way [`table`] collects the result folders' `report.json` into `study.csv` and
//! `study.json`.
//!
//! [`precision`] runs a study's variants `repeats` times each and sets each one's wall time
//! against its errors against the study's exact `reference` (`scanhil-study precision`).

pub mod plan;
pub mod precision;
pub mod run;
pub mod table;
