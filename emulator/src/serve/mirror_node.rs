//! The mirror node as a protocol state machine, free of I/O and clocks: coil commands in,
//! one plant period per step, angle readings, status and faults out. The transport loops
//! ([`super::lockstep`], [`super::realtime`]) feed it decoded messages and sends what it returns; lockstep and real
//! time differ only in who calls [`MirrorNode::step`] (the controller's Step frame, or the
//! emulator's own clock).

use scanhil_protocol::message::{FaultKind, NodeState};
use scanhil_protocol::plant_units::ActuatorPair;

use crate::plant::{Plant, PlantError, PlantEvent, PlantStep};
use crate::sensor_faults::{SensorFaultCounts, SensorFaultModel};

/// What the node sends after a period: its angle reading, then a fault frame for each fault
/// that started in it.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeOutput {
    /// The period just stepped (its angle reading and sensor samples).
    pub step: PlantStep,
    /// The faults that started in it, each with its detail (over-current: the commanded
    /// current in uA; power limit: the mean power in mW); empty (no allocation) in a period
    /// without one.
    pub started_faults: Vec<(FaultKind, i32)>,
}

/// How far behind the newest command (by its sequence counter) a command counts as late and
/// is not applied; further behind it is taken as a jump of the counter (a gap), so a corrupted
/// counter cannot lock the node out of its commands for long.
pub const LATE_COMMAND_WINDOW: u16 = 64;

/// Counters the node reports at the end of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct NodeCounters {
    /// Periods stepped.
    pub periods: u64,
    /// Coil commands received.
    pub commands: u64,
    /// Coil commands whose sequence counter skipped values.
    pub command_gaps: u64,
    /// Coil commands up to [`LATE_COMMAND_WINDOW`] behind the newest one received (delayed or
    /// reordered on the way): counted and not applied.
    pub late_commands: u64,
    /// Coil commands with the sequence counter of the one before (a duplicate).
    pub repeated_commands: u64,
    /// Step frames for the period just stepped (a duplicate, or the host asking again for a
    /// reading it did not get): answered with the same reading, the plant not stepped.
    pub repeated_steps: u64,
    /// Periods stepped without a fresh command for them (real time: the controller was late).
    pub stale_periods: u64,
    /// Step frames whose period counter was neither the node's next period nor the one just
    /// stepped (lockstep: not stepped, not answered).
    pub out_of_order_steps: u64,
    /// Frames with a loop id and a malformed payload.
    pub malformed_frames: u64,
    /// Fault frames sent.
    pub faults: u64,
    /// The largest coil current any received command asked for (either coil, by magnitude;
    /// applied or not), A: what a bench's amplifiers would have been told to drive.
    pub largest_command_a: f64,
}

/// The mirror node around an emulated plant.
#[derive(Debug)]
pub struct MirrorNode {
    plant: Plant,
    state: NodeState,
    command_a: ActuatorPair,
    fresh_command: bool,
    last_command_seq: Option<u16>,
    /// Faults active in the last period: a fault frame goes out when one starts, not every
    /// period it lasts.
    active_faults: Vec<FaultKind>,
    counters: NodeCounters,
    sensor_faults: Option<SensorFaultModel>,
}

impl MirrorNode {
    /// A node around `plant`, in state [`NodeState::Ready`].
    #[must_use]
    pub fn new(plant: Plant) -> MirrorNode {
        MirrorNode {
            plant,
            state: NodeState::Ready,
            command_a: ActuatorPair::default(),
            fresh_command: false,
            last_command_seq: None,
            active_faults: Vec::new(),
            counters: NodeCounters::default(),
            sensor_faults: None,
        }
    }

    /// The same node, its sensor losing its peak as `faults` says.
    #[must_use]
    pub fn with_sensor_faults(mut self, faults: SensorFaultModel) -> MirrorNode {
        self.sensor_faults = Some(faults);
        self
    }

    /// How many sensor samples each declared sensor fault replaced (`None`: none declared).
    #[must_use]
    pub fn sensor_fault_counts(&self) -> Option<SensorFaultCounts> {
        self.sensor_faults.as_ref().map(SensorFaultModel::counts)
    }

