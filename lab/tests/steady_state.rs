//! The paper's scans at steady state (issue: steady-state scans), in process (the same frames
//! as over ptys: `bit_for_bit.rs`): after the lead-in, the dual-tone with its tones on the
//! drive tracks the full-range 52/27 Hz Lissajous under 1 % on both axes, as the nominal loop
//! predicts; Table I as printed tracks as its detuned tones predict; the raster runs without a
//! saturated period in its frame; and at a tenth of the frame the Lissajous covers more of the
//! field than the raster, its preview already near its final error (Fig. 6).
//!
//! Each figure is asserted against the nominal loop's prediction within a band, so a control
//! regression (a detuned tone, a lost lead-in) fails; `a_detuned_tone_fails_the_check` keeps
//! that proof.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use scanhil_controller::run::plan::ScanPlan;
use scanhil_controller::run::scenario::Scenario;
use scanhil_controller::scan_controller::{AxisController, AxisLaw, ScanController};
use scanhil_controller::settings::ControllerSettings;
use scanhil_controller::sos::{Cascade, Section};
use serde_json::Value;

fn scenario(name: &str) -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/scenarios")
        .join(name);
    Scenario::load(&path).expect("the shipped scenario loads")
}

/// Runs `scenario` in process into a temporary folder; returns its report.
fn run(scenario: &Scenario) -> Value {
    let dir = tempfile::tempdir().expect("a temporary folder");
    scanhil_lab::in_process::run(scenario, Some(dir.path())).expect("the scan runs");
    let report = std::fs::read_to_string(dir.path().join("report.json")).expect("report");
    serde_json::from_str(&report).expect("report.json is JSON")
}

fn lissajous() -> &'static Value {
    static REPORT: OnceLock<Value> = OnceLock::new();
    REPORT.get_or_init(|| run(&scenario("duplo-lissajous-dual-tone.json")))
}

fn raster() -> &'static Value {
    static REPORT: OnceLock<Value> = OnceLock::new();
    REPORT.get_or_init(|| run(&scenario("duplo-raster-pid.json")))
}

fn number(report: &Value, pointer: &str) -> f64 {
    report
        .pointer(pointer)
        .and_then(Value::as_f64)
        .unwrap_or_else(|| panic!("{pointer} is not a number in the report"))
}

/// The steady-state checks of a scan's report: the frame starts after a lead-in, no period
/// of the frame saturated, each axis' tracking error over the frame is within `band` times
/// the nominal loop's prediction (too good fails as well as too bad: a prediction that no
/// longer describes the loop is a regression too), and under `target` when one is given.
fn steady_state(report: &Value, band: (f64, f64), target: Option<f64>) -> Result<(), String> {
    if number(report, "/frame/start_s") <= 0.0 {
        return Err("the frame starts with the loop: no lead-in".into());
    }
    let saturated = number(report, "/periods/saturated_in_frame");
    if saturated > 0.0 {
        return Err(format!("{saturated} saturated periods in the frame"));
    }
    for axis in ["alpha", "beta"] {
        let measured = number(
            report,
            &format!("/tracking_error/frame/{axis}/rms_relative"),
        );
        let predicted = number(
            report,
            &format!("/predicted_tracking_error/{axis}_rms_relative"),
        );
        let ratio = measured / predicted;
        if !(band.0..=band.1).contains(&ratio) {
            return Err(format!(
                "{axis}: measured {measured:.5}, predicted {predicted:.5}: ratio {ratio:.3} \
                 outside {band:?}"
            ));
        }
        if let Some(target) = target
            && measured >= target
        {
            return Err(format!(
                "{axis}: measured {measured:.5} is not under the {:.1} % target",
                100.0 * target
            ));
        }
    }
    Ok(())
}

#[test]
fn the_dual_tone_tracks_the_full_range_lissajous_under_one_per_cent() {
    let report = lissajous();
    // Measured 0.72 / 0.74 % against 0.70 / 0.72 % predicted (the rest: cross-talk, the
    // amplifiers' 10 kHz loop, noise).
    steady_state(report, (0.97, 1.10), Some(0.01)).unwrap();
    // The whole field, the paper's 9.8 x 15.2 mm, and the stud at its height.
    let (nx, ny) = (
        number(report, "/imaging/grid/nx"),
        number(report, "/imaging/grid/ny"),
    );
    assert!(
        (95.0..=100.0).contains(&nx) && (150.0..=156.0).contains(&ny),
        "{nx} x {ny}"
    );
    let height = number(report, "/imaging/feature/height_mm");
    assert!((height - 4.663).abs() < 0.03, "stud {height} mm");
    assert_eq!(
        number(report, "/power/check/factor"),
        1.0,
        "no shrink needed"
    );
}

