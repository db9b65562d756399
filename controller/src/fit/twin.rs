//! A fit written as the emulator's twin of the bench: a scene's plant sections
//! (`--write-scene`) and a rig's mirror section (`--write-rig`). The host links no emulator
//! code, so the files are edited as JSON, in the scene format of `emulator/src/scene.rs`
//! (per-axis `mirror.alpha` / `mirror.beta`, `amplifier`, `cross_talk`).
//!
//! - `mirror`: each axis' `dc_gain`, `natural_freq_rad_s`, `damping_ratio` and `delay_s`
//!   (eq. 4's `Ta`, at least one period: the emulator's command path is one period).
//! - A fitted first-order lag becomes the `amplifier` part's `bandwidth_hz` (the mean of the
//!   axes': the amplifiers drive both coils alike). Without one, a base scene's amplifier keeps
//!   its bandwidth and its lag `1 / (2 pi bandwidth)` is taken off the delay, which then held
//!   it (to first order in frequency).
//! - `cross_talk`: the fitted couplings; the part is switched on when either stands out
//!   ([`CrossTalkFit::stands_out`]).
//! - A second mode is reported, not written: the fit's mode adds to eq. 4 (modal
//!   superposition) where the scene's `second_mode` part is in series with it, with an
//!   anti-resonance; the one converts to the other exactly (numerator `s^2 + 2 zeta_z wz s +
//!   wz^2` of the sum), which is not written yet.
//!
//! Everything else of a base scene (surface, optics, sensor, limits, noise, seed) is kept, so
//! the twin scans what the bench scanned.

use serde_json::{Value, json};

use super::models::ModelKind;
use super::{AxisFit, CrossTalkFit};
use crate::trajectory::SensingAxis;

/// The amplifier bandwidth a scene's amplifier has when it states none, Hz (the emulator's).
const DEFAULT_AMPLIFIER_HZ: f64 = 10_000.0;

/// What was decided while writing, for the report.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TwinNotes {
    /// One line per decision.
    pub notes: Vec<String>,
}

