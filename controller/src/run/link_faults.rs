//! Injected faults, as a scenario declares them (`faults`) and as a run applies and reports
//! them. [`FaultsConfig`] is the scenario's section; [`LinkFaults`] puts the protocol's
//! [`FrameInjector`]s for both directions between the host loop and the mirror's link (the
//! two-process scan in [`super::mirror_link`], the in-process loop in `scanhil-lab`); the
//! sensor's faults go to the emulated sensor. Everything injected is reported in
//! `report.json` `faults`, beside what each side detected.
//!
//! A frame belongs to a loop period: a frame the host sends at loop time `k * Ta` to period
//! `k`, a frame it receives while awaiting reading `k` (loop time `(k + 1) * Ta`) to period
//! `k`, so `{"period": 500, "fault": "drop"}` on `node_to_host` drops AngleReading(500).

use std::collections::VecDeque;

use scanhil_protocol::can::CanFrame;
use scanhil_protocol::fault_injection::{
    DirectionFaults, FaultConfigError, FrameInjector, FrameLedger, InjectedFault, SensorFaults,
};
use scanhil_protocol::message::spec::Sender;
use serde::{Deserialize, Serialize};

/// A scenario's `faults` section: frame faults per direction of the mirror's link and the
/// sensor losing its peak. Empty by default.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FaultsConfig {
    /// Seed of the fault generators (default: the scenario's seed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Faults on the frames the host sends to the mirror node.
    pub host_to_node: DirectionFaults,
    /// Faults on the frames the mirror node sends to the host.
    pub node_to_host: DirectionFaults,
    /// The sensor losing its peak.
    pub sensor: SensorFaults,
}

impl FaultsConfig {
    /// Whether frame faults are declared on the mirror's link.
    #[must_use]
    pub fn frames_active(&self) -> bool {
        self.host_to_node.is_active() || self.node_to_host.is_active()
    }

    /// Whether anything is declared.
    #[must_use]
    pub fn is_active(&self) -> bool {
        self.frames_active() || self.sensor.is_active()
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`FaultConfigError`] with the field's full path (`faults.node_to_host.drop_rate`).
    pub fn check(&self) -> Result<(), FaultConfigError> {
        let prefixed = |prefix: &str| {
            let prefix = prefix.to_owned();
            move |error: FaultConfigError| FaultConfigError {
                field: format!("faults.{prefix}.{}", error.field),
                reason: error.reason,
            }
        };
        self.host_to_node
            .check()
            .and_then(|()| self.host_to_node.check_senders(&[Sender::Controller]))
            .map_err(prefixed("host_to_node"))?;
        // The node's link also carries the sensor's Distance frames (sensor `fsm`).
        self.node_to_host
            .check()
            .and_then(|()| {
                self.node_to_host
                    .check_senders(&[Sender::Fsm, Sender::Sensor])
            })
            .map_err(prefixed("node_to_host"))?;
        self.sensor.check().map_err(prefixed("sensor"))
    }

    /// Checks that every fault listed at a period falls within a run of `periods` (lead-in
    /// included), and sensor faults only where `has_sensor`: anything else could never fire.
    ///
    /// # Errors
    /// [`FaultConfigError`] naming the field (`faults.node_to_host.at[0].period`).
    pub fn check_reachable(&self, periods: u64, has_sensor: bool) -> Result<(), FaultConfigError> {
        for (name, direction) in [
            ("host_to_node", &self.host_to_node),
            ("node_to_host", &self.node_to_host),
        ] {
            if let Some((index, period)) = direction.first_beyond(periods) {
                return Err(FaultConfigError {
                    field: format!("faults.{name}.at[{index}].period"),
                    reason: format!(
                        "period {period} is beyond the run's {periods} periods (0 to {}, \
                         lead-in included): the fault could never fire",
                        periods.saturating_sub(1)
                    ),
                });
            }
        }
        if self.sensor.is_active() && !has_sensor {
            return Err(FaultConfigError {
                field: "faults.sensor".into(),
                reason: "the rig has no sensor: sensor faults could never fire".into(),
            });
        }
        Ok(())
    }

    /// Applies a command-line override `KEY=VALUE`: `KEY` a dotted path below `faults`
    /// (`node_to_host.drop_rate`, `sensor.laser_off`), `VALUE` JSON (a bare word is taken as
    /// a string). The result is checked as the file is.
    ///
    /// # Errors
    /// A malformed override, an unknown field, a value of the wrong type or one that fails
    /// [`Self::check`]: the message names the field.
    pub fn with_override(&self, assignment: &str) -> Result<FaultsConfig, FaultConfigError> {
        let invalid = |field: &str, reason: String| FaultConfigError {
            field: format!("faults.{field}"),
            reason,
        };
        let Some((key, value)) = assignment.split_once('=') else {
            return Err(invalid(
                assignment,
                "expected KEY=VALUE, such as node_to_host.drop_rate=0.001".into(),
            ));
        };
        let value: serde_json::Value = serde_json::from_str(value)
            .unwrap_or_else(|_| serde_json::Value::String(value.to_owned()));
        let mut tree = serde_json::to_value(self).map_err(|e| invalid(key, e.to_string()))?;
        let mut node = &mut tree;
        let parts: Vec<&str> = key.split('.').collect();
        for (index, part) in parts.iter().enumerate() {
            let serde_json::Value::Object(map) = node else {
                return Err(invalid(key, format!("`{part}` is below a value")));
            };
            if index + 1 == parts.len() {
                map.insert((*part).to_owned(), value.clone());
                break;
            }
            node = map
                .entry((*part).to_owned())
                .or_insert_with(|| serde_json::json!({}));
        }
        let faults: FaultsConfig =
            serde_json::from_value(tree).map_err(|e| invalid(key, e.to_string()))?;
        faults.check()?;
        Ok(faults)
    }
}

