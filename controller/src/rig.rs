//! A rig description (`fixtures/rigs/*.json`): what the host must know of the bench it runs
//! against, real or emulated, and nothing of how an emulator would model it.
//!
//! - `control_rate_hz`: the loop rate the mirror node runs at;
//! - `scanner`: the mechanical setup (paper eq. 1-3's `y_FSM`, `z_FSM`, `alpha` and the
//!   receiver) and the calibration of the angle sensor and the distance;
//! - `sensor`: the ILD 2300's measuring rate and range, the extra values it sends after each
//!   distance and the baud rate of its RS422 line (refused when they do not fit it), or `null`
//!   for a mirror-only rig;
//! - `mirror` (optional): the coils' resistance, the power limit and the cross-talk, from which
//!   the host estimates a trajectory's coil power before a run ([`crate::power_budget`]);
//! - `bus` (optional): the CAN bus the mirror node is on (bit rate, transit), from which
//!   `scanhil design` takes the highest loop rate the bus carries and the delay it adds.
//!
//! A scan of real devices needs only this file (and a scenario naming it); an emulator's scene
//! file is for the emulator alone. When the host starts the emulator it checks the emulated
//! devices against the rig (control rate, whether a sensor is served and at what rate), as it
//! checks a real sensor's read-back configuration, and refuses a mismatch naming both values.

use std::path::{Path, PathBuf};

use scanhil_geometry::ScannerSetup;
use scanhil_protocol::ild::command::{AddValue, AddValueSet, BAUD_RATES_UNCHECKED, MeasuringRate};
use scanhil_protocol::ild::stream::{FACTORY_BAUD, check_baud};
use scanhil_protocol::ild::{IldOutputInfo, MeasuringRange};
use scanhil_protocol::validation::Allowed;
use serde::{Deserialize, Serialize};

use crate::imaging::reconstruct::ScanSample;
use scanhil_scene::json_file::{self, JsonFileError};

/// A loaded, checked rig description.
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    /// Where it was loaded from.
    pub path: PathBuf,
    /// Short name (reports).
    pub name: String,
    /// Free text.
    pub description: String,
    /// The control loop's rate, Hz.
    pub control_rate_hz: f64,
    /// The scanner's geometry and calibration.
    pub scanner: RigScanner,
    /// The distance sensor, if the rig has one.
    pub sensor: Option<RigSensor>,
    /// The mirror's coils and power limit, if known (without them no power estimate).
    pub mirror: Option<RigMirror>,
    /// The mirror node's CAN bus, if stated.
    pub bus: Option<RigBus>,
}

/// The CAN bus between the host and the mirror node.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigBus {
    /// Nominal bit rate, bit/s (classical CAN: the loop's frames at their worst-case length).
    pub bitrate_bps: f64,
    /// Delay a command arrives after the one period of the loop's timing convention (the
    /// frames' time on the bus, the adapters' latency), s; 0 when the node applies commands on
    /// its period boundary.
    #[serde(default)]
    pub transit_s: f64,
}

impl RigBus {
    fn check(&self) -> Result<(), (&'static str, String)> {
        if !(self.bitrate_bps.is_finite() && self.bitrate_bps > 0.0) {
            return Err((
                "bus.bitrate_bps",
                format!("{} bit/s must be positive and finite", self.bitrate_bps),
            ));
        }
        if !(self.transit_s.is_finite() && (0.0..1.0).contains(&self.transit_s)) {
            return Err((
                "bus.transit_s",
                format!("{} s must be in [0, 1)", self.transit_s),
            ));
        }
        Ok(())
    }
}

/// The mirror's coils as the host's power estimate needs them (the dynamics are eq. 4, the
/// controller file's nominal plant).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigMirror {
    /// Resistance of one coil (actuator) axis, ohm; both axes are alike.
    pub coil_resistance_ohm: f64,
    /// The limit on the coils' mean power (both axes together), W.
    pub power_limit_w: f64,
    /// The current amplifiers' limit per coil axis, A (absent: not checked).
    #[serde(default)]
    pub amplifier_current_limit_a: Option<f64>,
    /// The cross-talk on the sensing axes' inputs (0 = none).
    #[serde(default)]
    pub cross_talk: RigCrossTalk,
}

/// Cross-talk between the sensing axes' inputs: the mirror's alpha axis receives
/// `u_alpha + alpha_from_beta * u_beta`, beta `u_beta + beta_from_alpha * u_alpha`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RigCrossTalk {
    /// Share of beta's input that acts on alpha.
    pub alpha_from_beta: f64,
    /// Share of alpha's input that acts on beta.
    pub beta_from_alpha: f64,
}