/// The scene of the fitted plant: `base` (the scene the bench was served from, when known)
/// with its plant sections replaced, or a new scene of the mirror alone at `rate_hz`.
#[must_use]
pub fn scene(
    base: Option<&Value>,
    name: &str,
    rate_hz: f64,
    fits: &[AxisFit],
    cross_talk: &[CrossTalkFit],
) -> (Value, TwinNotes) {
    let period_s = 1.0 / rate_hz;
    let mut notes = Vec::new();
    let mut scene = base.cloned().unwrap_or_else(|| {
        json!({
            "name": name,
            "control_rate_hz": rate_hz,
            "seed": 0,
            "parts": ["axes"],
        })
    });
    scene["name"] = json!(name);
    scene["description"] = json!(format!(
        "Twin of the identified mirror (scanhil identify --fit): eq. 4 per axis as fitted{}.",
        base.map_or(String::new(), |b| format!(
            ", the rest of scene `{}`",
            b.get("name").and_then(Value::as_str).unwrap_or("?")
        ))
    ));
    let mut parts: Vec<String> = scene
        .get("parts")
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(|p| p.as_str().map(str::to_owned))
                .collect()
        })
        .unwrap_or_default();
    let lags: Vec<f64> = fits.iter().filter_map(|f| f.params.lag_rad_s).collect();
    let base_amplifier_hz = (parts.iter().any(|p| p == "amplifier")).then(|| {
        scene
            .pointer("/amplifier/bandwidth_hz")
            .and_then(Value::as_f64)
            .unwrap_or(DEFAULT_AMPLIFIER_HZ)
    });
    let amplifier_hz = if lags.len() == fits.len() && !lags.is_empty() {
        let hz = lags.iter().sum::<f64>() / lags.len() as f64 / std::f64::consts::TAU;
        notes.push(format!(
            "the fitted lag is the amplifier's current loop: bandwidth {hz:.1} Hz"
        ));
        scene["amplifier"]["bandwidth_hz"] = json!(hz);
        if !parts.iter().any(|p| p == "amplifier") {
            parts.push("amplifier".into());
        }
        None
    } else {
        if let Some(hz) = base_amplifier_hz {
            notes.push(format!(
                "no lag fitted: the base scene's amplifier ({hz} Hz) keeps its bandwidth and \
                 its lag is taken off the fitted delay"
            ));
        }
        base_amplifier_hz
    };
    let mut mirror = scene.get("mirror").cloned().unwrap_or_else(|| json!({}));
    // A fitted axis' own section (and its alias) is replaced; the common values go only when
    // every axis is fitted, so an axis not measured keeps what the base said of it.
    let fitted = |axis: SensingAxis| fits.iter().any(|f| f.axis == axis);
    let mut stale = Vec::new();
    if SensingAxis::BOTH.iter().all(|&axis| fitted(axis)) {
        stale.extend(["dc_gain", "natural_freq_rad_s", "damping_ratio", "delay_s"]);
    }
    for (axis, alias) in [(SensingAxis::Alpha, "y"), (SensingAxis::Beta, "x")] {
        if fitted(axis) {
            stale.extend([axis.name(), alias]);
        } else {
            notes.push(format!(
                "{}: not measured: as the base scene has it (the paper's without one)",
                axis.name()
            ));
        }
    }
    if let Some(object) = mirror.as_object_mut() {
        for key in stale {
            object.remove(key);
        }
    }
    for fit in fits {
        let p = &fit.params;
        let amplifier_lag_s = amplifier_hz.map_or(0.0, |hz| 1.0 / (std::f64::consts::TAU * hz));
        let delay_s = twin_delay_s(p.delay_s - amplifier_lag_s, fit.std_of("delay_s"), period_s);
        if delay_s != p.delay_s - amplifier_lag_s {
            notes.push(format!(
                "{}: the delay {:.3e} +- {:.1e} s is not resolved beyond one period: written \
                 as one period ({period_s:.3e} s)",
                fit.axis.name(),
                p.delay_s - amplifier_lag_s,
                fit.std_of("delay_s"),
            ));
        }
        if fit.chosen == ModelKind::Eq4Mode || fit.chosen == ModelKind::Eq4ModeLag {
            notes.push(format!(
                "{}: the fitted second mode is not written (the scene's `second_mode` part \
                 is a series form it is not yet converted to)",
                fit.axis.name()
            ));
        }
        mirror[fit.axis.name()] = json!({
            "dc_gain": p.dc_gain,
            "natural_freq_rad_s": p.natural_freq_rad_s,
            "damping_ratio": p.damping_ratio,
            "delay_s": delay_s,
        });
    }
    scene["mirror"] = mirror;
    let significant = cross_talk.iter().any(CrossTalkFit::stands_out);
    for c in cross_talk {
        // The coupling on `to`'s input from `from`'s: `cross_talk.<to>_from_<from>`.
        let key = match (c.to, c.from) {
            (SensingAxis::Alpha, SensingAxis::Beta) => "alpha_from_beta",
            (SensingAxis::Beta, SensingAxis::Alpha) => "beta_from_alpha",
            _ => continue,
        };
        scene["cross_talk"][key] = json!(c.coefficient);
    }
    if significant && !parts.iter().any(|p| p == "cross_talk") {
        parts.push("cross_talk".into());
        notes.push("the cross-talk stands out: part `cross_talk` on".into());
    }
    scene["control_rate_hz"] = json!(rate_hz);
    scene["parts"] = json!(parts);
    (scene, TwinNotes { notes })
}

/// The delay an axis is written with: the fitted `delay_s` (standard uncertainty `std_s`) when
/// it stands more than three uncertainties beyond one period, else one period (the emulator's
/// command path, which no scene can shorten; a delay the data does not tell from it is it).
fn twin_delay_s(delay_s: f64, std_s: f64, period_s: f64) -> f64 {
    if delay_s > period_s + 3.0 * std_s {
        delay_s
    } else {
        period_s
    }
}

/// `base` (a rig file) with its mirror section's cross-talk set to the fitted one and its
/// control rate to the rate identified at. The coils' resistance and the power limit are not
/// in a frequency response: they stay as the base states them (the paper's when it has no
/// mirror section).
#[must_use]
pub fn rig(base: &Value, rate_hz: f64, cross_talk: &[CrossTalkFit]) -> Value {
    let mut rig = base.clone();
    if rig.get("mirror").is_none_or(Value::is_null) {
        rig["mirror"] = json!({
            "coil_resistance_ohm": 2.0172,
            "power_limit_w": 30.0,
        });
    }
    for c in cross_talk {
        let key = match (c.to, c.from) {
            (SensingAxis::Alpha, SensingAxis::Beta) => "alpha_from_beta",
            (SensingAxis::Beta, SensingAxis::Alpha) => "beta_from_alpha",
            _ => continue,
        };
        rig["mirror"]["cross_talk"][key] = json!(c.coefficient);
    }
    rig["control_rate_hz"] = json!(rate_hz);
    rig
}