#[test]
fn table_i_as_printed_tracks_as_its_detuned_tones_predict() {
    let report = run(&scenario("duplo-lissajous-dual-tone-table-i.json"));
    // Measured 6.2 / 15.0 % against 5.9 / 14.9 % predicted.
    steady_state(&report, (0.97, 1.10), None).unwrap();
    assert!(number(&report, "/tracking_error/frame/beta/rms_relative") > 0.1);
}

#[test]
fn the_raster_runs_its_frame_without_saturation_as_its_harmonics_predict() {
    let report = raster();
    // The fast axis: 4.46 % against 4.38 % predicted (|S| at 34 and 102 Hz); the slow axis
    // carries the fast one's cross-talk, which the one-axis prediction leaves out.
    let measured = number(report, "/tracking_error/frame/alpha/rms_relative");
    let predicted = number(report, "/predicted_tracking_error/alpha_rms_relative");
    assert!(
        (0.97..=1.10).contains(&(measured / predicted)),
        "{measured} / {predicted}"
    );
    assert_eq!(number(report, "/periods/saturated_in_frame"), 0.0);
    assert!(number(report, "/frame/start_s") > 0.0);
}

#[test]
fn at_a_tenth_of_the_frame_the_lissajous_gives_the_better_overview() {
    let first =
        |report: &Value, field: &str| number(report, &format!("/imaging/progressive/0/{field}"));
    let last = |report: &Value, field: &str| {
        let steps = report["imaging"]["progressive"]
            .as_array()
            .map_or(0, Vec::len);
        number(
            report,
            &format!("/imaging/progressive/{}/{field}", steps - 1),
        )
    };
    let (lissajous, raster) = (lissajous(), raster());
    assert!((first(lissajous, "t_s") - 0.1).abs() < 1e-9);
    assert!((first(raster, "t_s") - 0.05).abs() < 1e-9);
    let coverage = (
        first(lissajous, "coverage_fraction"),
        first(raster, "coverage_fraction"),
    );
    assert!(
        coverage.0 > 2.0 * coverage.1,
        "coverage at 10 %: {coverage:?}"
    );
    // The preview's error against the truth, over its final value: the Lissajous is nearly
    // there after a tenth of its frame, the raster is not.
    let near_final = |report: &Value| first(report, "image_rms_mm") / last(report, "image_rms_mm");
    let (l, r) = (near_final(lissajous), near_final(raster));
    assert!(
        l < 1.3 && r > 1.5 && l < r,
        "error at 10 % over final: {l:.2} / {r:.2}"
    );
}

#[test]
fn a_detuned_tone_fails_the_check() {
    // The shipped controller with its 52 Hz tone moved to 52.5 Hz.
    let mut detuned = scenario("duplo-lissajous-dual-tone.json");
    let text = std::fs::read_to_string(&detuned.controller).expect("the controller file");
    let changed = text.replace(
        "\"tone_poles_at_hz\": [27.0, 52.0]",
        "\"tone_poles_at_hz\": [27.0, 52.5]",
    );
    assert_ne!(changed, text, "the controller places its tones");
    let dir = tempfile::tempdir().expect("a temporary folder");
    let file: PathBuf = dir.path().join("detuned.json");
    std::fs::write(&file, changed).expect("writing the controller");
    detuned.controller = file;
    detuned.duration_s = 0.2;
    let error = steady_state(&run(&detuned), (0.97, 1.10), Some(0.01)).unwrap_err();
    assert!(
        error.contains("alpha") && error.contains("target"),
        "{error}"
    );
}

