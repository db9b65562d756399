//! A scenario file (`fixtures/scenarios/*.json`): everything one `scanhil scan` needs: the
//! rig it runs on, the controller settings, the trajectory, the links, the timing mode, the
//! duration and the seed, and how to image the result; for emulated devices the scene the
//! emulator serves, and optionally a true surface to score the reconstruction against.
//!
//! The host reads the rig, never the scene: the scene's path is only handed to
//! `scanhil-emulator serve` when the host starts it. A scan of real devices names a rig and no
//! scene; a `truth` (a scene file whose `surface` describes the object on the bench) enables
//! the error figures. For an emulated scan the truth defaults to the emulator's scene.
//!
//! Relative paths inside a scenario are resolved against the scenario file's directory.

use std::path::{Path, PathBuf};

use scanhil_geometry::GeometryModel;
use scanhil_protocol::scheduling::{self, RealtimeOptions};
use scanhil_protocol::validation::{Allowed, Invalid, InvalidValue};
use scanhil_protocol::{interface_name, loop_limits};
use serde::{Deserialize, Serialize};

use super::lead_in::LeadIn;
use super::link_faults::FaultsConfig;
use crate::imaging::feature::FeatureParams;
use crate::imaging::pipeline::MAX_PROGRESSIVE_STEPS;
use crate::rig::{Rig, RigError};
use crate::trajectory::Trajectory;
use scanhil_scene::json_file::{self, JsonFileError};

/// The longest scan a scenario may ask for, s (an hour of 20 kHz loop, 72 million periods:
/// [`loop_limits::DURATION_S`]).
pub const MAX_DURATION_S: f64 = loop_limits::DURATION_S.max;

/// A loaded, checked scenario with absolute paths.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// Where it was loaded from.
    pub path: PathBuf,
    /// Short name (used in reports).
    pub name: String,
    /// Free text.
    pub description: String,
    /// The rig the host runs against.
    pub rig: Rig,
    /// The scene file the emulator serves, for emulated devices.
    pub scene: Option<PathBuf>,
    /// The scene file whose surface scores the reconstruction (default: `scene`).
    pub truth: Option<PathBuf>,
    /// The controller settings file.
    pub controller: PathBuf,
    /// The reference the mirror follows.
    pub trajectory: Trajectory,
    /// How long to scan, in seconds of (virtual) time.
    pub duration_s: f64,
    /// Seed of every random generator in the plant (overrides the scene's seed).
    pub seed: u64,
    /// Lockstep or real time, and the watchdog.
    pub timing: TimingConfig,
    /// Which links carry the mirror and the sensor.
    pub links: LinksConfig,
    /// How the point cloud is gridded and scored.
    pub imaging: ImagingConfig,
    /// The coil power policy ([`super::power_guard`]).
    pub power: PowerConfig,
    /// How long the trajectory runs before the recorded frame ([`super::lead_in`]).
    pub lead_in: LeadIn,
    /// Injected faults ([`super::link_faults`]; none by default).
    pub faults: FaultsConfig,
    /// How the mirror link's recording is stamped and named.
    pub recording: RecordingConfig,
    /// Which output files a run writes (every one by default).
    pub outputs: OutputsConfig,
}

/// How the loop is clocked.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize, Default, clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
pub enum TimingMode {
    /// The controller's Step frame advances the emulator by exactly one period (virtual time).
    #[default]
    Lockstep,
    /// The emulator is the clock master on the wall clock; the controller answers each period.
    Realtime,
}

impl TimingMode {
    /// The mode as scenarios and command lines spell it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            TimingMode::Lockstep => "lockstep",
            TimingMode::Realtime => "realtime",
        }
    }
}