impl RigMirror {
    /// The paper's mirror: R = 30 W / (10 / |G(j 2 pi 52)|)^2 = 2.0172 ohm (full-range 52 Hz
    /// sines on both sensing axes at 30 W), 30 W, 4 A amplifiers (the emulator's), cross-talk 0.1
    /// (-20 dB) both ways.
    pub const PAPER: RigMirror = RigMirror {
        coil_resistance_ohm: 2.0172,
        power_limit_w: 30.0,
        amplifier_current_limit_a: Some(4.0),
        cross_talk: RigCrossTalk {
            alpha_from_beta: 0.1,
            beta_from_alpha: 0.1,
        },
    };

    fn check(&self) -> Result<(), (&'static str, String)> {
        for (field, value) in [
            ("mirror.coil_resistance_ohm", self.coil_resistance_ohm),
            ("mirror.power_limit_w", self.power_limit_w),
            (
                "mirror.amplifier_current_limit_a",
                self.amplifier_current_limit_a.unwrap_or(1.0),
            ),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err((field, format!("{value} must be positive and finite")));
            }
        }
        let c = self.cross_talk;
        for (field, value) in [
            ("mirror.cross_talk.alpha_from_beta", c.alpha_from_beta),
            ("mirror.cross_talk.beta_from_alpha", c.beta_from_alpha),
        ] {
            if !(value.is_finite() && value.abs() < 1.0) {
                return Err((field, format!("{value} must be finite and within (-1, 1)")));
            }
        }
        Ok(())
    }
}

/// The scanner's geometry and calibration.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RigScanner {
    /// Where mirror and receiver sit relative to the laser (defaults: the paper's setup).
    pub setup: ScannerSetup,
    /// Corrections applied to every sample before reconstruction.
    pub calibration: Calibration,
}

/// Corrections of the measured angles and distance: a true deflection is
/// `gain * (reading - offset)`, a true distance `z_meas + distance_offset_mm`. The identity
/// (the default) leaves every value bit for bit as it was.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Calibration {
    /// The alpha angle sensor's reading at zero deflection, urad.
    pub alpha_offset_urad: f64,
    /// The beta angle sensor's reading at zero deflection, urad.
    pub beta_offset_urad: f64,
    /// True alpha deflection per unit of reading.
    pub alpha_gain: f64,
    /// True beta deflection per unit of reading.
    pub beta_gain: f64,
    /// Added to every measured distance, mm.
    pub distance_offset_mm: f64,
}

impl Default for Calibration {
    fn default() -> Calibration {
        Calibration {
            alpha_offset_urad: 0.0,
            beta_offset_urad: 0.0,
            alpha_gain: 1.0,
            beta_gain: 1.0,
            distance_offset_mm: 0.0,
        }
    }
}

impl Calibration {
    /// The sample with its angles and distance corrected.
    #[must_use]
    pub fn apply(&self, sample: ScanSample) -> ScanSample {
        ScanSample {
            t_s: sample.t_s,
            d_alpha_rad: self.alpha_gain * (sample.d_alpha_rad - self.alpha_offset_urad * 1e-6),
            d_beta_rad: self.beta_gain * (sample.d_beta_rad - self.beta_offset_urad * 1e-6),
            z_meas_mm: sample.z_meas_mm.map(|z| z + self.distance_offset_mm),
        }
    }

    fn check(&self) -> Result<(), (&'static str, String)> {
        let offset = Allowed::closed(-MAX_ANGLE_OFFSET_URAD, MAX_ANGLE_OFFSET_URAD, "urad");
        let gain = Allowed::above(0.0, MAX_ANGLE_GAIN, "");
        let distance = Allowed::closed(-MAX_DISTANCE_OFFSET_MM, MAX_DISTANCE_OFFSET_MM, "mm");
        for (field, allowed, value) in [
            (
                "scanner.calibration.alpha_offset_urad",
                offset,
                self.alpha_offset_urad,
            ),
            (
                "scanner.calibration.beta_offset_urad",
                offset,
                self.beta_offset_urad,
            ),
            ("scanner.calibration.alpha_gain", gain, self.alpha_gain),
            ("scanner.calibration.beta_gain", gain, self.beta_gain),
            (
                "scanner.calibration.distance_offset_mm",
                distance,
                self.distance_offset_mm,
            ),
        ] {
            allowed
                .check(field, value)
                .map_err(|invalid| (field, invalid.reason))?;
        }
        Ok(())
    }
}

