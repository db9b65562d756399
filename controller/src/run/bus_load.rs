//! Before a run on a link with a real bit rate (`socketcan:can0@1000000`,
//! `slcan:/dev/ttyACM0@1M`): the bus load the configured loop puts on it (the protocol's
//! worst-case frame lengths), a warning above 70 %, and a refusal with the numbers above
//! 100 %. A pty, or a `vcan0` without `@BITRATE`, has no bit rate and is not checked.
//!
//! The loop's traffic on the mirror's link: CoilCommand, AngleReading and Step (lockstep) or
//! Sync (real time) at the control rate; Distance at the sensor's measuring rate when the
//! sensor shares the link; StatusFsm at the heartbeat rate.

use scanhil_protocol::bus_load::{Bitrates, BusLoad, LoadLimits, Traffic};
use scanhil_protocol::link::LinkUri;
use scanhil_protocol::message::ids;
use scanhil_protocol::message::spec::message_spec;

use super::scenario::{NodeLink, Scenario, TimingMode};

/// Status frames per second of loop time (the emulator's default heartbeat).
pub const HEARTBEAT_HZ: f64 = 10.0;

/// A loop that does not fit its bus.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "refusing to run: the loop does not fit on {link}: {overload}; at most {max_rate_hz:.0} Hz \
     control rate fits at this bit rate (or use CAN FD, or a link without a bit rate limit)"
)]
pub struct LoopDoesNotFit {
    /// The link.
    pub link: String,
    /// The protocol's numbers.
    pub overload: scanhil_protocol::bus_load::BusOverload,
    /// The highest control rate that fits, Hz.
    pub max_rate_hz: f64,
}

/// The loop's traffic at `control_rate_hz` with `distance_rate_hz` Distance frames/s.
#[must_use]
pub fn loop_traffic(mode: TimingMode, control_rate_hz: f64, distance_rate_hz: f64) -> Vec<Traffic> {
    let clock = match mode {
        TimingMode::Lockstep => ids::STEP,
        TimingMode::Realtime => ids::SYNC,
    };
    let mut traffic: Vec<Traffic> = [ids::COIL_COMMAND, clock, ids::ANGLE_READING]
        .into_iter()
        .filter_map(message_spec)
        .map(|spec| Traffic::message(spec, control_rate_hz))
        .collect();
    if distance_rate_hz > 0.0 {
        traffic.extend(message_spec(ids::DISTANCE).map(|s| Traffic::message(s, distance_rate_hz)));
    }
    traffic.extend(message_spec(ids::STATUS_FSM).map(|s| Traffic::message(s, HEARTBEAT_HZ)));
    traffic
}

/// The highest control rate whose loop traffic (`mode`, with `distance_rate_hz` Distance
/// frames/s on the same bus) fits `rates` at the refusal limit ([`LoadLimits::DEFAULT`]),
/// Hz: the load is linear in the rates, so the control-rate part is scaled to what the fixed
/// part leaves. On a classical 1 Mbit/s bus in lockstep without the sensor: 2736 Hz.
#[must_use]
pub fn max_control_rate_hz(mode: TimingMode, rates: Bitrates, distance_rate_hz: f64) -> f64 {
    let fixed = BusLoad::of(&loop_traffic(mode, 0.0, distance_rate_hz), rates).load;
    let per_hz = BusLoad::of(&loop_traffic(mode, 1.0, distance_rate_hz), rates).load - fixed;
    ((LoadLimits::DEFAULT.refuse - fixed) / per_hz).max(0.0)
}

/// Checks the scenario's mirror link if it names a bit rate. Returns the load (and prints a
/// warning above 70 %).
///
/// # Errors
/// [`LoopDoesNotFit`] with the numbers; a link URI that does not parse.
pub fn check(
    scenario: &Scenario,
    sensor_rate_hz: f64,
    period_s: f64,
) -> anyhow::Result<Option<BusLoad>> {
    let NodeLink::Uri(uri) = &scenario.links.fsm else {
        return Ok(None);
    };
    let parsed: LinkUri = uri.parse()?;
    let Some(bitrate) = parsed.bus_bitrate() else {
        return Ok(None);
    };
    let sensor_on_bus = matches!(&scenario.links.sensor, NodeLink::Uri(s) if s == "fsm");
    let distance_rate_hz = if sensor_on_bus { sensor_rate_hz } else { 0.0 };
    let rates = Bitrates {
        nominal_bps: f64::from(bitrate),
        data_bps: f64::from(bitrate),
    };
    let control_rate_hz = 1.0 / period_s;
    let traffic = loop_traffic(scenario.timing.mode, control_rate_hz, distance_rate_hz);
    let load = BusLoad::of(&traffic, rates);
    match load.check(LoadLimits::DEFAULT) {
        Ok(Some(warning)) => eprintln!("scanhil: warning: {uri}: {warning}"),
        Ok(None) => {}
        Err(overload) => {
            return Err(LoopDoesNotFit {
                link: uri.clone(),
                overload,
                max_rate_hz: max_control_rate_hz(scenario.timing.mode, rates, distance_rate_hz),
            }
            .into());
        }
    }
    Ok(Some(load))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_20_khz_loop_does_not_fit_on_one_megabit_but_2_khz_does() {
        let rates = Bitrates::CLASSICAL_1M;
        let fast = BusLoad::of(&loop_traffic(TimingMode::Lockstep, 20_000.0, 0.0), rates);
        assert!(fast.load > 1.0, "{fast:?}");
        let slow = BusLoad::of(&loop_traffic(TimingMode::Lockstep, 2_000.0, 0.0), rates);
        assert!(slow.load < 1.0, "{slow:?}");
    }

    #[test]
    fn the_highest_rate_fills_the_bus_exactly() {
        // CoilCommand 135 + Step 95 + AngleReading 135 bits a period, StatusFsm at 10 Hz.
        for (mode, distance_hz) in [
            (TimingMode::Lockstep, 0.0),
            (TimingMode::Realtime, 0.0),
            (TimingMode::Lockstep, 1_500.0),
        ] {
            let rates = Bitrates::CLASSICAL_1M;
            let max = max_control_rate_hz(mode, rates, distance_hz);
            let load = BusLoad::of(&loop_traffic(mode, max, distance_hz), rates).load;
            assert!(
                (load - 1.0).abs() < 1e-12,
                "{mode:?}: {max} Hz loads {load}"
            );
        }
        let max = max_control_rate_hz(TimingMode::Lockstep, Bitrates::CLASSICAL_1M, 0.0);
        assert_eq!(max.floor(), 2736.0);
    }
}