#[cfg(test)]
mod tests {
    use super::super::Estimate;
    use super::super::models::ModelParams;
    use super::*;

    const T: f64 = 1e-4;

    fn fit(axis: SensingAxis, params: ModelParams, delay_std_s: f64) -> AxisFit {
        AxisFit {
            axis,
            chosen: params.kind(),
            selection: String::new(),
            params,
            estimates: vec![Estimate {
                name: "delay_s",
                value: params.delay_s,
                std: delay_std_s,
                unit: "s",
            }],
            candidates: Vec::new(),
            residuals: Vec::new(),
            period_s: T,
        }
    }

    fn coupling(from: SensingAxis, to: SensingAxis, coefficient: f64, std: f64) -> CrossTalkFit {
        CrossTalkFit {
            from,
            to,
            coefficient,
            std,
            quadrature: 0.0,
            level_db: 20.0 * coefficient.abs().log10(),
            per_frequency: Vec::new(),
        }
    }

    fn differing(k: f64, delay_s: f64) -> ModelParams {
        ModelParams {
            dc_gain: k,
            delay_s,
            ..ModelParams::paper(T)
        }
    }

    #[test]
    fn each_axis_gets_its_own_section_and_the_base_keeps_the_rest() {
        let base = json!({
            "name": "bench", "control_rate_hz": 10000.0, "seed": 5,
            "parts": ["axes", "optics"],
            "mirror": {"dc_gain": 11.4, "delay_s": 2e-4, "y": {"dc_gain": 3.0}, "axes": ["alpha"]},
            "surface": {"kind": "plane"},
        });
        let fits = [
            fit(SensingAxis::Alpha, differing(9.8, 1.5e-4), 1e-6),
            fit(SensingAxis::Beta, differing(12.6, 1e-4), 1e-6),
        ];
        let (scene, notes) = scene(Some(&base), "twin", 1e4, &fits, &[]);
        assert_eq!(scene["name"], "twin");
        assert_eq!(scene["seed"], 5);
        assert_eq!(scene["surface"], base["surface"]);
        assert_eq!(scene["parts"], json!(["axes", "optics"]));
        assert_eq!(scene["mirror"]["axes"], json!(["alpha"]));
        for key in ["dc_gain", "delay_s", "y"] {
            assert!(scene["mirror"].get(key).is_none(), "{key} left: {scene:#}");
        }
        assert_eq!(scene["mirror"]["alpha"]["dc_gain"], 9.8);
        assert_eq!(scene["mirror"]["alpha"]["delay_s"], 1.5e-4);
        assert_eq!(scene["mirror"]["beta"]["dc_gain"], 12.6);
        assert_eq!(scene["mirror"]["beta"]["natural_freq_rad_s"], 140.68);
        assert!(notes.notes.is_empty(), "{notes:?}");
    }

    #[test]
    fn an_axis_not_measured_keeps_what_the_base_says_of_it() {
        let base = json!({"name": "b", "parts": ["axes"],
                          "mirror": {"dc_gain": 9.0, "x": {"damping_ratio": 0.05},
                                     "y": {"dc_gain": 3.0}}});
        let fits = [fit(SensingAxis::Alpha, differing(9.8, T), 1e-6)];
        let (written, notes) = scene(Some(&base), "twin", 1e4, &fits, &[]);
        let mirror = &written["mirror"];
        assert_eq!(mirror["dc_gain"], 9.0);
        assert_eq!(mirror["x"], json!({"damping_ratio": 0.05}));
        assert!(mirror.get("y").is_none(), "{mirror:#}");
        assert_eq!(mirror["alpha"]["dc_gain"], 9.8);
        assert_eq!(notes.notes.len(), 1, "{notes:?}");
        assert!(
            notes.notes[0].starts_with("beta: not measured"),
            "{notes:?}"
        );
    }