/// The largest angle offset a calibration may correct, urad: a whole radian, far beyond a
/// mirror's range.
pub const MAX_ANGLE_OFFSET_URAD: f64 = 1e6;

/// The largest angle gain a calibration may apply (a reading off by a factor of 100).
pub const MAX_ANGLE_GAIN: f64 = 100.0;

/// The largest distance offset a calibration may add, mm: ten times the ILD 2300-100's range.
pub const MAX_DISTANCE_OFFSET_MM: f64 = 1000.0;

/// The distance sensor: an ILD 2300.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigSensor {
    /// Measuring rate, Hz: one of the ILD 2300's rates (1.5, 2.5, 5, 10, 20, 30, 49.14 kHz;
    /// `MEASRATE` words the last `49`).
    pub measuring_rate_hz: f64,
    /// Start of the measuring range (SMR), mm from the sensor's reference.
    pub range_start_mm: f64,
    /// Length of the measuring range (MR), mm.
    pub range_span_mm: f64,
    /// The extra values sent after each distance (`OUTADD_RS422`; default none): with
    /// `counter`, samples are placed by the sensor's measured-value counter, without it by
    /// their arrival alone.
    #[serde(default)]
    pub extra_values: AddValueSet,
    /// The baud rate of the sensor's RS422 line (default: the factory 691 200). The values per
    /// cycle must fit it (the manual's rule `BR > 33 x MR x m`): checked when the rig loads.
    #[serde(default = "factory_baud")]
    pub baud: u32,
}

fn factory_baud() -> u32 {
    FACTORY_BAUD
}

impl RigSensor {
    /// The ILD 2300-100 at 20 kHz, as in the paper: the distance alone at the factory baud
    /// rate (all that 691 200 baud carries at 20 kHz).
    pub const ILD2300_100_AT_20_KHZ: RigSensor = RigSensor {
        measuring_rate_hz: 20_000.0,
        range_start_mm: 70.0,
        range_span_mm: 100.0,
        extra_values: AddValueSet::NONE,
        baud: FACTORY_BAUD,
    };

    /// Whether each distance comes with the sensor's measured-value counter.
    #[must_use]
    pub fn sends_counter(&self) -> bool {
        self.extra_values.contains(AddValue::Counter)
    }

    /// The values of an output cycle: the distance, then the extra values.
    #[must_use]
    pub fn output(&self) -> IldOutputInfo {
        IldOutputInfo::distance_then(self.extra_values)
    }

    /// The measuring range, for converting raw values to mm.
    #[must_use]
    pub fn range(&self) -> MeasuringRange {
        MeasuringRange {
            start_mm: self.range_start_mm,
            span_mm: self.range_span_mm,
        }
    }
}

/// Why a rig description could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    /// The file could not be read or parsed.
    #[error(transparent)]
    File(#[from] JsonFileError),
    /// A field has a value no rig can have.
    #[error("{path}: field `{field}`: {reason}")]
    Invalid {
        /// The rig file.
        path: PathBuf,
        /// The offending field.
        field: &'static str,
        /// Why.
        reason: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RigFile {
    name: String,
    #[serde(default)]
    description: String,
    control_rate_hz: f64,
    #[serde(default)]
    scanner: RigScanner,
    /// Required, `null` for none: a forgotten sensor section is an error, not "no sensor".
    #[serde(deserialize_with = "Option::deserialize")]
    sensor: Option<RigSensor>,
    #[serde(default)]
    mirror: Option<RigMirror>,
    #[serde(default)]
    bus: Option<RigBus>,
}

impl Rig {
    /// Reads, parses and checks a rig description.
    ///
    /// # Errors
    /// [`RigError`] naming the file and, for parse errors, the line and column.
    pub fn load(path: &Path) -> Result<Rig, RigError> {
        Rig::from_json_str(&json_file::read_text(path, "rig")?, path)
    }

    /// Parses and checks a rig description; `origin` names it in errors.
    ///
    /// # Errors
    /// [`RigError::File`] (parse) or [`RigError::Invalid`].
    pub fn from_json_str(text: &str, origin: &Path) -> Result<Rig, RigError> {
        let file: RigFile = json_file::parse(text, origin)?;
        let invalid = |(field, reason): (&'static str, String)| RigError::Invalid {
            path: origin.to_owned(),
            field,
            reason,
        };
        scanhil_protocol::loop_limits::CONTROL_RATE_HZ
            .check("control_rate_hz", file.control_rate_hz)
            .map_err(|error| invalid(("control_rate_hz", error.reason)))?;
        file.scanner
            .setup
            .validate()
            .map_err(|error| invalid(("scanner.setup", error.to_string())))?;
        file.scanner.calibration.check().map_err(invalid)?;
        if let Some(sensor) = &file.sensor {
            check_sensor(sensor).map_err(invalid)?;
        }
        if let Some(mirror) = &file.mirror {
            mirror.check().map_err(invalid)?;
        }
        if let Some(bus) = &file.bus {
            bus.check().map_err(invalid)?;
        }
        Ok(Rig {
            path: origin.to_owned(),
            name: file.name,
            description: file.description,
            control_rate_hz: file.control_rate_hz,
            scanner: file.scanner,
            sensor: file.sensor,
            mirror: file.mirror,
            bus: file.bus,
        })
    }

    /// The control period, s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        1.0 / self.control_rate_hz
    }

    /// The rig as JSON for reports.
    #[must_use]
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "name": self.name,
            "file": self.path.display().to_string(),
            "control_rate_hz": self.control_rate_hz,
            "scanner": self.scanner,
            "sensor": self.sensor,
            "mirror": self.mirror,
            "bus": self.bus,
        })
    }
}