#[test]
fn a_wrong_sign_controller_never_scans() {
    // The dual-tone's gain k negated: positive feedback around the mirror. The host refuses
    // it before the loop (its nominal closed loop is unstable), so no scan can pass the
    // steady-state checks with it.
    let mut wrong = scenario("duplo-lissajous-dual-tone.json");
    let text = std::fs::read_to_string(&wrong.controller).expect("the controller file");
    let changed = text.replace("\"k\": 179.75", "\"k\": -179.75");
    assert_ne!(changed, text, "the controller has Table I's gain");
    let dir = tempfile::tempdir().expect("a temporary folder");
    let file: PathBuf = dir.path().join("wrong-sign.json");
    std::fs::write(&file, changed).expect("writing the controller");
    wrong.controller = file;
    wrong.duration_s = 0.05;
    let out = tempfile::tempdir().expect("a temporary folder");
    let error = scanhil_lab::in_process::run(&wrong, Some(out.path()))
        .expect_err("a wrong-sign controller must not run");
    let message = format!("{error:#}");
    assert!(message.contains("unstable"), "{message}");
    assert!(
        !out.path().join("report.json").exists(),
        "refused before any scan was written"
    );
}

/// Runs the dual-tone Lissajous (0.2 s frame) with `lag_deg` of phase lag added to the
/// controller at the nominal loop's crossover (a delay of whole periods), as an
/// implementation that lags its own model would run it: the plan, and so the predicted
/// tracking, is the correct controller's. Returns whether the check `ControllerSettings::build`
/// makes before any scan (the nominal closed loop's poles) passes the lagging controller, and
/// the scan's report.
fn run_lagging_dual_tone(lag_deg: f64) -> (bool, Value) {
    let mut scenario = scenario("duplo-lissajous-dual-tone.json");
    scenario.duration_s = 0.2;
    let settings = ControllerSettings::load(&scenario.controller).expect("the controller file");
    let mut plan = ScanPlan::new(&scenario).expect("the shipped controller plans");
    let axis = plan.controller.axis().clone();
    let nominal = settings.nominal_loop(&axis);
    let period_s = nominal.period_s();
    // Crossover: the highest frequency where |L| falls through 1 (52.5 Hz: above its tones
    // the dual-tone's loop gain is below 1).
    let crossover_hz = nominal
        .frequency_grid()
        .windows(2)
        .rev()
        .find(|w| nominal.loop_gain(w[0]).norm() >= 1.0 && nominal.loop_gain(w[1]).norm() < 1.0)
        .map(|w| w[1])
        .expect("the loop crosses over");
    let delay_periods = (lag_deg / (360.0 * crossover_hz * period_s)).round() as usize;
    let linear = axis.linear();
    let mut sections = linear.sections().to_vec();
    sections.extend(std::iter::repeat_n(Section::delay(), delay_periods));
    let lagging = AxisController::new(
        AxisLaw::Cascade(Cascade::new(linear.gain(), sections)),
        axis.output_limit(),
    );
    let stable = settings
        .nominal_loop(&lagging)
        .closed_loop_poles()
        .iter()
        .all(|pole| pole.norm() < 1.0);
    plan.controller = ScanController::new(lagging, settings.coil_current_limit_a, period_s);
    let dir = tempfile::tempdir().expect("a temporary folder");
    scanhil_lab::in_process::run_plan(&scenario, plan, Some(dir.path())).expect("the scan runs");
    let report = std::fs::read_to_string(dir.path().join("report.json")).expect("report");
    (
        stable,
        serde_json::from_str(&report).expect("report.json is JSON"),
    )
}

#[test]
fn a_controller_lagging_its_model_by_60_degrees_fails_the_band_not_the_old_target() {
    // 60 degrees of lag at crossover (63 periods): the closed loop stays stable, so the
    // check before the scan lets it run; both axes still track under 1 % (0.73 / 0.69 %), so
    // the old "under the target" check passes it; the band around the prediction does not
    // (beta tracks 5 % better than the model it claims: 0.954 of the prediction).
    let (stable, report) = run_lagging_dual_tone(60.0);
    assert!(stable, "not refused before the scan");
    steady_state(&report, (0.0, f64::INFINITY), Some(0.01))
        .expect("the old loose check (under 1 %) passes it");
    let error = steady_state(&report, (0.97, 1.10), Some(0.01)).unwrap_err();
    assert!(error.contains("beta") && error.contains("ratio"), "{error}");
}

#[test]
fn a_20_degree_lag_at_the_dual_tones_crossover_is_below_the_checks_resolution() {
    // The limit of the check, kept so it is known and moves if the check gets finer: 20
    // degrees (21 periods) at the dual-tone's crossover leave its tracking at the drive,
    // set by the tones' gain there, within 2 / 4 % of the prediction: inside the band.
    let (stable, report) = run_lagging_dual_tone(20.0);
    assert!(stable);
    steady_state(&report, (0.97, 1.10), Some(0.01)).expect("inside the band");
}