    #[test]
    fn a_delay_not_resolved_beyond_one_period_is_written_as_one_period() {
        assert_eq!(twin_delay_s(1.2e-4, 1e-5, T), T);
        assert_eq!(twin_delay_s(0.9e-4, 1e-6, T), T);
        assert_eq!(twin_delay_s(1.2e-4, 5e-6, T), 1.2e-4);
        // At the edge: three uncertainties beyond is not enough.
        assert_eq!(twin_delay_s(1.3e-4, 1e-5, T), T);
        let fits = [fit(SensingAxis::Alpha, differing(9.8, 1.2e-4), 1e-5)];
        let (scene, notes) = scene(None, "twin", 1e4, &fits, &[]);
        assert_eq!(scene["mirror"]["alpha"]["delay_s"], T);
        assert_eq!(notes.notes.len(), 2, "{notes:?}");
        assert!(notes.notes[1].starts_with("alpha: the delay"), "{notes:?}");
    }

    #[test]
    fn a_base_amplifiers_lag_comes_off_the_delay_and_a_fitted_lag_becomes_the_amplifier() {
        let base = json!({"name": "b", "parts": ["axes", "amplifier"],
                          "amplifier": {"bandwidth_hz": 1000.0}});
        let lag_s = 1.0 / (std::f64::consts::TAU * 1000.0);
        let fits = [fit(SensingAxis::Alpha, differing(9.8, 2e-4 + lag_s), 1e-6)];
        let (written, _) = scene(Some(&base), "twin", 1e4, &fits, &[]);
        let delay = written["mirror"]["alpha"]["delay_s"].as_f64().unwrap();
        assert!((delay - 2e-4).abs() < 1e-12, "{delay}");
        assert_eq!(written["amplifier"]["bandwidth_hz"], 1000.0);

        let lagged = |axis, hz: f64| {
            let params = ModelParams {
                lag_rad_s: Some(std::f64::consts::TAU * hz),
                ..differing(9.8, T)
            };
            fit(axis, params, 1e-6)
        };
        let fits = [
            lagged(SensingAxis::Alpha, 4000.0),
            lagged(SensingAxis::Beta, 6000.0),
        ];
        let (written, notes) = scene(None, "twin", 1e4, &fits, &[]);
        let hz = written["amplifier"]["bandwidth_hz"].as_f64().unwrap();
        assert!((hz - 5000.0).abs() < 1e-9, "{hz}");
        assert_eq!(written["parts"], json!(["axes", "amplifier"]));
        assert_eq!(written["mirror"]["beta"]["delay_s"], T);
        assert!(notes.notes[0].contains("5000.0 Hz"), "{notes:?}");
    }

    #[test]
    fn cross_talk_is_written_and_switched_on_only_when_it_stands_out() {
        let fits = [fit(SensingAxis::Alpha, differing(9.8, T), 1e-6)];
        let couplings = [
            coupling(SensingAxis::Alpha, SensingAxis::Beta, 0.12, 1e-3),
            coupling(SensingAxis::Beta, SensingAxis::Alpha, -0.08, 1e-3),
        ];
        let (written, _) = scene(None, "twin", 1e4, &fits, &couplings);
        assert_eq!(written["cross_talk"]["beta_from_alpha"], 0.12);
        assert_eq!(written["cross_talk"]["alpha_from_beta"], -0.08);
        assert_eq!(written["parts"], json!(["axes", "cross_talk"]));
        // Within three uncertainties of zero, or below the analyser's floor however sure.
        for (coefficient, std) in [(2e-3, 1e-3), (-9e-4, 1e-9)] {
            let faint = [coupling(
                SensingAxis::Alpha,
                SensingAxis::Beta,
                coefficient,
                std,
            )];
            let (written, _) = scene(None, "twin", 1e4, &fits, &faint);
            assert_eq!(written["parts"], json!(["axes"]));
            assert_eq!(written["cross_talk"]["beta_from_alpha"], coefficient);
        }
    }

    #[test]
    fn the_rig_gets_the_fitted_cross_talk_and_rate_and_keeps_the_rest() {
        let couplings = [coupling(SensingAxis::Beta, SensingAxis::Alpha, 0.07, 1e-3)];
        let base = json!({"name": "bench", "mirror": {"coil_resistance_ohm": 3.0}});
        let written = rig(&base, 2736.0, &couplings);
        assert_eq!(written["name"], "bench");
        assert_eq!(written["control_rate_hz"], 2736.0);
        assert_eq!(written["mirror"]["coil_resistance_ohm"], 3.0);
        assert_eq!(written["mirror"]["cross_talk"]["alpha_from_beta"], 0.07);
        let written = rig(&json!({"name": "bare", "mirror": null}), 1e4, &couplings);
        assert_eq!(written["mirror"]["power_limit_w"], 30.0);
        assert_eq!(written["mirror"]["coil_resistance_ohm"], 2.0172);
    }
}
