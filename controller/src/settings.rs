//! Controller settings (`fixtures/controllers/*.json`): the control law, its discretisation,
//! limits and the nominal plant. Building a controller checks its discrete poles and the
//! nominal closed loop, and refuses an unstable choice with the offending poles.

use std::path::{Path, PathBuf};

use crate::continuous::FactoredTf;
use crate::discretise::{Method, discretise};
use crate::dual_tone::DualToneParams;
use crate::loop_analysis::{NominalLoop, ZPoint, format_poles};
use crate::pid::{Pid, PidParams};
use crate::plant_model::PlantModel;
use crate::scan_controller::{AxisController, AxisLaw, ScanController};
use crate::sos::Cascade;
use scanhil_scene::json_file::{self, JsonFileError};

/// The control law and its coefficients (`"kind": "pid"` or `"kind": "dual_tone"`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LawSettings {
    /// Table II PID.
    Pid(PidParams),
    /// Eq. 5 dual-tone controller.
    DualTone(DualToneParams),
}

/// One controller file.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerSettings {
    /// Short name for reports.
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Control rate, Hz (20 kHz in the paper).
    #[serde(default = "default_rate_hz")]
    pub control_rate_hz: f64,
    /// The control law.
    pub law: LawSettings,
    /// How the continuous law is discretised.
    pub discretisation: Method,
    /// Per-axis command limit, A (default: coil limit / sqrt 2, so the rotation never clips).
    #[serde(default)]
    pub axis_command_limit_a: Option<f64>,
    /// Coil current limit, A.
    #[serde(default = "default_coil_limit_a")]
    pub coil_current_limit_a: f64,
    /// The nominal plant used for the closed-loop check (default: eq. 4 as printed).
    #[serde(default)]
    pub plant: PlantModel,
    /// The file the settings came from (named in every error).
    #[serde(skip)]
    pub origin: PathBuf,
}

fn default_rate_hz() -> f64 {
    20_000.0
}

fn default_coil_limit_a() -> f64 {
    6.0
}

/// Why a controller file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum SettingsError {
    /// The file could not be read or parsed.
    #[error(transparent)]
    File(#[from] JsonFileError),
    /// A field's value is not usable.
    #[error("{path}: field `{field}`: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The field.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The discretised controller or the nominal closed loop is unstable.
    #[error("{path}: {what} is unstable with {method}: poles {}", format_poles(.poles))]
    Unstable {
        /// The file.
        path: PathBuf,
        /// "the discrete controller" or "the nominal closed loop".
        what: String,
        /// The discretisation method.
        method: String,
        /// The offending poles (|z| >= 1).
        poles: Vec<ZPoint>,
    },
}

impl ControllerSettings {
    /// Reads and parses a settings file (no stability check yet: see [`Self::build`]).
    pub fn load(path: &Path) -> Result<Self, SettingsError> {
        Self::from_json_str(&json_file::read_text(path, "controller settings")?, path)
    }

    /// Parses settings from JSON text; `origin` names the source in errors.
    pub fn from_json_str(text: &str, origin: &Path) -> Result<Self, SettingsError> {
        let settings: Self = json_file::parse(text, origin)?;
        let settings = Self {
            origin: origin.to_owned(),
            ..settings
        };
        settings.check()?;
        Ok(settings)
    }

