//! Controller design for a plant and a control rate (`scanhil design`): the paper's PID tuning
//! rule ([`alpha_tuning`]) and a dual-tone rule in the form of eq. 5 ([`tones`]), each
//! designed on the discrete loop at the rate asked (the plant's hold and its delay of one
//! period, plus any extra delay the plant or the rig's bus states), discretised with the
//! method asked ([`crate::discretise`]), checked for stability on its poles and against the
//! stated margins, and described by the figures a designer reads: crossover, phase and gain
//! margins, sensitivity peak, bandwidth, peaking of T, T and the error at the drive
//! frequencies, the predicted tracking error of the trajectory, the closed loop's slowest pole.
//! [`reach`] says how far a rate carries each rule.
//!
//! A design is a [`ControllerSettings`] like any controller file, with the plant it was
//! designed for as its nominal plant, so `scanhil analyze` and `scanhil scan` read it as they
//! read the paper's.

pub mod alpha_tuning;
pub mod reach;
pub mod tones;

use std::path::PathBuf;

use serde::Serialize;

use crate::discretise::Method;
use crate::loop_analysis::{GainCrossover, NominalLoop, ZPoint, format_poles};
use crate::plant_model::PlantModel;
use crate::settings::{ControllerSettings, LawSettings, SettingsError};
use crate::steady_state::{PredictedTracking, predict};
use crate::trajectory::Trajectory;
use alpha_tuning::AlphaTuning;
use tones::ToneRule;

/// What a design must keep.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Margins {
    /// The smallest phase margin over every gain crossover, degrees (the angle between `L`
    /// and -1 where `|L| = 1`).
    pub phase_deg: f64,
    /// The smallest gain margin over the phase crossovers where `|L| < 1`, dB.
    pub gain_db: f64,
}

impl Default for Margins {
    /// 45 degrees (the paper's PID) and 6 dB.
    fn default() -> Margins {
        Margins {
            phase_deg: 45.0,
            gain_db: 6.0,
        }
    }
}

/// What is designed for.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignRequest {
    /// The controller's name in the written file.
    pub name: String,
    /// The plant (eq. 4, with its extra delay).
    pub plant: PlantModel,
    /// The control rate, Hz.
    pub rate_hz: f64,
    /// The discretisation.
    pub method: Method,
    /// The margins a design must keep.
    pub margins: Margins,
    /// The trajectory whose tracking is predicted (and whose drive frequencies a dual-tone's
    /// tones sit on).
    pub trajectory: Option<Trajectory>,
    /// The coil current limit written into the controller, A.
    pub coil_current_limit_a: f64,
}

/// A design rule with its choices.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "rule", rename_all = "snake_case")]
pub enum Rule {
    /// The paper's alpha-tuned PID.
    AlphaTuning(AlphaTuning),
    /// Resonant tones on the equalised plant.
    DualTone(ToneRule),
}

/// T and the error of a sine at one drive frequency.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AtDrive {
    /// Frequency, Hz.
    pub f_hz: f64,
    /// |T|, dB.
    pub t_db: f64,
    /// arg T, degrees.
    pub t_deg: f64,
    /// |S| = |1 - T|: a sine's error over its amplitude.
    pub error_relative: f64,
}

/// The figures of a designed loop (one axis, the nominal plant).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignFigures {
    /// The highest gain crossover, Hz.
    pub crossover_hz: Option<f64>,
    /// Every gain crossover with its phase margin (signed as `scanhil analyze` reports it).
    pub gain_crossovers: Vec<GainCrossover>,
    /// The smallest phase margin, as an angle from -1, degrees (`None`: `|L|` never crosses 1).
    pub phase_margin_deg: Option<f64>,
    /// The smallest gain margin where `|L| < 1`, dB (`None`: no such phase crossover).
    pub gain_margin_db: Option<f64>,
    /// max |S| = 1 / (the smallest distance of L from -1), dB.
    pub sensitivity_peak_db: f64,
    /// Where |S| peaks, Hz.
    pub sensitivity_peak_hz: f64,
    /// The highest frequency where |T| falls through -3 dB, Hz.
    pub bandwidth_3db_hz: Option<f64>,
    /// max |T|, dB (the peaking).
    pub peak_db: f64,
    /// Where |T| peaks, Hz.
    pub peak_hz: f64,
    /// T and the error at the drive frequencies.
    pub at_drive: Vec<AtDrive>,
    /// The trajectory's steady-state tracking error the loop predicts (rms over peak).
    pub predicted_tracking: Option<PredictedTracking>,
    /// The largest closed-loop pole magnitude.
    pub spectral_radius: f64,
    /// How long the slowest closed-loop pole takes to decay to 1e-3, s.
    pub settle_s: f64,
    /// The closed-loop poles.
    pub closed_loop_poles: Vec<ZPoint>,
}