    /// Counts a Step frame for the period just stepped (answered again, not stepped).
    pub fn on_repeated_step(&mut self) {
        self.counters.repeated_steps += 1;
    }

    /// The node's state.
    #[must_use]
    pub fn state(&self) -> NodeState {
        self.state
    }

    /// The plant (for its period and active parts).
    #[must_use]
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// Its counters so far.
    #[must_use]
    pub fn counters(&self) -> NodeCounters {
        self.counters
    }

    /// The coil currents the node applies from the next period on (zero after a fault), A.
    #[must_use]
    pub fn held_command_a(&self) -> ActuatorPair {
        if self.state == NodeState::Fault {
            ActuatorPair::default()
        } else {
            self.command_a
        }
    }

    /// The next period to step.
    #[must_use]
    pub fn next_period(&self) -> u64 {
        self.plant.period_index()
    }

    /// Checks a Step frame's period counter (32 bits on the wire) against the next period;
    /// counts and returns false when it is another.
    pub fn check_step_counter(&mut self, period: u32) -> bool {
        let next = u64::from(period) == self.next_period() & u64::from(u32::MAX);
        if !next {
            self.counters.out_of_order_steps += 1;
        }
        next
    }

    /// Counts a frame with a loop id and a malformed payload.
    pub fn on_malformed_frame(&mut self) {
        self.counters.malformed_frames += 1;
    }

    /// A coil current command with its 16-bit sequence counter. Non-finite currents are
    /// refused by the plant at the next step; here they are held like any other command. A
    /// command just behind the newest one (by its counter, mod 2^16; up to
    /// [`LATE_COMMAND_WINDOW`]) is counted, not applied.
    pub fn on_command(&mut self, seq: u16, currents_a: ActuatorPair) {
        self.counters.largest_command_a = self
            .counters
            .largest_command_a
            .max(currents_a.a.abs())
            .max(currents_a.b.abs());
        if let Some(last) = self.last_command_seq {
            match seq.wrapping_sub(last) {
                0 => self.counters.repeated_commands += 1,
                1 => {}
                offset if offset.wrapping_neg() <= LATE_COMMAND_WINDOW => {
                    // Just behind the newest one (delayed or reordered): not applied.
                    self.counters.late_commands += 1;
                    return;
                }
                _ => self.counters.command_gaps += 1,
            }
        }
        self.last_command_seq = Some(seq);
        self.counters.commands += 1;
        if self.state != NodeState::Fault {
            self.command_a = currents_a;
        }
        self.fresh_command = true;
    }

    /// Advances the plant one period with the newest command (zero after a fault) and returns
    /// what to send: the angle reading, then a fault frame for each fault that started in
    /// this period.
    ///
    /// # Errors
    /// The plant's error (a non-finite command): the caller reports it and stops.
    pub fn step(&mut self) -> Result<NodeOutput, PlantError> {
        if self.state != NodeState::Fault {
            self.state = NodeState::Running;
        }
        if !self.fresh_command {
            self.counters.stale_periods += 1;
        }
        self.fresh_command = false;
        let command = if self.state == NodeState::Fault {
            ActuatorPair::default()
        } else {
            self.command_a
        };
        let mut step = self.plant.step(command)?;
        if let Some(faults) = &mut self.sensor_faults {
            step.sensor_samples
                .iter_mut()
                .for_each(|sample| faults.apply(sample));
        }
        self.counters.periods += 1;
        let mut faults: Vec<(FaultKind, i32)> = Vec::new();
        for event in &step.events {
            let fault = match *event {
                PlantEvent::CurrentLimited { requested_a, .. } => (
                    FaultKind::OverCurrent,
                    saturate_i32(requested_a.a.abs().max(requested_a.b.abs()) * 1e6),
                ),
                PlantEvent::PowerClamped { requested_w, .. } => {
                    (FaultKind::PowerLimit, saturate_i32(requested_w * 1e3))
                }
                PlantEvent::PowerFault { mean_w } => {
                    (FaultKind::PowerLimit, saturate_i32(mean_w * 1e3))
                }
                // A real driver reports no rail saturation: the host sees it in the angles.
                PlantEvent::VoltageLimited { .. } => continue,
            };
            if !faults.iter().any(|(kind, _)| *kind == fault.0) {
                faults.push(fault);
            }
        }
        if step.faulted {
            self.enter_fault();
        }
        let kinds: Vec<FaultKind> = faults.iter().map(|(kind, _)| *kind).collect();
        faults.retain(|(kind, _)| !self.active_faults.contains(kind));
        self.counters.faults += faults.len() as u64;
        self.active_faults = kinds;
        Ok(NodeOutput {
            step,
            started_faults: faults,
        })
    }

