//! [`PlantLink`] over a real mirror link, so `scanhil identify --fsm LINK` measures whatever
//! is on the other end: the emulator (started here on a pty pair, `--fsm pty`), or a real
//! mirror node (`--fsm slcan:/dev/ttyACM0`, `--fsm socketcan:can0`). Each exchange is one
//! lockstep period. With a record folder every frame on the link goes to its `fsm.log`
//! (candump `-L`, loop-time stamps), as a scan records it.

use std::path::Path;
use std::time::Duration;

use anyhow::Context;
use scanhil_protocol::plant_units::{ActuatorPair, SensingPair};

use super::emulator_process::EmulatorProcess;
use super::mirror_link::MirrorLink;
use super::output_failures::{OutputFailures, RecordingFailure};
use super::scenario::{NodeLink, TimingConfig};
use super::{LinkPlan, open_links};
use crate::link::{CoilsAtEnd, LinkError, PlantLink};

/// Wall-clock allowance per missed answer.
const ANSWER_ALLOWANCE: Duration = Duration::from_millis(10);
/// Missed answers before the link counts as timed out.
const WATCHDOG_PERIODS: u32 = 200;

/// A mirror node on a real link, driven in lockstep.
#[derive(Debug)]
pub struct LinkedPlant {
    runtime: tokio::runtime::Runtime,
    mirror: MirrorLink,
    period_s: f64,
    next_period: u64,
    /// How the session ended, once it has ([`PlantLink::end`]).
    ended: Option<CoilsAtEnd>,
    /// The recording's write errors, and its creation's.
    recordings: (Vec<RecordingFailure>, OutputFailures),
    _emulator: Option<EmulatorProcess>,
}

impl LinkedPlant {
    /// Connects to the mirror node on `fsm`. With [`NodeLink::Pty`], starts
    /// `scanhil-emulator serve --scene SCENE` on a new pty pair (the scene is then required).
    /// With `record_dir`, the link's frames are recorded to its `fsm.log`.
    ///
    /// # Errors
    /// A link that does not open, no emulator binary, no scene for an emulated node.
    pub fn connect(
        fsm: &NodeLink,
        scene: Option<&Path>,
        emulator: Option<&Path>,
        period_s: f64,
        record_dir: Option<&Path>,
    ) -> anyhow::Result<LinkedPlant> {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .context("starting the I/O runtime")?;
        let scene = match (fsm, scene) {
            (NodeLink::Pty, None) => anyhow::bail!("--fsm pty emulates the mirror: give --scene"),
            (_, scene) => scene.map(Path::to_owned).unwrap_or_default(),
        };
        let plan = LinkPlan {
            fsm: fsm.clone(),
            sensor: None,
            spawn_emulator: false,
            emulator: emulator.map(Path::to_owned),
            scene,
            seed: 0,
            sensor_faults: Default::default(),
            timing: TimingConfig {
                watchdog_periods: WATCHDOG_PERIODS,
                lockstep_answer_allowance_s: ANSWER_ALLOWANCE.as_secs_f64(),
                ..TimingConfig::default()
            },
            period_s,
            duration_s: 0.0,
            record_dir: record_dir.map(Path::to_owned),
            recording: Default::default(),
            bus_bitrate: None,
            sensor_expectation: None,
            replay: None,
        };
        let links = runtime.block_on(open_links(&plan))?;
        Ok(LinkedPlant {
            runtime,
            mirror: links.mirror,
            period_s,
            next_period: 0,
            ended: None,
            recordings: (links.recordings, links.recording_failures),
            _emulator: links.emulator,
        })
    }

    /// Ends the session (coils at zero, the link closed, the recording written out) and
    /// returns the recording's failures: `file: error`, empty when it was written whole.
    #[must_use]
    pub fn finish(mut self) -> Vec<String> {
        self.end();
        let (written, created) = std::mem::take(&mut self.recordings);
        drop(self);
        let mut failures: Vec<String> = created
            .iter()
            .map(|(file, error)| format!("{file}: {error}"))
            .collect();
        failures.extend(
            written
                .iter()
                .filter_map(|r| r.get().map(|error| format!("{}: {error}", r.name))),
        );
        failures
    }
}

/// Ends the session with the coils at zero (if [`PlantLink::end`] has not) and closes the
/// mirror's link explicitly (`C` on SLCAN, bounded wait) however identification ends:
/// normally, on an error, or unwinding.
impl Drop for LinkedPlant {
    fn drop(&mut self) {
        self.end();
        let mirror = &mut self.mirror;
        let _ = self.runtime.block_on(mirror.close());
    }
}

impl PlantLink for LinkedPlant {
    fn exchange(&mut self, coil_currents_a: ActuatorPair) -> Result<SensingPair, LinkError> {
        let k = self.next_period;
        let result = self
            .runtime
            .block_on(self.mirror.exchange_lockstep(k, coil_currents_a));
        match result {
            Ok(angles) => {
                self.next_period += 1;
                Ok(angles)
            }
            Err(error) => {
                // An early stop: zero best effort, no answer awaited (the link may be gone).
                let mirror = &mut self.mirror;
                let zero_commanded = self.runtime.block_on(mirror.command_zero(k));
                self.ended.get_or_insert(CoilsAtEnd {
                    zero_commanded,
                    acknowledged: false,
                });
                Err(LinkError {
                    message: error.to_string(),
                })
            }
        }
    }

    fn period_s(&self) -> f64 {
        self.period_s
    }

    /// CoilCommand(0) and the controller's Status(ready) after the last exchange, and the
    /// node's Status(ready) awaited as their acknowledgement ([`MirrorLink::end_session`]);
    /// once per session.
    fn end(&mut self) -> Option<CoilsAtEnd> {
        if self.ended.is_none() {
            let (mirror, periods) = (&mut self.mirror, self.next_period);
            self.ended = Some(self.runtime.block_on(mirror.end_session(periods)));
        }
        self.ended
    }
}