/// A design that meets its margins.
#[derive(Debug, Clone)]
pub struct Design {
    /// The controller file's contents.
    pub settings: ControllerSettings,
    /// The rule and the choices that made it.
    pub rule: Rule,
    /// Its loop's figures.
    pub figures: DesignFigures,
}

/// Why no controller was designed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DesignError {
    /// An input is not usable.
    #[error("{option}: {reason}")]
    Invalid {
        /// The option or field.
        option: String,
        /// Why.
        reason: String,
    },
    /// The rule gave no design that is stable and meets the margins.
    #[error("refused: {reason}; poles {}", format_poles(.poles))]
    Refused {
        /// What failed.
        reason: String,
        /// The offending poles: unstable ones, or the closed loop's slowest.
        poles: Vec<ZPoint>,
    },
}

/// The slowest closed-loop poles shown when a stable loop misses its margins.
const POLES_SHOWN: usize = 4;

impl DesignRequest {
    /// Checks the rate, the plant, the margins and the trajectory.
    ///
    /// # Errors
    /// [`DesignError::Invalid`] naming the option.
    pub fn check(&self) -> Result<(), DesignError> {
        let invalid = |option: &str, reason: String| DesignError::Invalid {
            option: option.into(),
            reason,
        };
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(invalid(
                "rate_hz",
                format!("{} Hz must be positive and finite", self.rate_hz),
            ));
        }
        let p = &self.plant;
        for (field, value) in [
            ("plant.dc_gain", p.dc_gain),
            ("plant.natural_freq_rad_s", p.natural_freq_rad_s),
            ("plant.damping_ratio", p.damping_ratio),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(invalid(
                    field,
                    format!("{value} must be positive and finite"),
                ));
            }
        }
        if !(p.extra_delay_s.is_finite() && p.extra_delay_s >= 0.0) {
            return Err(invalid(
                "plant.extra_delay_s",
                format!("{} s must be finite and not negative", p.extra_delay_s),
            ));
        }
        if !(self.margins.phase_deg.is_finite() && (0.0..180.0).contains(&self.margins.phase_deg)) {
            return Err(invalid(
                "phase_margin_deg",
                format!("{} must be in [0, 180)", self.margins.phase_deg),
            ));
        }
        if !(self.margins.gain_db.is_finite() && self.margins.gain_db >= 0.0) {
            return Err(invalid(
                "gain_margin_db",
                format!("{} must be finite and not negative", self.margins.gain_db),
            ));
        }
        if let Some(trajectory) = &self.trajectory {
            trajectory
                .check(self.rate_hz / 2.0)
                .map_err(|(field, reason)| invalid(field, reason))?;
        }
        Ok(())
    }

    /// The period, s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        1.0 / self.rate_hz
    }

    /// The trajectory's drive frequencies: its tones above DC, lowest first.
    #[must_use]
    pub fn drive_hz(&self) -> Vec<f64> {
        self.trajectory
            .as_ref()
            .map(|t| {
                t.tones(self.rate_hz / 2.0)
                    .iter()
                    .map(|tone| tone.f_hz)
                    .filter(|f| *f > 0.0)
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The controller file of a law.
    fn settings(&self, law: LawSettings, description: String) -> ControllerSettings {
        ControllerSettings {
            name: self.name.clone(),
            description,
            control_rate_hz: self.rate_hz,
            law,
            discretisation: self.method.clone(),
            axis_command_limit_a: None,
            coil_current_limit_a: self.coil_current_limit_a,
            plant: self.plant,
            origin: PathBuf::from(&self.name),
        }
    }

    /// Designs with `rule` and checks the result.
    ///
    /// # Errors
    /// [`DesignError::Invalid`] for unusable choices, [`DesignError::Refused`] with the poles
    /// when the design is unstable or misses the margins.
    pub fn design(&self, rule: &Rule) -> Result<Design, DesignError> {
        let design = self.candidate(rule)?;
        check_margins(&design.figures, self.margins)?;
        Ok(design)
    }

    /// The rule's controller and its figures, stable but with the margins unchecked.
    fn candidate(&self, rule: &Rule) -> Result<Design, DesignError> {
        self.check()?;
        let invalid = |(option, reason): (&str, String)| DesignError::Invalid {
            option: option.into(),
            reason,
        };
        let (law, description) = match rule {
            Rule::AlphaTuning(tuning) => {
                tuning.check().map_err(invalid)?;
                (
                    LawSettings::Pid(tuning.pid(&self.plant)),
                    self.describe_pid(tuning),
                )
            }
            Rule::DualTone(tones) => {
                tones.check(self.rate_hz).map_err(invalid)?;
                let params = tones.design(&self.plant, self.period_s(), &self.method);
                (LawSettings::DualTone(params), self.describe_tones(tones))
            }
        };
        let settings = self.settings(law, description);
        let figures = evaluate(&settings, self.trajectory.as_ref(), &self.drive_hz())?;
        Ok(Design {
            settings,
            rule: rule.clone(),
            figures,
        })
    }

    /// The alpha-tuned PID with the highest crossover that keeps the margins, between 0.45
    /// Nyquist and twice the plant's resonance (the rule's `|G| ~ K ws^2 / w^2`, the mass line,
    /// is a third off there and worse below): crossovers 5 % apart from the top, the first
    /// that keeps the margins refined to 0.1 % against the one above it.
    ///
    /// # Errors
    /// [`DesignError::Refused`] when none does, with the poles of the one that came closest
    /// (the largest phase margin).
    pub fn highest_pid(&self, template: &AlphaTuning) -> Result<Design, DesignError> {
        self.check()?;
        let resonance_hz = self.plant.natural_freq_rad_s / std::f64::consts::TAU;
        let (low, high) = (2.0 * resonance_hz, 0.45 * self.rate_hz / 2.0);
        let at = |crossover_hz: f64| {
            Rule::AlphaTuning(AlphaTuning {
                crossover_hz,
                ..*template
            })
        };
        let mut closest: Option<(f64, f64, DesignError)> = None;
        let (mut above, mut crossover_hz) = (None, high);
        while crossover_hz >= low {
            let candidate = self.candidate(&at(crossover_hz));
            let margin = match &candidate {
                Ok(design) => design.figures.phase_margin_deg.unwrap_or(180.0),
                Err(DesignError::Refused { .. }) => f64::NEG_INFINITY,
                Err(error) => return Err(error.clone()),
            };
            match candidate
                .and_then(|design| check_margins(&design.figures, self.margins).map(|()| design))
            {
                Ok(mut design) => {
                    // Refine between this crossover and the failing one above it.
                    let (mut good, mut bad) = (crossover_hz, above.unwrap_or(crossover_hz));
                    while bad / good > 1.001 {
                        let mid = (good * bad).sqrt();
                        match self.design(&at(mid)) {
                            Ok(better) => (good, design) = (mid, better),
                            Err(_) => bad = mid,
                        }
                    }
                    return Ok(design);
                }
                Err(error) => {
                    if closest.as_ref().is_none_or(|(m, _, _)| margin > *m) {
                        closest = Some((margin, crossover_hz, error));
                    }
                }
            }
            above = Some(crossover_hz);
            crossover_hz /= 1.05;
        }
        let (margin, at_hz, error) = closest.ok_or_else(|| DesignError::Refused {
            reason: format!(
                "no crossover to try between {low:.1} Hz (twice the plant's resonance) and \
                 {high:.1} Hz (0.45 x Nyquist)"
            ),
            poles: Vec::new(),
        })?;
        let DesignError::Refused { reason, poles } = error else {
            unreachable!("only refusals are kept")
        };
        Err(DesignError::Refused {
            reason: format!(
                "no alpha-tuned PID (alpha {}) keeps {} deg / {} dB at {} Hz with its crossover \
                 between {low:.1} and {high:.1} Hz; the closest, at {at_hz:.1} Hz \
                 ({margin:.1} deg): {reason}",
                template.alpha, self.margins.phase_deg, self.margins.gain_db, self.rate_hz
            ),
            poles,
        })
    }

    fn describe_pid(&self, tuning: &AlphaTuning) -> String {
        format!(
            "Alpha-tuned series PID (the paper's rule, Table II's at 211 Hz) for crossover {} Hz, \
             alpha {}, integrator at crossover / {}, derivative stopped at {} alpha crossover; {}",
            tuning.crossover_hz,
            tuning.alpha,
            tuning.integrator_ratio,
            tuning.taming,
            self.describe_plant()
        )
    }

    fn describe_tones(&self, tones: &ToneRule) -> String {
        format!(
            "Dual-tone in eq. 5's form: resonant tones at {:?} Hz (width {} Hz, damping {}) on \
             the plant equalised by a zero pair on its resonance and a roll-off pair at {} Hz; {}",
            tones.tones_hz,
            tones.width_hz,
            tones.damping,
            tones.rolloff_hz,
            self.describe_plant()
        )
    }

    /// The plant, rate and method a design was made for.
    fn describe_plant(&self) -> String {
        let p = &self.plant;
        format!(
            "plant K {}, ws {} rad/s, zeta {}, extra delay {} s; at {} Hz, {}.",
            p.dc_gain,
            p.natural_freq_rad_s,
            p.damping_ratio,
            p.extra_delay_s,
            self.rate_hz,
            self.method.name()
        )
    }
}

/// Builds `settings` (its stability checks) and reads its nominal loop's figures.
///
/// # Errors
/// [`DesignError::Refused`] with the unstable poles of the controller or the closed loop;
/// [`DesignError::Invalid`] when the law does not form sections.
pub fn evaluate(
    settings: &ControllerSettings,
    trajectory: Option<&Trajectory>,
    drive_hz: &[f64],
) -> Result<DesignFigures, DesignError> {
    let controller = settings.build().map_err(|error| match error {
        SettingsError::Unstable { what, poles, .. } => DesignError::Refused {
            reason: format!("{what} is unstable"),
            poles,
        },
        other => DesignError::Invalid {
            option: "law".into(),
            reason: other.to_string(),
        },
    })?;
    let nominal = settings.nominal_loop(controller.axis());
    Ok(figures(&nominal, trajectory, drive_hz))
}

/// The figures of a stable nominal loop.
fn figures(
    nominal: &NominalLoop,
    trajectory: Option<&Trajectory>,
    drive_hz: &[f64],
) -> DesignFigures {
    let report = nominal.report(drive_hz);
    let period_s = nominal.period_s();
    let settle_s = if report.spectral_radius > 0.0 {
        1e-3f64.ln() / report.spectral_radius.ln() * period_s
    } else {
        0.0
    };
    DesignFigures {
        crossover_hz: report.crossover_hz,
        phase_margin_deg: report
            .gain_crossovers
            .iter()
            .map(|c| c.phase_margin_deg.abs())
            .reduce(f64::min),
        gain_crossovers: report.gain_crossovers.clone(),
        gain_margin_db: report.gain_margin_db,
        sensitivity_peak_db: report.sensitivity_peak_db,
        sensitivity_peak_hz: report.sensitivity_peak_hz,
        bandwidth_3db_hz: report.bandwidth_3db_hz,
        peak_db: report.peak_db,
        peak_hz: report.peak_hz,
        at_drive: report
            .at
            .iter()
            .map(|t| AtDrive {
                f_hz: t.f_hz,
                t_db: t.magnitude_db,
                t_deg: t.phase_deg,
                error_relative: (nominal.loop_gain(t.f_hz) + 1.0).inv().norm(),
            })
            .collect(),
        predicted_tracking: trajectory.map(|t| predict(nominal, t)),
        spectral_radius: report.spectral_radius,
        settle_s,
        closed_loop_poles: report.closed_loop_poles,
    }
}

/// Refuses a stable loop that misses the margins, with its slowest poles.
fn check_margins(figures: &DesignFigures, margins: Margins) -> Result<(), DesignError> {
    let mut misses = Vec::new();
    if let Some(pm) = figures.phase_margin_deg
        && pm < margins.phase_deg
    {
        let at = figures
            .gain_crossovers
            .iter()
            .find(|c| c.phase_margin_deg.abs() == pm)
            .map_or(f64::NAN, |c| c.f_hz);
        misses.push(format!(
            "phase margin {pm:.1} deg at {at:.1} Hz is below the {} deg asked",
            margins.phase_deg
        ));
    }
    if let Some(gm) = figures.gain_margin_db
        && gm < margins.gain_db
    {
        misses.push(format!(
            "gain margin {gm:.1} dB is below the {} dB asked",
            margins.gain_db
        ));
    }
    if misses.is_empty() {
        return Ok(());
    }
    let mut poles = figures.closed_loop_poles.clone();
    poles.sort_by(|a, b| b.abs.total_cmp(&a.abs));
    poles.truncate(POLES_SHOWN);
    Err(DesignError::Refused {
        reason: misses.join(", "),
        poles,
    })
}