/// The `timing` section.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct TimingConfig {
    /// Lockstep (default) or real time.
    pub mode: TimingMode,
    /// Missed periods after which either side declares a link timeout.
    pub watchdog_periods: u32,
    /// In lockstep, the wall-clock allowance for one answer before a period counts as missed,
    /// in seconds (a debug build on a busy machine needs far more than one period).
    pub lockstep_answer_allowance_s: f64,
    /// Real time: both ends spin on non-blocking reads instead of waiting on readiness.
    pub busy_poll: bool,
    /// Real time: pin the host's loop to this CPU.
    pub cpu: Option<usize>,
    /// Real time: pin the emulator this scan starts to this CPU.
    pub emulator_cpu: Option<usize>,
    /// Real time: run both loops under `SCHED_FIFO` at this priority (1 to 99), memory locked.
    pub sched_fifo_priority: Option<u8>,
    /// Real time: how long each end's wake-up probe runs before the loop, in seconds (0: none).
    pub probe_s: f64,
    /// How long an emulator started here may take to say it is ready, in seconds (its
    /// real-time wake-up probe, `probe_s`, comes on top); past it the emulator is stopped and
    /// the scan refused.
    pub emulator_ready_s: f64,
}

/// The allowed `timing.emulator_ready_s`: an emulator builds its plant and opens its links in
/// well under a second; ten minutes covers any machine.
pub const EMULATOR_READY_S: Allowed = Allowed::above(0.0, 600.0, "s");

impl TimingConfig {
    /// What the host asks of the OS for its real-time loop.
    #[must_use]
    pub fn host_options(&self) -> RealtimeOptions {
        RealtimeOptions {
            busy_poll: self.busy_poll,
            cpu: self.cpu,
            sched_fifo_priority: self.sched_fifo_priority,
        }
    }

    /// What the emulator this scan starts asks of the OS for its real-time loop.
    #[must_use]
    pub fn emulator_options(&self) -> RealtimeOptions {
        RealtimeOptions {
            cpu: self.emulator_cpu,
            ..self.host_options()
        }
    }

    /// Checks the timing of a loop at `period_s`: the answer allowance and the watchdog
    /// within the limits both ends hold ([`loop_limits`]), and the real-time options: only in
    /// real time, a priority within 1 to 99, CPUs the machine has, two busy-polling ends on
    /// two CPUs, a probe of 0 to 60 s. Fields are named below `timing`.
    fn check(&self, period_s: f64) -> Result<(), Invalid> {
        loop_limits::ANSWER_ALLOWANCE_S.check(
            "timing.lockstep_answer_allowance_s",
            self.lockstep_answer_allowance_s,
        )?;
        let allowance_s = match self.mode {
            TimingMode::Lockstep => self.lockstep_answer_allowance_s,
            TimingMode::Realtime => period_s,
        };
        loop_limits::check_watchdog(
            "timing.watchdog_periods",
            self.watchdog_periods,
            allowance_s,
        )?;
        let asked =
            self.host_options() != RealtimeOptions::default() || self.emulator_cpu.is_some();
        if asked && self.mode == TimingMode::Lockstep {
            return Err(Invalid::new(
                "timing.mode",
                "busy_poll, cpu, emulator_cpu and sched_fifo_priority apply to real time only \
                 (`\"mode\": \"realtime\"` or `--timing realtime`)",
            ));
        }
        for (options, cpu_field) in [
            (self.host_options(), "timing.cpu"),
            (self.emulator_options(), "timing.emulator_cpu"),
        ] {
            scheduling::check(&options).map_err(|(field, reason)| match field {
                "cpu" => Invalid::new(cpu_field, reason),
                _ => Invalid::new("timing.sched_fifo_priority", reason),
            })?;
        }
        if self.busy_poll
            && let (Some(host), Some(emulator)) = (self.cpu, self.emulator_cpu)
            && host == emulator
        {
            return Err(Invalid::new(
                "timing.emulator_cpu",
                format!(
                    "CPU {emulator} is also the host's: two busy-polling loops on one CPU take \
                     turns by time slices, far longer than a period"
                ),
            ));
        }
        loop_limits::PROBE_S.check("timing.probe_s", self.probe_s)?;
        EMULATOR_READY_S.check("timing.emulator_ready_s", self.emulator_ready_s)
    }

    /// How long an emulator started here may take to become ready: `emulator_ready_s`, and
    /// in real time its wake-up probe.
    #[must_use]
    pub fn emulator_ready_wait(&self) -> std::time::Duration {
        let probe_s = match self.mode {
            TimingMode::Lockstep => 0.0,
            TimingMode::Realtime => self.probe_s,
        };
        std::time::Duration::from_secs_f64(self.emulator_ready_s + probe_s)
    }
}