fn check_sensor(sensor: &RigSensor) -> Result<(), (&'static str, String)> {
    let rate = sensor.measuring_rate_hz;
    if MeasuringRate::from_hz(rate).is_none() {
        return Err((
            "sensor.measuring_rate_hz",
            format!(
                "{rate} Hz is not an ILD 2300 rate (MEASRATE {} kHz, the last 49.14)",
                MeasuringRate::words()
            ),
        ));
    }
    if !BAUD_RATES_UNCHECKED.contains(&sensor.baud) {
        return Err((
            "sensor.baud",
            format!(
                "{} is not an ILD 2300 baud rate (BAUDRATE {BAUD_RATES_UNCHECKED:?})",
                sensor.baud
            ),
        ));
    }
    let output = sensor.output();
    check_baud(
        rate,
        &output.words(),
        output.values.len() as u32,
        sensor.baud,
    )
    .map_err(|shortfall| ("sensor.extra_values", shortfall.to_string()))?;
    if !(sensor.range_start_mm.is_finite() && sensor.range_start_mm >= 0.0) {
        return Err((
            "sensor.range_start_mm",
            format!(
                "{} mm must be finite and not negative",
                sensor.range_start_mm
            ),
        ));
    }
    if !(sensor.range_span_mm.is_finite() && sensor.range_span_mm > 0.0) {
        return Err((
            "sensor.range_span_mm",
            format!("{} mm must be positive and finite", sensor.range_span_mm),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Rig, RigError> {
        Rig::from_json_str(text, Path::new("rig.json"))
    }

    #[test]
    fn the_shipped_rigs_load() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/rigs");
        let paper = Rig::load(&dir.join("paper-bench.json")).unwrap();
        assert_eq!(paper.sensor, Some(RigSensor::ILD2300_100_AT_20_KHZ));
        assert_eq!(paper.scanner.setup, ScannerSetup::default());
        assert!((paper.period_s() - 50e-6).abs() < 1e-15);
        assert_eq!(paper.mirror, Some(RigMirror::PAPER));
        let mirror_only = Rig::load(&dir.join("paper-mirror-only.json")).unwrap();
        assert_eq!(mirror_only.sensor, None);
        assert_eq!(mirror_only.mirror, Some(RigMirror::PAPER));
    }

    #[test]
    fn a_rate_the_sensor_does_not_have_is_refused_by_field() {
        let error = parse(
            r#"{"name": "r", "control_rate_hz": 20000,
                "sensor": {"measuring_rate_hz": 12000, "range_start_mm": 70, "range_span_mm": 100}}"#,
        )
        .unwrap_err()
        .to_string();
        assert!(error.contains("sensor.measuring_rate_hz"), "{error}");
        assert!(error.contains("12000"), "{error}");
    }

    #[test]
    fn values_that_do_not_fit_the_sensors_line_are_refused_with_the_numbers() {
        let sensor = |extra: &str, rate: u32, baud: u32| {
            format!(
                r#"{{"name": "r", "control_rate_hz": 20000,
                    "sensor": {{"measuring_rate_hz": {rate}, "range_start_mm": 70,
                                "range_span_mm": 100, "extra_values": {extra}, "baud": {baud}}}}}"#
            )
        };
        let error = parse(&sensor(r#"["counter"]"#, 20_000, 691_200))
            .unwrap_err()
            .to_string();
        assert_eq!(
            error,
            "rig.json: field `sensor.extra_values`: the ILD line at 691200 baud cannot carry 2 \
             value(s) per cycle (DIST1 COUNTER) at 20 kHz: the manual's rule BR > 33 x MR x m / \
             ODR needs more than 1320000 baud"
        );
        assert!(parse(&sensor(r#"["counter"]"#, 20_000, 921_600)).is_err());
        let fits = parse(&sensor(r#"["counter"]"#, 10_000, 691_200)).unwrap();
        assert!(fits.sensor.unwrap().sends_counter());
        let alone = parse(&sensor("[]", 20_000, 691_200)).unwrap();
        assert!(!alone.sensor.unwrap().sends_counter());
        let error = parse(&sensor("[]", 20_000, 500_000))
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("sensor.baud") && error.contains("500000"),
            "{error}"
        );
        let error = parse(&sensor(r#"["speed"]"#, 20_000, 691_200))
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("`speed` is not an ILD 2300 extra value"),
            "{error}"
        );
    }

    #[test]
    fn bad_numbers_name_their_field() {
        for (text, field) in [
            (
                r#"{"name": "r", "control_rate_hz": 0, "sensor": null}"#,
                "control_rate_hz",
            ),
            (
                r#"{"name": "r", "control_rate_hz": 1000, "sensor": null,
                    "scanner": {"calibration": {"alpha_gain": -1}}}"#,
                "scanner.calibration.alpha_gain",
            ),
            (
                r#"{"name": "r", "control_rate_hz": 1000, "sensor": null,
                    "scanner": {"setup": {"y_fsm_mm": -5}}}"#,
                "scanner.setup",
            ),
            (
                r#"{"name": "r", "control_rate_hz": 1000, "sensor": null,
                    "mirror": {"coil_resistance_ohm": -2.0, "power_limit_w": 30}}"#,
                "mirror.coil_resistance_ohm",
            ),
            (
                r#"{"name": "r", "control_rate_hz": 1000, "sensor": null,
                    "mirror": {"coil_resistance_ohm": 2.0, "power_limit_w": 0}}"#,
                "mirror.power_limit_w",
            ),
            (
                r#"{"name": "r", "control_rate_hz": 1000, "sensor": null,
                    "mirror": {"coil_resistance_ohm": 2.0, "power_limit_w": 30,
                               "cross_talk": {"alpha_from_beta": 1.5}}}"#,
                "mirror.cross_talk.alpha_from_beta",
            ),
            (
                r#"{"name": "r", "control_rate_hz": 1000, "sensor": null,
                    "bus": {"bitrate_bps": 0}}"#,
                "bus.bitrate_bps",
            ),
            (
                r#"{"name": "r", "control_rate_hz": 1000, "sensor": null,
                    "bus": {"bitrate_bps": 1e6, "transit_s": -1e-4}}"#,
                "bus.transit_s",
            ),
        ] {
            let error = parse(text).unwrap_err().to_string();
            assert!(error.contains(field), "{field}: {error}");
        }
    }

    #[test]
    fn a_missing_sensor_section_is_an_error_not_a_default() {
        let error = parse(r#"{"name": "r", "control_rate_hz": 1000}"#)
            .unwrap_err()
            .to_string();
        assert!(error.contains("sensor"), "{error}");
        assert!(error.starts_with("rig.json:"), "{error}");
    }

    #[test]
    fn the_identity_calibration_changes_no_bit_and_others_correct() {
        let sample = ScanSample {
            t_s: 0.25,
            d_alpha_rad: 0.012_345_678_9,
            d_beta_rad: -0.009_876_543_21,
            z_meas_mm: Some(131.123_456_7),
        };
        assert_eq!(Calibration::default().apply(sample), sample);
        let calibration = Calibration {
            alpha_offset_urad: 100.0,
            beta_offset_urad: -50.0,
            alpha_gain: 2.0,
            beta_gain: 0.5,
            distance_offset_mm: -1.0,
        };
        let corrected = calibration.apply(sample);
        assert!((corrected.d_alpha_rad - 2.0 * (sample.d_alpha_rad - 1e-4)).abs() < 1e-15);
        assert!((corrected.d_beta_rad - 0.5 * (sample.d_beta_rad + 5e-5)).abs() < 1e-15);
        assert!((corrected.z_meas_mm.unwrap() - 130.123_456_7).abs() < 1e-12);
    }
}
