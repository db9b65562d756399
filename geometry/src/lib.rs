//! Scanner geometry (being written).