impl Default for TimingConfig {
    fn default() -> TimingConfig {
        TimingConfig {
            mode: TimingMode::Lockstep,
            watchdog_periods: 200,
            lockstep_answer_allowance_s: 0.01,
            busy_poll: false,
            cpu: None,
            emulator_cpu: None,
            sched_fifo_priority: None,
            probe_s: 0.5,
            emulator_ready_s: 20.0,
        }
    }
}

/// Where a node lives.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub enum NodeLink {
    /// Emulated: `scanhil scan` starts `scanhil-emulator serve` on a fresh pty pair (SLCAN for
    /// the mirror, the ILD stream for the sensor). Written `"pty"`.
    Pty,
    /// A link URI (`socketcan:IFACE`, `slcan:PATH[@BITRATE]`, `ild:PATH[@BAUD]`).
    Uri(String),
}

impl<'de> Deserialize<'de> for NodeLink {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<NodeLink, D::Error> {
        let text = String::deserialize(deserializer)?;
        Ok(NodeLink::parse(&text))
    }
}

impl NodeLink {
    /// `"pty"` or a URI.
    #[must_use]
    pub fn parse(text: &str) -> NodeLink {
        if text == "pty" {
            NodeLink::Pty
        } else {
            NodeLink::Uri(text.to_owned())
        }
    }
}

/// The `links` section.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinksConfig {
    /// The mirror node.
    pub fsm: NodeLink,
    /// The sensor node.
    pub sensor: NodeLink,
    /// Start `scanhil-emulator serve` for the emulated nodes (true, the default), or use
    /// devices already on the links (false: real hardware, or an emulator started by hand).
    pub spawn_emulator: bool,
}

impl LinksConfig {
    /// Whether a scan starts the emulator: when asked, or for any `pty` link it uses (a pty
    /// has nothing behind it but the emulator); `uses_sensor` when the rig has a sensor.
    #[must_use]
    pub fn starts_emulator(&self, uses_sensor: bool) -> bool {
        self.spawn_emulator
            || self.fsm == NodeLink::Pty
            || (uses_sensor && self.sensor == NodeLink::Pty)
    }
}

impl Default for LinksConfig {
    fn default() -> LinksConfig {
        LinksConfig {
            fsm: NodeLink::Pty,
            sensor: NodeLink::Pty,
            spawn_emulator: true,
        }
    }
}

/// The `recording` section: how `fsm.log` (the mirror link's candump `-L` recording) is
/// stamped and which interface its lines name, for the tools a technician replays it with
/// (`canplayer`, `log2asc`). The defaults keep recordings of the same seed bit-identical on
/// every transport.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecordingConfig {
    /// Lockstep: stamp each frame with a Unix time (the wall clock when the loop started plus
    /// the loop's time) instead of the loop's time from zero (`--record-epoch`). A real-time
    /// loop's stamps are the wall clock's either way.
    pub epoch: bool,
    /// The interface name each line carries (`--record-iface`), a Linux interface name.
    pub iface: String,
}

impl Default for RecordingConfig {
    fn default() -> RecordingConfig {
        RecordingConfig {
            epoch: false,
            iface: DEFAULT_RECORDING_IFACE.to_owned(),
        }
    }
}

/// The `outputs` section: which of the scan's files a run writes. A run that only wants its
/// report (a study's table) leaves out the recordings and the figures and saves their time;
/// `report.json` lists what was left out. By default every output is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputsConfig {
    /// `fsm.log` and `sensor.ild`, the links' recordings (`--no-recordings` leaves them out).
    pub recordings: bool,
    /// The pictures: `tracking.svg`, `height_map.png`, `progressive.svg`, `snapshots.png`,
    /// `profiles.svg` (`--no-figures` leaves them out). The CSV files and the point cloud
    /// are written either way.
    pub figures: bool,
}

impl Default for OutputsConfig {
    fn default() -> OutputsConfig {
        OutputsConfig {
            recordings: true,
            figures: true,
        }
    }
}

/// The interface name recordings carry by default, the same on every transport so that
/// recordings compare.
pub const DEFAULT_RECORDING_IFACE: &str = "fsm";

impl RecordingConfig {
    /// Checks the interface name against the kernel's rule ([`interface_name::check`]).
    ///
    /// # Errors
    /// `recording.iface` with why the name is no interface name.
    pub fn check(&self) -> Result<(), Invalid> {
        interface_name::check(&self.iface)
            .map_err(|error| Invalid::new("recording.iface", error.to_string()))
    }
}

