//! Before a run on a link with a real bit rate (`socketcan:can0@1000000`,
//! `slcan:/dev/ttyACM0@1M`): the bus load the configured loop puts on it, and a refusal with
//! the numbers when it cannot fit. A pty or a `vcan` without `@BITRATE` has no bit rate and is
//! not checked.
//!
//! Frames per control period on the mirror's link: CoilCommand and Step (lockstep) or
//! CoilCommand and Sync (real time) and the AngleReading; Distance frames at the sensor's
//! measuring rate when the sensor shares the link; Status frames at the heartbeat rate (10 Hz).
//! Each is a classical frame with an 11-bit id and 8 data bytes, counted at its worst-case
//! length with bit stuffing.

use scanhil_emulator::scene::Scene;
use scanhil_protocol::link::LinkUri;

use super::scenario::{NodeLink, Scenario};

/// Status frames per second of loop time.
const HEARTBEAT_HZ: f64 = 10.0;
/// Data bytes of every loop frame.
const LOOP_FRAME_BYTES: u32 = 8;

/// Worst-case bits on the wire of a classical data frame with an 11-bit id and `data_bytes`
/// bytes: 44 + 8n bits of frame up to the CRC, of which 34 + 8n are stuffed (at most one
/// stuff bit per 4 after the first), plus the unstuffed CRC delimiter, ACK, EOF and the 3-bit
/// interframe space.
#[must_use]
pub fn classical_frame_bits(data_bytes: u32) -> u32 {
    let stuffed_region = 34 + 8 * data_bytes;
    let stuff_bits = (stuffed_region - 1) / 4;
    44 + 8 * data_bytes + stuff_bits + 3
}

/// The loop's load on a CAN bus.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BusLoad {
    /// Frames per second.
    pub frames_per_s: f64,
    /// Bits per second at worst-case stuffing.
    pub bits_per_s: f64,
    /// The bus's bit rate.
    pub bitrate: u32,
    /// `bits_per_s / bitrate`.
    pub load: f64,
}

/// The load of a loop at `control_rate_hz` with `distance_rate_hz` Distance frames per
/// second on the same bus.
#[must_use]
pub fn loop_load(control_rate_hz: f64, distance_rate_hz: f64, bitrate: u32) -> BusLoad {
    let frames_per_s = 3.0 * control_rate_hz + distance_rate_hz + HEARTBEAT_HZ;
    let bits_per_s = frames_per_s * f64::from(classical_frame_bits(LOOP_FRAME_BYTES));
    BusLoad {
        frames_per_s,
        bits_per_s,
        bitrate,
        load: bits_per_s / f64::from(bitrate),
    }
}

/// The refusal.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "the loop does not fit on {link}: {frames:.0} frames/s x {bits} bits (worst-case \
     stuffing) = {needed:.0} bit/s, but the bus carries {bitrate} bit/s (load {percent:.0} %). \
     Lower the control rate (at most {max_rate:.0} Hz here), use CAN FD, or a link without a \
     bit rate limit"
)]
pub struct BusOverload {
    /// The link.
    pub link: String,
    /// Frames per second asked for.
    pub frames: f64,
    /// Bits per frame.
    pub bits: u32,
    /// Bit/s needed.
    pub needed: f64,
    /// The bus's bit rate.
    pub bitrate: u32,
    /// Load in percent.
    pub percent: f64,
    /// The highest control rate that fits, Hz.
    pub max_rate: f64,
}

/// Checks the scenario's mirror link, if it names a bit rate.
///
/// # Errors
/// [`BusOverload`] with the numbers; a link URI that does not parse.
pub fn check(scenario: &Scenario, scene: &Scene, period_s: f64) -> anyhow::Result<Option<BusLoad>> {
    let NodeLink::Uri(uri) = &scenario.links.fsm else {
        return Ok(None);
    };
    let parsed: LinkUri = uri.parse()?;
    let Some(bitrate) = parsed.bus_bitrate() else {
        return Ok(None);
    };
    let sensor_on_bus = matches!(&scenario.links.sensor, NodeLink::Uri(s) if s == "fsm");
    let distance_rate_hz = if sensor_on_bus {
        scene.sensor.clone().unwrap_or_default().measuring_rate_hz
    } else {
        0.0
    };
    let control_rate_hz = 1.0 / period_s;
    let load = loop_load(control_rate_hz, distance_rate_hz, bitrate);
    if load.load > 1.0 {
        let bits = classical_frame_bits(LOOP_FRAME_BYTES);
        let per_control_period = 3.0 + distance_rate_hz / control_rate_hz;
        let max_rate = (f64::from(bitrate) / f64::from(bits) - HEARTBEAT_HZ) / per_control_period;
        return Err(BusOverload {
            link: uri.clone(),
            frames: load.frames_per_s,
            bits,
            needed: load.bits_per_s,
            bitrate,
            percent: 100.0 * load.load,
            max_rate,
        }
        .into());
    }
    Ok(Some(load))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_eight_byte_frame_is_at_most_135_bits() {
        assert_eq!(classical_frame_bits(8), 135);
        assert_eq!(classical_frame_bits(0), 55);
    }

    #[test]
    fn a_20_khz_loop_does_not_fit_on_one_megabit_but_2_khz_does() {
        assert!(loop_load(20_000.0, 0.0, 1_000_000).load > 1.0);
        let slow = loop_load(2_000.0, 0.0, 1_000_000);
        assert!(slow.load < 1.0, "{slow:?}");
        assert!((slow.frames_per_s - 6_010.0).abs() < 1e-9);
    }
}
