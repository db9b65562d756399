//! The ILD 2300's own RS422 interface.
//!
//! # Layout
//! - [`value`]: raw 18-bit values, distances in mm for a measuring range, error codes.
//! - [`stream`]: the 3-byte L/M/H value stream: encoder and resynchronising decoder.
//! - [`command`]: the ASCII command subset and its replies, host and device side.

pub mod command;
pub mod stream;
pub mod value;

pub use command::{
    AddValue, AddValueSet, IldCommand, IldCommandError, IldInfo, IldOutputInfo, IldReply,
    IldReplyParser, MeasuringRate,
};
pub use stream::{
    BaudShortfall, IldDecoder, IldStreamError, IldWord, check_baud, encode_cycle, encode_word,
};
pub use value::{IldError, IldValue, MeasuringRange};
