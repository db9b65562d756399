#![forbid(unsafe_code)]
//! scanhil wire format.