    fn check(&self) -> Result<(), SettingsError> {
        let origin = &self.origin;
        let invalid = |field: &str, reason: String| SettingsError::Invalid {
            path: origin.to_owned(),
            field: field.into(),
            reason,
        };
        let positive = |field: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(invalid(
                    field,
                    format!("must be a positive number, got {v}"),
                ))
            }
        };
        scanhil_protocol::loop_limits::CONTROL_RATE_HZ
            .check("control_rate_hz", self.control_rate_hz)
            .map_err(|error| invalid("control_rate_hz", error.reason))?;
        positive("coil_current_limit_a", self.coil_current_limit_a)?;
        if let Some(l) = self.axis_command_limit_a {
            positive("axis_command_limit_a", l)?;
        }
        positive("plant.dc_gain", self.plant.dc_gain)?;
        positive("plant.natural_freq_rad_s", self.plant.natural_freq_rad_s)?;
        if let Method::TustinPrewarped { prewarp_hz } = &self.discretisation {
            let nyquist = self.control_rate_hz / 2.0;
            if prewarp_hz.is_empty() || prewarp_hz.iter().any(|f| !(*f > 0.0 && *f < nyquist)) {
                return Err(invalid(
                    "discretisation.prewarp_hz",
                    format!(
                        "needs frequencies between 0 and Nyquist ({nyquist} Hz), got {prewarp_hz:?}"
                    ),
                ));
            }
        }
        match &self.law {
            LawSettings::Pid(p) => {
                for (field, v) in [
                    ("law.kp", p.kp),
                    ("law.kd", p.kd),
                    ("law.ki", p.ki),
                    ("law.wt_rad_s", p.wt_rad_s),
                ] {
                    positive(field, v)?;
                }
            }
            LawSettings::DualTone(d) => d
                .check()
                .map_err(|(field, reason)| invalid(&format!("law.{field}"), reason))?,
        }
        Ok(())
    }

    /// The control period, s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        1.0 / self.control_rate_hz
    }

    /// The continuous control law.
    #[must_use]
    pub fn continuous(&self) -> FactoredTf {
        match &self.law {
            LawSettings::Pid(p) => p.continuous(),
            LawSettings::DualTone(d) => d.continuous(),
        }
    }

    /// The per-axis command limit, A.
    #[must_use]
    pub fn axis_limit_a(&self) -> f64 {
        self.axis_command_limit_a
            .unwrap_or(self.coil_current_limit_a * std::f64::consts::FRAC_1_SQRT_2)
    }

    /// One axis' discrete controller, unchecked.
    pub fn axis_controller(&self) -> Result<AxisController, SettingsError> {
        let origin = &self.origin;
        let limit = self.axis_limit_a() / scanhil_protocol::plant_units::AMPS_PER_INPUT_UNIT;
        let law = match &self.law {
            LawSettings::Pid(p) => {
                AxisLaw::Pid(Pid::new(p, &self.discretisation, self.period_s(), limit))
            }
            LawSettings::DualTone(d) => {
                let tf = d.continuous();
                let sections = tf.sections().map_err(|e| SettingsError::Invalid {
                    path: origin.to_owned(),
                    field: "law".into(),
                    reason: e.to_string(),
                })?;
                AxisLaw::Cascade(Cascade::new(
                    tf.gain,
                    sections
                        .iter()
                        .map(|s| discretise(s, &self.discretisation, self.period_s()))
                        .collect(),
                ))
            }
        };
        Ok(AxisController::new(law, limit))
    }

    /// The nominal loop of one axis.
    #[must_use]
    pub fn nominal_loop(&self, axis: &AxisController) -> NominalLoop {
        NominalLoop::new(
            axis.linear(),
            self.plant.discrete(self.period_s()),
            self.period_s(),
        )
    }

    /// Discretises and checks stability: the controller's poles (|z| <= 1, the integrator's
    /// z = 1 allowed) and the nominal closed loop (all |z| < 1).
    pub fn build(&self) -> Result<ScanController, SettingsError> {
        let origin = &self.origin;
        let axis = self.axis_controller()?;
        let unstable = |what: &str, poles: Vec<ZPoint>| SettingsError::Unstable {
            path: origin.to_owned(),
            what: what.into(),
            method: self.discretisation.name(),
            poles,
        };
        let t = self.period_s();
        let bad: Vec<ZPoint> = axis
            .linear()
            .poles()
            .into_iter()
            .filter(|p| p.norm() > 1.0 + 1e-12)
            .map(|p| ZPoint::new(p, t))
            .collect();
        if !bad.is_empty() {
            return Err(unstable("the discrete controller", bad));
        }
        let bad: Vec<ZPoint> = self
            .nominal_loop(&axis)
            .closed_loop_poles()
            .into_iter()
            .filter(|p| p.norm() >= 1.0)
            .map(|p| ZPoint::new(p, t))
            .collect();
        if !bad.is_empty() {
            return Err(unstable("the nominal closed loop", bad));
        }
        Ok(ScanController::new(axis, self.coil_current_limit_a, t))
    }
}
