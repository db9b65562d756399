//! Trajectory figures derived from the definition: the paper's Lissajous and raster scans.

use scanhil_controller::trajectory::{SensingAxis, Trajectory};

fn lissajous(phase_deg: f64) -> Trajectory {
    Trajectory::Lissajous {
        alpha_hz: 52.0,
        beta_hz: 27.0,
        alpha_amplitude_rad: 0.02,
        beta_amplitude_rad: 0.02,
        relative_phase_rad: phase_deg.to_radians(),
    }
}

#[test]
fn lissajous_27_52_gives_the_papers_frame_rate_and_resolution() {
    let fig = lissajous(0.0).figures(Some((11.5, 18.5)));
    assert_eq!(fig.frame_rate_hz, Some(1.0));
    let resolution = fig.resolution_fraction.unwrap();
    // The paper quotes 0.058 and 1.07 mm at 18.5 mm (y, the 52 Hz alpha axis).
    assert_eq!(
        (resolution * 1000.0).round() / 1000.0,
        0.058,
        "{resolution}"
    );
    let mm = fig.resolution_mm.unwrap();
    assert!((1.065..1.075).contains(&mm), "{mm} mm");
    assert_eq!(fig.spacing_alpha_fraction, Some(resolution));
    // Closed form at the centre column: sin(pi/27)/2 of the image height.
    assert!((resolution - (std::f64::consts::PI / 27.0).sin() / 2.0).abs() < 1e-12);
    // Along x the centre row is finer: sin(pi/52)/2.
    let beta = fig.spacing_beta_fraction.unwrap();
    assert!(
        (beta - (std::f64::consts::PI / 52.0).sin() / 2.0).abs() < 1e-12,
        "{beta}"
    );
}

#[test]
fn relative_phase_changes_the_line_spacing() {
    let zero = lissajous(0.0).figures(None).spacing_alpha_fraction.unwrap();
    let two = lissajous(2.0).figures(None).spacing_alpha_fraction.unwrap();
    assert!(two > 1.5 * zero, "2 deg: {two} vs 0 deg: {zero}");
}

#[test]
fn raster_2_34_has_17_lines_per_quarter_second_sweep() {
    let raster = Trajectory::Raster {
        slow_hz: 2.0,
        fast_hz: 34.0,
        slow_axis: SensingAxis::Beta,
        alpha_amplitude_rad: 0.02,
        beta_amplitude_rad: 0.02,
        fast_max_harmonic: None,
    };
    let fig = raster.figures(Some((11.5, 18.5)));
    assert_eq!(fig.lines_per_frame, Some(17.0));
    assert_eq!(fig.frame_time_s, Some(0.25));
    assert!((fig.spacing_beta_mm.unwrap() - 11.5 / 17.0).abs() < 1e-12);
    // The reference really is a triangle pair: slow axis at -A, 0, +A over one sweep.
    let at = |t: f64| raster.reference_rad(t);
    assert!((at(0.0).beta + 0.02).abs() < 1e-12 && (at(0.125).beta).abs() < 1e-12);
    assert!((at(0.25).beta - 0.02).abs() < 1e-12);
    // 17 fast half periods in one sweep: the fast axis turns at every 1/68 s.
    assert!((at(1.0 / 68.0).alpha - 0.02).abs() < 1e-12);
}

#[test]
fn frame_rate_of_table_i_tones_is_the_common_period() {
    let fig = Trajectory::Lissajous {
        alpha_hz: 52.044,
        beta_hz: 27.056,
        alpha_amplitude_rad: 0.02,
        beta_amplitude_rad: 0.02,
        relative_phase_rad: 0.0,
    }
    .figures(None);
    // gcd(52044, 27056) mHz = 4 mHz: one frame in 250 s.
    assert!((fig.frame_time_s.unwrap() - 250.0).abs() < 1e-9);
}

#[test]
fn trajectories_parse_from_json() {
    let t: Trajectory =
        serde_json::from_str(r#"{"kind": "lissajous", "alpha_hz": 52, "beta_hz": 27}"#).unwrap();
    assert!(
        matches!(t, Trajectory::Lissajous { relative_phase_rad, .. } if relative_phase_rad == 0.0)
    );
    let err = serde_json::from_str::<Trajectory>(
        r#"{"kind": "lissajous", "alpha_hz": 52, "beta_hz": 27, "phase": 1}"#,
    )
    .unwrap_err();
    assert!(err.to_string().contains("phase"), "{err}");
}
