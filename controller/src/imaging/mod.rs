//! 3D reconstruction and imaging: from recorded samples to points, height maps and the
//! height of a feature, and the progressive image a scan builds over time.
//!
//! # Layout
//! - [`reconstruct`]: samples (mirror angles, distances) to 3D points, eq. 1-3 or exact.
//! - [`recording`]: recorded samples as CSV or JSON lines (the `scanhil reconstruct` input).
//! - [`ply`]: point clouds as PLY files (writer and reader).
//! - [`grid`]: scattered points onto a regular height map (PNG and CSV output).
//! - [`fill`]: filling the missing cells of a height map (nearest, diffusion).
//! - [`ransac`]: the seeded RANSAC base-plane fit and heights above the plane.
//! - [`feature`]: the height of a feature above its base plane, with its spread.
//! - [`pipeline`]: the whole chain on one recording, and its files (PLY, PNG, CSV, JSON).
//! - [`progressive`]: the image after any part of a frame and its error against scan time.

pub mod feature;
pub mod fill;
pub mod grid;
pub mod pipeline;
pub mod ply;
pub mod progressive;
pub mod ransac;
pub mod reconstruct;
pub mod recording;