/// What to do with a trajectory whose estimate is over `margin x limit`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PowerPolicy {
    /// Scale its amplitudes down to fit.
    #[default]
    Shrink,
    /// Refuse to run it.
    Refuse,
    /// Run it as written.
    Off,
}

/// A scenario's `power` section.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PowerConfig {
    /// Shrink, refuse or off.
    pub policy: PowerPolicy,
    /// The share of the rig's power limit a trajectory may use, in (0, 1].
    pub margin: f64,
    /// Back off when the node reports its power limit (lockstep loops).
    pub backoff: bool,
}

impl Default for PowerConfig {
    fn default() -> PowerConfig {
        PowerConfig {
            policy: PowerPolicy::Shrink,
            margin: 0.9,
            backoff: true,
        }
    }
}

impl PowerConfig {
    /// Checks the margin; on failure the field and why.
    ///
    /// # Errors
    /// A margin outside (0, 1].
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        if self.margin.is_finite() && self.margin > 0.0 && self.margin <= 1.0 {
            Ok(())
        } else {
            Err(("power.margin", format!("{} must be in (0, 1]", self.margin)))
        }
    }
}

/// The `imaging` section.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImagingConfig {
    /// Height map cell size, in mm.
    pub pitch_mm: f64,
    /// Which geometry turns angles and distances into points.
    pub reconstruction: GeometryModel,
    /// The feature whose height is measured (the Duplo stud), if any.
    pub feature: Option<FeatureParams>,
    /// Points of the progressive-imaging curve (reconstruction error against scan time),
    /// 1 to [`MAX_PROGRESSIVE_STEPS`].
    pub progressive_steps: usize,
}

impl Default for ImagingConfig {
    fn default() -> ImagingConfig {
        ImagingConfig {
            pitch_mm: 0.1,
            reconstruction: crate::imaging::reconstruct::DEFAULT_MODEL,
            feature: None,
            progressive_steps: 10,
        }
    }
}

