//! The plant emulator.
