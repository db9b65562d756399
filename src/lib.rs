//! Holds nothing: the loop tests live in tests/.