/// Why a scenario could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read or parsed.
    #[error(transparent)]
    File(#[from] JsonFileError),
    /// The rig description could not be loaded.
    #[error("{path}: rig: {source}")]
    Rig {
        /// The scenario file.
        path: PathBuf,
        /// The rig's own error (file, line, field).
        source: RigError,
    },
    /// A value that cannot run: a field of the scenario file, or the command-line flag that
    /// overrode it.
    #[error(transparent)]
    Invalid(#[from] InvalidValue),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenarioFile {
    name: String,
    #[serde(default)]
    description: String,
    rig: PathBuf,
    #[serde(default)]
    scene: Option<PathBuf>,
    #[serde(default)]
    truth: Option<PathBuf>,
    controller: PathBuf,
    trajectory: Trajectory,
    duration_s: f64,
    #[serde(default)]
    seed: u64,
    #[serde(default)]
    timing: TimingConfig,
    #[serde(default)]
    links: LinksConfig,
    #[serde(default)]
    imaging: ImagingConfig,
    #[serde(default)]
    power: PowerConfig,
    #[serde(default)]
    lead_in: LeadIn,
    #[serde(default)]
    faults: FaultsConfig,
    #[serde(default)]
    recording: RecordingConfig,
    #[serde(default)]
    outputs: OutputsConfig,
}

impl Scenario {
    /// Reads, parses and checks a scenario file.
    ///
    /// # Errors
    /// [`ScenarioError`] naming the file and, for parse errors, the line and column.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        Scenario::from_json_str(&json_file::read_text(path, "scenario")?, path)
    }

    /// Parses and checks a scenario; `origin` names it in errors and anchors relative paths.
    ///
    /// # Errors
    /// [`ScenarioError::File`] (parse), [`ScenarioError::Rig`] or [`ScenarioError::Invalid`].
    pub fn from_json_str(text: &str, origin: &Path) -> Result<Scenario, ScenarioError> {
        let file: ScenarioFile = json_file::parse(text, origin)?;
        let base = origin.parent().unwrap_or(Path::new("."));
        let rig = Rig::load(&base.join(&file.rig)).map_err(|source| ScenarioError::Rig {
            path: origin.to_owned(),
            source,
        })?;
        let scenario = Scenario {
            path: origin.to_owned(),
            name: file.name,
            description: file.description,
            rig,
            truth: file.truth.map(|truth| base.join(truth)),
            scene: file.scene.map(|scene| base.join(scene)),
            controller: base.join(file.controller),
            trajectory: file.trajectory,
            duration_s: file.duration_s,
            seed: file.seed,
            timing: file.timing,
            links: file.links,
            imaging: file.imaging,
            power: file.power,
            lead_in: file.lead_in,
            faults: file.faults,
            recording: file.recording,
            outputs: file.outputs,
        };
        scenario.check()?;
        Ok(scenario)
    }

    /// Checks every field's value, naming the scenario file and the field.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the scenario file and the field.
    pub fn check(&self) -> Result<(), ScenarioError> {
        self.check_values()
            .map_err(|invalid| invalid.in_file(&self.path).into())
    }

    /// Checks every field's value; the error names the field alone, for the caller to place
    /// in the file or on the flag that overrode it (`scanhil scan` checks again after its
    /// command-line overrides, so an override passes the same checks as the file).
    ///
    /// # Errors
    /// The first field whose value cannot run, with the value and what is allowed.
    pub fn check_values(&self) -> Result<(), Invalid> {
        let field = |(field, reason): (&'static str, String)| Invalid::new(field, reason);
        loop_limits::DURATION_S.check("duration_s", self.duration_s)?;
        self.timing.check(self.rig.period_s())?;
        let pitch = self.imaging.pitch_mm;
        if !(pitch.is_finite() && pitch > 0.0) {
            return Err(Invalid::new(
                "imaging.pitch_mm",
                format!("{pitch} mm must be positive and finite"),
            ));
        }
        let steps = self.imaging.progressive_steps;
        if !(1..=MAX_PROGRESSIVE_STEPS).contains(&steps) {
            return Err(Invalid::new(
                "imaging.progressive_steps",
                format!("{steps} is not between 1 and {MAX_PROGRESSIVE_STEPS}"),
            ));
        }
        if let Some(feature) = &self.imaging.feature {
            feature.check().map_err(|(field, reason)| {
                Invalid::new("imaging.feature", format!("{field}: {reason}"))
            })?;
        }
        self.trajectory
            .check(0.5 * self.rig.control_rate_hz)
            .map_err(field)?;
        self.power.check().map_err(field)?;
        self.lead_in.check().map_err(field)?;
        self.faults
            .check()
            .map_err(|error| Invalid::new(error.field, error.reason))?;
        self.recording.check()?;
        let links_are_emulated = self.links.spawn_emulator
            || self.links.fsm == NodeLink::Pty
            || self.links.sensor == NodeLink::Pty;
        if self.faults.sensor.is_active() && !links_are_emulated {
            return Err(Invalid::new(
                "faults.sensor",
                "sensor faults are injected into the emulated sensor: they need emulated \
                 devices (`pty` links or `spawn_emulator`)",
            ));
        }
        if self.scene.is_none() && links_are_emulated {
            return Err(Invalid::new(
                "scene",
                "emulated devices (`pty` links or `spawn_emulator`) need the scene the \
                 emulator serves; a scan of real devices sets both links to their URIs and \
                 `spawn_emulator` to false",
            ));
        }
        Ok(())
    }

    /// The scene file whose surface is the truth: `truth`, else the emulator's `scene`.
    #[must_use]
    pub fn truth_scene(&self) -> Option<&Path> {
        self.truth.as_deref().or(self.scene.as_deref())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn realtime() -> TimingConfig {
        TimingConfig {
            mode: TimingMode::Realtime,
            ..TimingConfig::default()
        }
    }

    #[test]
    fn real_time_options_are_checked_and_name_their_field() {
        let field = |timing: TimingConfig| timing.check(5e-5).err().map(|error| error.field);
        assert_eq!(field(realtime()), None);
        let lockstep_busy = TimingConfig {
            busy_poll: true,
            ..TimingConfig::default()
        };
        assert_eq!(field(lockstep_busy).as_deref(), Some("timing.mode"));
        let priority = TimingConfig {
            sched_fifo_priority: Some(100),
            ..realtime()
        };
        assert_eq!(
            field(priority).as_deref(),
            Some("timing.sched_fifo_priority")
        );
        let no_such_cpu = TimingConfig {
            emulator_cpu: Some(usize::MAX),
            ..realtime()
        };
        assert_eq!(field(no_such_cpu).as_deref(), Some("timing.emulator_cpu"));
        let one_cpu_for_two_spinners = TimingConfig {
            busy_poll: true,
            cpu: Some(0),
            emulator_cpu: Some(0),
            ..realtime()
        };
        assert_eq!(
            field(one_cpu_for_two_spinners).as_deref(),
            Some("timing.emulator_cpu")
        );
        let probe = TimingConfig {
            probe_s: -1.0,
            ..realtime()
        };
        assert_eq!(field(probe).as_deref(), Some("timing.probe_s"));
    }

    #[test]
    fn a_feature_that_cannot_be_measured_is_refused_with_the_file_and_field() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/scenarios/duplo-lissajous-dual-tone.json");
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(Scenario::from_json_str(&text, &path).is_ok());
        let inverted = text.replace(
            r#""plane_region": { "shape": "all" }"#,
            r#""plane_region": { "shape": "rect", "x_min_mm": 5, "x_max_mm": -5, "y_min_mm": -5, "y_max_mm": 5 }"#,
        );
        assert_ne!(inverted, text, "the fixture's plane region");
        let error = Scenario::from_json_str(&inverted, &path).unwrap_err();
        assert!(
            error.to_string().ends_with(
                "duplo-lissajous-dual-tone.json: field `imaging.feature`: plane_region: \
                 x_min_mm 5 is above x_max_mm -5"
            ),
            "{error}"
        );
    }

    #[test]
    fn a_recording_interface_that_is_no_interface_name_is_refused_with_the_file_and_field() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/scenarios/duplo-lissajous-dual-tone.json");
        let text = std::fs::read_to_string(&path).unwrap();
        let with = |recording: &str| {
            let edited = text.replacen('{', &format!("{{ \"recording\": {recording},"), 1);
            Scenario::from_json_str(&edited, &path)
        };
        let scenario = with(r#"{ "epoch": true, "iface": "can0" }"#).unwrap();
        assert_eq!(
            scenario.recording,
            RecordingConfig {
                epoch: true,
                iface: "can0".into()
            }
        );
        assert_eq!(
            Scenario::from_json_str(&text, &path).unwrap().recording,
            RecordingConfig {
                epoch: false,
                iface: "fsm".into()
            }
        );
        let error = with(r#"{ "iface": "can 0" }"#).unwrap_err().to_string();
        assert!(
            error.ends_with(
                "duplo-lissajous-dual-tone.json: field `recording.iface`: interface name \
                 `can 0` contains ' ' at byte 3 (no `/`, `:` or white space)"
            ),
            "{error}"
        );
    }

    #[test]
    fn outputs_are_all_written_unless_the_scenario_leaves_some_out() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/scenarios/duplo-lissajous-dual-tone.json");
        let text = std::fs::read_to_string(&path).unwrap();
        let with = |outputs: &str| {
            let edited = text.replacen('{', &format!("{{ \"outputs\": {outputs},"), 1);
            Scenario::from_json_str(&edited, &path)
        };
        assert_eq!(
            Scenario::from_json_str(&text, &path).unwrap().outputs,
            OutputsConfig {
                recordings: true,
                figures: true
            }
        );
        assert_eq!(
            with(r#"{ "figures": false }"#).unwrap().outputs,
            OutputsConfig {
                recordings: true,
                figures: false
            }
        );
        let error = with(r#"{ "plots": false }"#).unwrap_err().to_string();
        assert!(
            error.contains("duplo-lissajous-dual-tone.json") && error.contains("plots"),
            "{error}"
        );
    }

    #[test]
    fn the_emulator_gets_its_own_cpu_and_the_shared_settings() {
        let timing = TimingConfig {
            busy_poll: true,
            cpu: Some(0),
            emulator_cpu: Some(1),
            sched_fifo_priority: Some(80),
            ..realtime()
        };
        let emulator = timing.emulator_options();
        assert_eq!(emulator.cpu, Some(1));
        assert_eq!(timing.host_options().cpu, Some(0));
        assert!(emulator.busy_poll);
        assert_eq!(emulator.sched_fifo_priority, Some(80));
    }
}
