//! The scanhil host.

pub mod continuous;
pub mod discretise;
pub mod imaging;
pub mod sos;
