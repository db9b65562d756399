#![warn(missing_docs)]
//! Holds nothing: the loop tests live in tests/.
