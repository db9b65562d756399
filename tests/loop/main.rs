//! Loop tests: `scanhil` and `scanhil-emulator` as separate processes over pty pairs.

mod util;

// The emulator's watchdog: a controller that goes quiet gets its coil currents zeroed and a
// LinkTimeout fault frame.
mod emulator_watchdog;
