//! 3D reconstruction and imaging: from recorded samples to points, height maps and the
//! height of a feature, and the progressive image a scan builds over time.
//!
//! # Layout
//! - [`reconstruct`]: samples (mirror angles, distances) to 3D points, eq. 1-3 or exact.
//! - [`recording`]: recorded samples as CSV or JSON lines (the `scanhil reconstruct` input).
//! - [`ply`]: point clouds as PLY files (writer and reader).
//! - [`point`]: a point's x, y, z, read in place from `[f64; 3]` or a reconstructed point.
//! - [`grid`]: scattered points onto a regular height map (PNG and CSV output).
//! - [`fill`]: filling the missing cells of a height map (nearest, diffusion).
//! - [`ransac`]: the seeded RANSAC base-plane fit and heights above the plane.
//! - [`feature`]: the height of a feature above its base plane, with its spread.
//! - [`pipeline`]: the whole chain on one recording, and its files (PLY, PNG, CSV, SVG).
//! - [`progressive`]: the image after any part of a frame and its error against scan time.
//! - [`snapshots`]: the maps after fractions of the frame, drawn side by side (Fig. 6).
//! - [`profiles`]: sections along x and y through the feature, against the truth (Fig. 10).
//! - [`compare`]: two output folders' snapshots and profiles in one figure each.

pub mod compare;
pub mod feature;
pub mod fill;
pub mod grid;
pub mod pipeline;
pub mod ply;
pub mod point;
pub mod profiles;
pub mod progressive;
pub mod ransac;
pub mod reconstruct;
pub mod recording;
pub mod snapshots;
