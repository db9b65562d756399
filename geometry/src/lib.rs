#![warn(missing_docs)]
#![forbid(unsafe_code)]
//! Scanner geometry of the scanning triangulation sensor: from the fast steering mirror's
//! mechanical deflections to the laser beam in front of the sensor, and back from
//! (deflections, measured distance) to a surface point. Shared by the emulator's optics and
//! the controller's reconstruction, so both sides use the same numbers.
//!
//! # Conventions
//! Lengths in millimetres, angles in radians (except `alpha_deg` in the serde setup, which a
//! person types). Right-handed axes, origin at the sensor's reference point (the point the
//! ILD 2300 measures `z_meas` from, on its laser axis):
//! - the laser leaves the sensor along **-y** and meets the mirror `y_FSM` (+ the shift `dy`)
//!   away, at `z = 0`;
//! - at zero deflection the reflected beam goes straight down, along **-z**, so surface points
//!   have negative `z_s` (the paper's distances 60, 130, 158.8 mm are `|z_s|`);
//! - `d_alpha` tilts the mirror about x and moves the spot along y (positive `d_alpha`: spot
//!   towards -y); `d_beta` tilts it about the mirror's in-plane axis and moves the spot along x
//!   (positive `d_beta`: spot towards +x).
//!
//! Two models, selected by [`GeometryModel`]: the paper's small-angle eq. 1-3
//! ([`GeometryModel::SmallAngle`]) and the exact vector reflection on the tilted mirror plane
//! ([`GeometryModel::ExactReflection`]). Both give a [`BeamRay`] whose contract is
//! `z_meas = path_to_origin_mm + t` for the point `origin_mm + t * direction`.
//!
//! # Layout
//! - [`setup`]: the mechanical setup ([`ScannerSetup`]: `y_FSM`, `z_FSM`, `alpha`, receiver).
//! - [`small_angle`]: the paper's eq. 1-3, with the readings in `docs/paper-readings.md`.
//! - [`exact`]: the mirror plane and the exact reflection of the laser.
//! - [`receiver`]: the triangulation receiver's view of the spot, for shading.
//! - [`beam_ray`]: [`BeamRay`], the beam after the mirror for one deflection.
//! - [`scanner`]: [`Scanner`], the model behind one enum: beam rays and reconstruction.

pub mod beam_ray;
pub mod exact;
pub mod receiver;
pub mod scanner;
pub mod setup;
pub mod small_angle;

pub use beam_ray::BeamRay;
pub use nalgebra::{Point3, Vector3};
pub use receiver::ReceiverPath;
pub use scanner::{GeometryModel, Scanner};
pub use setup::{ScannerSetup, SetupError};
