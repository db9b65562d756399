//! The ILD 2300's own RS422 interface.
//!
//! # Layout
//! - [`value`]: raw 18-bit values, distances in mm for a measuring range, error codes.

pub mod value;

pub use value::{IldError, IldValue, MeasuringRange};
