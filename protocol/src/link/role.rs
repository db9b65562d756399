//! Which end of a link this program is.

/// Which end of a link this program is. SocketCAN has no ends (every node is equal) and
/// ignores it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The controller or any client: opens an SLCAN adapter (`C`, `Sn`, `O`), sends ILD
    /// commands and reads the value stream.
    Host,
    /// The device end, as the emulator serves it: answers SLCAN's `O`/`C`/`Sn`/`V`/`N` like a
    /// CANable adapter, sends the ILD value stream and answers its commands like the sensor.
    Device,
}