/// The frame faults of one run of the mirror's link, both directions.
#[derive(Debug, Clone)]
pub struct LinkFaults {
    to_node: FrameInjector,
    to_host: FrameInjector,
    period_s: f64,
    /// Frames from the node that passed the wire, not yet taken by the host.
    inbound: VecDeque<CanFrame>,
    scratch: Vec<CanFrame>,
}

/// Offset of the node-to-host generator's seed from the host-to-node one's.
const NODE_TO_HOST_STREAM: u64 = 0x9e37_79b9_7f4a_7c15;

impl LinkFaults {
    /// The frame faults of `config` on a loop of `period_s`, seeded with `config.seed` or
    /// `seed`; `None` when no frame fault is declared.
    #[must_use]
    pub fn new(config: &FaultsConfig, seed: u64, period_s: f64) -> Option<LinkFaults> {
        if !config.frames_active() {
            return None;
        }
        let seed = config.seed.unwrap_or(seed);
        Some(LinkFaults {
            to_node: FrameInjector::new(config.host_to_node.clone(), seed),
            to_host: FrameInjector::new(config.node_to_host.clone(), seed ^ NODE_TO_HOST_STREAM),
            period_s,
            inbound: VecDeque::new(),
            scratch: Vec::new(),
        })
    }

    /// The host sends `frame` at loop time `t_s`: what the node gets now, in order.
    pub fn outgoing(&mut self, frame: &CanFrame, t_s: f64) -> impl Iterator<Item = CanFrame> {
        let period = (t_s / self.period_s).round() as u64;
        self.to_node.send(*frame, period, &mut self.scratch);
        self.scratch.drain(..)
    }

    /// A frame from the node reaches the wire while the host waits at loop time `t_s`.
    pub fn incoming(&mut self, frame: &CanFrame, t_s: f64) {
        let period = self.incoming_period(t_s);
        self.to_host.send(*frame, period, &mut self.scratch);
        self.inbound.extend(self.scratch.drain(..));
    }

    /// The next frame from the node that has passed the wire by loop time `t_s` (delayed
    /// frames due by then included), if any.
    pub fn next_incoming(&mut self, t_s: f64) -> Option<CanFrame> {
        let period = self.incoming_period(t_s);
        self.to_host.release_due(period, &mut self.scratch);
        self.inbound.extend(self.scratch.drain(..));
        self.inbound.pop_front()
    }

    /// What was injected in each direction, for the report.
    #[must_use]
    pub fn report(&self) -> InjectedFrameFaults {
        InjectedFrameFaults {
            host_to_node: DirectionReport::of(&self.to_node),
            node_to_host: DirectionReport::of(&self.to_host),
        }
    }

    fn incoming_period(&self, t_s: f64) -> u64 {
        ((t_s / self.period_s).round() as u64).saturating_sub(1)
    }
}

/// What was injected on the mirror's link.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InjectedFrameFaults {
    /// On the frames the host sent.
    pub host_to_node: DirectionReport,
    /// On the frames the node sent.
    pub node_to_host: DirectionReport,
}

/// One direction's ledger and its first faults.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DirectionReport {
    /// Every frame accounted for.
    pub ledger: FrameLedger,
    /// Whether the ledger balances (delivered = offered - dropped + duplicated - held).
    pub balances: bool,
    /// The first faults injected, with their period and message.
    pub first_faults: Vec<InjectedFault>,
}

impl DirectionReport {
    fn of(injector: &FrameInjector) -> DirectionReport {
        let ledger = injector.ledger();
        DirectionReport {
            ledger,
            balances: ledger.balances(),
            first_faults: injector.log().to_vec(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_pass_the_checks_of_the_file() {
        let faults = FaultsConfig::default()
            .with_override("node_to_host.drop_rate=0.01")
            .unwrap()
            .with_override(r#"host_to_node.at=[{"period": 5, "fault": "duplicate"}]"#)
            .unwrap()
            .with_override(r#"sensor.laser_off=[{"from_s": 0.1, "to_s": 0.2}]"#)
            .unwrap();
        assert_eq!(faults.node_to_host.drop_rate, 0.01);
        assert_eq!(faults.host_to_node.at.len(), 1);
        assert_eq!(faults.sensor.laser_off.len(), 1);
        let bad = [
            ("node_to_host.drop_rate=2", "faults.node_to_host.drop_rate"),
            ("node_to_host.drop_rat=0.1", "faults.node_to_host.drop_rat"),
            (
                "node_to_host.drop_rate=high",
                "faults.node_to_host.drop_rate",
            ),
            (
                "sensor.laser_off=[{\"from_s\": 1, \"to_s\": 0}]",
                "faults.sensor.laser_off[0]",
            ),
            ("node_to_host", "faults.node_to_host"),
        ];
        for (assignment, field) in bad {
            let error = faults.with_override(assignment).unwrap_err();
            assert_eq!(error.field, field, "{assignment}: {error}");
        }
    }
}