    /// The watchdog fired after `missed_periods`: coil currents drop to zero, and the fault
    /// to report is returned.
    pub fn on_link_timeout(&mut self, missed_periods: u32) -> (FaultKind, i32) {
        self.enter_fault();
        self.counters.faults += 1;
        (
            FaultKind::LinkTimeout,
            i32::try_from(missed_periods).unwrap_or(i32::MAX),
        )
    }

    /// The node's link failed (bus-off, an OS error on the line): coil currents drop to zero,
    /// as for the watchdog, and the fault to report is returned: a LinkTimeout with detail 0
    /// (no period was missed; the link itself went away).
    pub fn on_link_failure(&mut self) -> (FaultKind, i32) {
        self.on_link_timeout(0)
    }

    /// The controller ended the run: a running node is ready again (a faulted one stays in
    /// fault), holding the command it has (the controller's last one is its zero).
    pub fn on_end_of_run(&mut self) {
        if self.state != NodeState::Fault {
            self.state = NodeState::Ready;
        }
    }

    fn enter_fault(&mut self) {
        self.state = NodeState::Fault;
        self.command_a = ActuatorPair::default();
    }
}

/// Rounds to the nearest `i32`, saturating (a fault frame's detail field).
fn saturate_i32(value: f64) -> i32 {
    value
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// A node around the protocol-only scene (the mirror still, every sample the same).
    pub(in crate::serve) fn node() -> MirrorNode {
        let scene = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../fixtures/scenes/protocol-only.json"
        );
        let (_, plant) = super::super::load_plant(std::path::Path::new(scene), None).unwrap();
        MirrorNode::new(plant)
    }

    #[test]
    fn a_fault_goes_out_in_the_period_it_starts_and_not_while_it_lasts() {
        let scene = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../fixtures/scenes/loop-power-fault.json"
        );
        let (_, plant) = super::super::load_plant(std::path::Path::new(scene), None).unwrap();
        let mut node = MirrorNode::new(plant);
        let beyond = ActuatorPair { a: 100.0, b: 0.0 };
        let mut started = Vec::new();
        // The plant applies a command one period after it came.
        for seq in 0..4 {
            node.on_command(seq, beyond);
            started.push(node.step().unwrap().started_faults);
        }
        let kinds: Vec<Vec<FaultKind>> = started
            .iter()
            .map(|faults| faults.iter().map(|(kind, _)| *kind).collect())
            .collect();
        assert_eq!(
            kinds,
            [vec![], vec![FaultKind::OverCurrent], vec![], vec![]],
            "{started:?}"
        );
        assert_eq!(node.counters().faults, 1);
    }

    #[test]
    fn the_largest_command_received_is_kept_late_ones_included() {
        let mut node = node();
        assert_eq!(node.counters().largest_command_a, 0.0);
        node.on_command(10, ActuatorPair { a: 0.3, b: -1.25 });
        node.on_command(11, ActuatorPair { a: 0.5, b: 0.0 });
        assert_eq!(node.counters().largest_command_a, 1.25);
        // A command behind the newest is not applied, but the node did receive it.
        node.on_command(9, ActuatorPair { a: -8.0, b: 0.0 });
        assert_eq!(node.counters().late_commands, 1);
        assert_eq!(node.held_command_a(), ActuatorPair { a: 0.5, b: 0.0 });
        assert_eq!(node.counters().largest_command_a, 8.0);
    }
}
