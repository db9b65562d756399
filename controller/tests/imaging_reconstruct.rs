//! Reconstruction against the geometry's forward model, recordings, the whole pipeline, its
//! figures (snapshots, profiles), and the `scanhil reconstruct` and `scanhil compare`
//! commands.

mod imaging_support;
mod reconstruct_command;

use imaging_support::{
    BASE_Z_MM, FULL_RANGE_RAD, STUD_HEIGHT_MM, field_centre, lissajous, raster, stud_scene,
    stud_surface,
};
use reconstruct_command::{reconstruct_succeeds, scanhil_reconstruct};
use scanhil_controller::imaging::feature::{FeatureParams, Region};
use scanhil_controller::imaging::pipeline::{
    Figures, HEIGHT_MAP_PNG, ImagingError, ImagingOptions, MAX_PROGRESSIVE_STEPS, PROFILES_SVG,
    PROGRESSIVE_SVG, SNAPSHOTS_PNG, image_points, image_samples, write_outputs,
};
use scanhil_controller::imaging::ply::PlyEncoding;
use scanhil_controller::imaging::ply::read_ply_file;
use scanhil_controller::imaging::profiles::{Profiles, Section, sections};
use scanhil_controller::imaging::progressive::{ScanFrame, simulate_samples};
use scanhil_controller::imaging::reconstruct::{DEFAULT_MODEL, ScanSample, reconstruct};
use scanhil_controller::imaging::recording::{parse_recording, write_recording_csv};
use scanhil_controller::imaging::snapshots::{SNAPSHOT_FRACTIONS, snapshots};
use scanhil_geometry::{GeometryModel, Scanner};
use scanhil_protocol::ild::MeasuringRange;
use scanhil_report::MISSING_RGB;

/// Samples of a flat plane at z = -130 mm seen through `model`'s beam.
fn plane_samples(model: GeometryModel) -> Vec<ScanSample> {
    let scanner = Scanner::paper(model);
    let mut out = Vec::new();
    for i in -5..=5 {
        for j in -5..=5 {
            let (a, b) = (
                i as f64 * FULL_RANGE_RAD / 5.0,
                j as f64 * FULL_RANGE_RAD / 5.0,
            );
            let ray = scanner.beam(a, b);
            let t = (BASE_Z_MM - ray.origin_mm.z) / ray.direction.z;
            out.push(ScanSample {
                t_s: out.len() as f64 * 5e-5,
                d_alpha_rad: a,
                d_beta_rad: b,
                z_meas_mm: Some(ray.z_meas_at(t)),
            });
        }
    }
    out
}

#[test]
fn reconstruction_inverts_the_forward_model_for_both_models() {
    for model in GeometryModel::ALL {
        let samples = plane_samples(model);
        let r = reconstruct(&samples, &Scanner::paper(model));
        assert_eq!(r.cloud.model, model);
        assert_eq!(r.cloud.points.len(), samples.len());
        for (p, s) in r.cloud.points.iter().zip(&samples) {
            assert!((p.z_mm - BASE_Z_MM).abs() < 1e-9, "{model}: {p:?}");
            assert_eq!(
                (p.t_s, p.d_alpha_rad, p.d_beta_rad),
                (s.t_s, s.d_alpha_rad, s.d_beta_rad)
            );
        }
    }
}

#[test]
fn the_paper_model_on_exact_data_errs_by_at_most_a_tenth_of_a_mm() {
    let samples = plane_samples(GeometryModel::ExactReflection);
    let r = reconstruct(&samples, &Scanner::paper(GeometryModel::SmallAngle));
    assert_eq!(r.cloud.model, DEFAULT_MODEL);
    let worst = r
        .cloud
        .points
        .iter()
        .map(|p| (p.z_mm - BASE_Z_MM).abs())
        .fold(0.0, f64::max);
    assert!(worst > 1e-4 && worst < 0.1, "{worst}");
}

#[test]
fn missing_and_non_finite_samples_become_no_point() {
    let mut samples = plane_samples(GeometryModel::SmallAngle);
    samples[3].z_meas_mm = None;
    samples[4].d_beta_rad = f64::NAN;
    let r = reconstruct(&samples, &Scanner::paper(GeometryModel::SmallAngle));
    assert_eq!((r.missing_samples, r.non_finite_samples), (1, 1));
    assert_eq!(r.cloud.points.len(), samples.len() - 2);
}

#[test]
fn recordings_parse_as_csv_and_json_lines() {
    let range = MeasuringRange::ILD2300_100;
    let csv =
        "# a comment\nt_s, d_alpha_rad,d_beta_rad,z_meas_mm\n0.0,0.001,-0.002,140.5\n5e-5,0,0,\n";
    let r = parse_recording(csv, "rec.csv", &range).unwrap();
    assert_eq!(r.samples.len(), 2);
    assert_eq!(r.samples[0].z_meas_mm, Some(140.5));
    assert_eq!(r.samples[1].z_meas_mm, None);
    assert_eq!(r.missing_by_reason["empty"], 1);

    let raw = range.mm_to_digital(140.0).unwrap();
    let jsonl = format!(
        "{{\"t_s\":0,\"d_alpha_rad\":0,\"d_beta_rad\":0,\"ild_raw\":{raw}}}\n\
         {{\"t_s\":1e-4,\"d_alpha_rad\":0,\"d_beta_rad\":0,\"ild_raw\":262076,\"extra\":true}}\n"
    );
    let r = parse_recording(&jsonl, "rec.jsonl", &range).unwrap();
    assert!((r.samples[0].z_meas_mm.unwrap() - 140.0).abs() <= range.mm_per_digit());
    assert_eq!(r.samples[1].z_meas_mm, None);
    assert_eq!(r.missing_by_reason["no_peak"], 1);

    // Round trip through the CSV writer.
    let samples = plane_samples(GeometryModel::SmallAngle);
    let mut text = Vec::new();
    write_recording_csv(&mut text, &samples).unwrap();
    let back = parse_recording(std::str::from_utf8(&text).unwrap(), "x", &range).unwrap();
    assert_eq!(back.samples, samples);
}

#[test]
fn bad_recordings_name_file_line_and_field() {
    let range = MeasuringRange::ILD2300_100;
    let cases = [
        (
            "t_s,d_alpha_rad,z_meas_mm\n",
            "rec.csv:1: header: no 'd_beta_rad' column",
        ),
        (
            "t_s,d_alpha_rad,d_beta_rad,z_meas_mm,ild_raw\n",
            "both 'z_meas_mm' and 'ild_raw'",
        ),
        (
            "t_s,d_alpha_rad,d_beta_rad,z_meas_mm\n0,0,x,1\n",
            "rec.csv:2: d_beta_rad: 'x' is not a number",
        ),
        (
            "t_s,d_alpha_rad,d_beta_rad,z_meas_mm\n0,0,0\n",
            "rec.csv:2: line: 3 values for 4 columns",
        ),
        (
            "t_s,d_alpha_rad,d_beta_rad,ild_raw\n0,0,0,1.5\n",
            "rec.csv:2: ild_raw: 1.5 is not an 18-bit raw value (an integer from 0 to 262143)",
        ),
        // Beyond 18 bits: masked, 300000 once became 127.93 mm.
        (
            "t_s,d_alpha_rad,d_beta_rad,ild_raw\n0,0,0,1000\n5e-5,0,0,300000\n",
            "rec.csv:3: ild_raw: 300000 is not an 18-bit raw value",
        ),
        (
            "{\"t_s\":0,\"d_alpha_rad\":0,\"z_meas_mm\":1}\n",
            "rec.csv:1: d_beta_rad: missing",
        ),
        ("{\"t_s\":0}\n[1]\n", "rec.csv:1: line: neither"),
    ];
    for (text, needle) in cases {
        let err = parse_recording(text, "rec.csv", &range)
            .unwrap_err()
            .to_string();
        assert!(err.contains(needle), "{err} (wanted {needle})");
    }
}

#[test]
fn the_pipeline_measures_the_simulated_stud_from_both_trajectories() {
    for (name, angles) in [
        ("lissajous", lissajous as imaging_support::Angles),
        ("raster", raster),
    ] {
        let samples = simulate_samples(
            angles,
            &stud_scene(GeometryModel::SmallAngle),
            10_000.0,
            1.0,
        );
        let options = ImagingOptions {
            subtract_plane: true,
            feature: Some(FeatureParams::default()),
            ..ImagingOptions::default()
        };
        let imaging = image_samples(&samples, &options).unwrap();
        let f = imaging.feature.unwrap().unwrap();
        // Ideal data: the top is flat and exact; the plane picks up the few samples that hit
        // the stud's wall less than the inlier threshold above the base, a sub-micrometre
        // bias.
        assert!((f.height_mm - STUD_HEIGHT_MM).abs() < 1e-3, "{name}: {f:?}");
        assert!(f.std_mm < 1e-4 && f.points > 100, "{name}: {f:?}");
        assert!(f.plane.plane.tilt_rad() < 1e-4);
        assert!(imaging.map.coverage_fraction() > 0.1, "{name}");
    }
}

#[test]
fn scanhil_reconstruct_writes_ply_png_csv_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rec.csv");
    let mut samples = simulate_samples(
        lissajous,
        &stud_scene(GeometryModel::SmallAngle),
        5_000.0,
        1.0,
    );
    samples[7].z_meas_mm = None;
    write_recording_csv(std::fs::File::create(&input).unwrap(), &samples).unwrap();
    let out = dir.path().join("out");
    let (stdout, report) = reconstruct_succeeds(
        scanhil_reconstruct(&input, &out).args([
            "--feature-height",
            "--subtract-plane",
            "--fill",
            "nearest",
            "--pitch-mm",
            "0.2",
        ]),
        &out,
    );
    assert!(stdout.contains("feature height 4.66"), "{stdout}");
    assert_eq!(report.model, "small_angle");
    assert_eq!(report.samples, samples.len());
    assert_eq!(
        (report.missing_samples, report.missing_by_reason["empty"]),
        (1, 1)
    );
    assert_eq!(report.map_quantity, "height_above_plane_mm");
    // At 5 kHz the samples are ~0.5 mm apart along the figure, so a few wall hits pass the
    // edge margin: a slightly lower mean and a larger spread than at 10 kHz.
    let f = report.feature.as_ref().unwrap();
    assert!(
        (f.height_mm - STUD_HEIGHT_MM).abs() < 0.01 && f.std_mm < 0.05,
        "{f:?}"
    );
    assert!(report.fill.filled_cells > 0);
    let ply = read_ply_file(&out.join("points.ply"))
        .unwrap()
        .to_point_cloud()
        .unwrap();
    assert_eq!(ply.points.len(), report.points);
    assert!(image::open(out.join("height_map.png")).is_ok());
    let csv = std::fs::read_to_string(out.join("height_map.csv")).unwrap();
    assert_eq!(csv.lines().count(), report.grid.nx * report.grid.ny + 1);

    // A bad recording: non-zero exit, the file and line named.
    std::fs::write(&input, "t_s,d_alpha_rad,d_beta_rad,z_meas_mm\n0,0,0,abc\n").unwrap();
    let run = scanhil_reconstruct(&input, &out).output().unwrap();
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("rec.csv:2: z_meas_mm: 'abc' is not a number"),
        "{stderr}"
    );
}

/// A recording of an ideal scan of the plane-120mm scene, scored by `scanhil reconstruct
/// --truth-scene` against that scene's surface (read by `scanhil-scene`, no emulator).
#[test]
fn scanhil_reconstruct_scores_a_recording_against_a_scene_surface() {
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/scenes/plane-120mm.json");
    let plane = scanhil_controller::imaging::progressive::HeightFieldScene {
        scanner: Scanner::paper(GeometryModel::ExactReflection),
        surface: |_x: f64, _y: f64| -120.0,
        range_mm: (70.0, 170.0),
    };
    let samples = simulate_samples(lissajous, &plane, 20_000.0, 0.1);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rec.csv");
    write_recording_csv(std::fs::File::create(&input).unwrap(), &samples).unwrap();
    let out = dir.path().join("out");
    let (stdout, report) = reconstruct_succeeds(
        scanhil_reconstruct(&input, &out)
            .args([
                "--model",
                "exact-reflection",
                "--pitch-mm",
                "0.3",
                "--truth-scene",
            ])
            .arg(&scene),
        &out,
    );
    assert!(stdout.contains("against the true surface"), "{stdout}");
    let e = report.truth_error.unwrap();
    // The ideal samples lie on the true plane: only gridding remains.
    assert!(e.covered_rms_mm.unwrap() < 1e-6, "{e:?}");
    assert!(e.coverage_fraction > 0.3, "{e:?}");
    assert_eq!(report.progressive.len(), 10);
    assert!(out.join("progressive.svg").exists());
    // The same scene without its surface section would not score: a wrong truth is refused.
    let wrong =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/loop-fast.json");
    let run = scanhil_reconstruct(&input, &dir.path().join("out2"))
        .arg("--truth-scene")
        .arg(&wrong)
        .output()
        .unwrap();
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("loop-fast.json"));
}

/// Ideal samples of the stud scene (the paper's model on both sides: exact data).
fn stud_samples(angles: imaging_support::Angles, rate_hz: f64) -> Vec<ScanSample> {
    simulate_samples(angles, &stud_scene(GeometryModel::SmallAngle), rate_hz, 1.0)
}

#[test]
fn snapshot_coverage_grows_with_the_fraction_of_the_frame() {
    for (name, angles) in [
        ("lissajous", lissajous as imaging_support::Angles),
        ("raster", raster),
    ] {
        // A frame that starts late on the sample clock: the snapshots count from its start.
        let samples: Vec<ScanSample> = stud_samples(angles, 5_000.0)
            .into_iter()
            .map(|s| ScanSample {
                t_s: s.t_s + 2.0,
                ..s
            })
            .collect();
        let imaging = image_samples(&samples, &ImagingOptions::default()).unwrap();
        let frame = ScanFrame::from_first_sample(samples.iter().map(|s| s.t_s), 1.0);
        assert_eq!(frame.start_s, 2.0);
        let shots = snapshots(
            &imaging.reconstruction.cloud.points,
            None,
            imaging.map.spec,
            imaging.options.grid,
            frame,
            &SNAPSHOT_FRACTIONS,
        );
        let coverage: Vec<f64> = shots.iter().map(|s| s.map.coverage_fraction()).collect();
        // Coverage never shrinks; the Lissajous figure reaches new cells all frame long, the
        // raster finishes its one slow sweep at 0.25 s and then retraces the same lines.
        assert!(
            coverage[0] > 0.0 && coverage[0] < coverage[1],
            "{name}: {coverage:?}"
        );
        assert!(
            coverage.windows(2).all(|w| w[0] <= w[1]),
            "{name}: {coverage:?}"
        );
        if name == "lissajous" {
            assert!(coverage.windows(2).all(|w| w[0] < w[1]), "{coverage:?}");
        }
        // The whole frame is the map itself (no fill asked).
        assert_eq!(shots[3].map, imaging.map, "{name}");
        assert!((shots[1].t_s - 0.25).abs() < 1e-12, "{name}");
    }
}

/// Heights above the base plane, with the default feature measured.
fn plane_and_feature() -> ImagingOptions {
    ImagingOptions {
        subtract_plane: true,
        feature: Some(FeatureParams::default()),
        ..ImagingOptions::default()
    }
}

#[test]
fn snapshots_above_the_plane_of_points_out_of_time_order_are_those_of_the_ordered_points() {
    let samples = stud_samples(lissajous, 5_000.0);
    let options = plane_and_feature();
    let imaging = image_samples(&samples, &options).unwrap();
    let plane = imaging.plane.as_ref().map(|f| &f.plane);
    let frame = ScanFrame::from_first_sample(samples.iter().map(|s| s.t_s), 1.0);
    let snapshots_of = |points: &[_]| {
        snapshots(
            points,
            plane,
            imaging.map.spec,
            imaging.options.grid,
            frame,
            &SNAPSHOT_FRACTIONS,
        )
    };
    let in_order = snapshots_of(&imaging.reconstruction.cloud.points);
    // The whole frame is the map of heights above the plane (no fill asked).
    assert_eq!(in_order[3].map, imaging.map);
    let mut reversed = imaging.reconstruction.cloud.points.clone();
    reversed.reverse();
    assert_eq!(snapshots_of(&reversed), in_order);
}

#[test]
fn image_points_images_reconstructed_points_as_image_samples_does_and_checks_its_options() {
    let samples = stud_samples(lissajous, 10_000.0);
    let options = plane_and_feature();
    let reconstruction = || {
        reconstruct(
            &samples,
            &Scanner::new(options.setup, options.model).unwrap(),
        )
    };
    assert_eq!(
        image_points(reconstruction(), &options).unwrap(),
        image_samples(&samples, &options).unwrap()
    );
    for steps in [0, MAX_PROGRESSIVE_STEPS + 1] {
        let bad = ImagingOptions {
            progressive_steps: steps,
            ..options
        };
        let error = image_points(reconstruction(), &bad).unwrap_err();
        assert!(
            matches!(
                error,
                ImagingError::Options {
                    field: "progressive_steps",
                    ..
                }
            ),
            "{error}"
        );
        assert!(matches!(
            image_samples(&samples, &bad),
            Err(ImagingError::Options {
                field: "progressive_steps",
                ..
            })
        ));
    }
    let mut feature = options
        .feature
        .expect("plane_and_feature measures the stud");
    feature.plane_region = Region::Disc {
        x_mm: 0.0,
        y_mm: 0.0,
        radius_mm: -1.0,
    };
    let bad = ImagingOptions {
        feature: Some(feature),
        ..options
    };
    let error = image_points(reconstruction(), &bad).unwrap_err();
    assert_eq!(
        error.to_string(),
        "imaging option `feature`: plane_region: radius_mm -1 must be positive and finite"
    );
}

#[test]
fn the_profile_through_the_stud_crosses_its_height_as_the_truth_does() {
    let options = ImagingOptions {
        subtract_plane: true,
        feature: Some(FeatureParams::default()),
        ..ImagingOptions::default()
    };
    let imaging = image_samples(&stud_samples(lissajous, 10_000.0), &options).unwrap();
    let feature = imaging.feature.clone().unwrap().unwrap();
    let (cx, cy) = field_centre();
    // The feature points' centre is the stud's centre (a ring: its points all round).
    assert!(
        (feature.centre_mm[0] - cx).hypot(feature.centre_mm[1] - cy) < 0.1,
        "{:?} against ({cx}, {cy})",
        feature.centre_mm
    );
    let plane = imaging.plane.clone().unwrap().plane;
    let surface = stud_surface();
    let profiles = sections(
        &imaging.map,
        (feature.centre_mm[0], feature.centre_mm[1]),
        |x, y| Some(plane.height_mm([x, y, surface(x, y)])),
    );
    for section in [Section::X, Section::Y] {
        let points: Vec<_> = profiles.along(section).collect();
        let heights: Vec<f64> = points.iter().filter_map(|p| p.height_mm).collect();
        assert!(heights.len() > 50, "{section:?}: {}", heights.len());
        let top = heights.iter().copied().fold(f64::MIN, f64::max);
        let base = heights.iter().copied().fold(f64::MAX, f64::min);
        // Gridding averages only samples within one pitch: the top cells are the stud's.
        assert!(
            (top - base - STUD_HEIGHT_MM).abs() < 0.01,
            "{section:?}: top {top} base {base}"
        );
        // The section crosses the ring twice: four steps of the true surface.
        let truth: Vec<f64> = points.iter().map(|p| p.true_height_mm.unwrap()).collect();
        let steps = truth
            .windows(2)
            .filter(|w| (w[1] - w[0]).abs() > 2.0)
            .count();
        assert_eq!(steps, 4, "{section:?}");
        // Away from the walls the map is the truth.
        let agree = points
            .iter()
            .filter(|p| p.height_mm.is_some())
            .filter(|p| (p.height_mm.unwrap() - p.true_height_mm.unwrap()).abs() < 0.01)
            .count();
        assert!(
            agree as f64 > 0.9 * heights.len() as f64,
            "{section:?}: {agree}"
        );
    }
}

#[test]
fn scanhil_reconstruct_writes_a_readable_map_snapshots_and_profiles_and_compare_draws_both_scans() {
    let dir = tempfile::tempdir().unwrap();
    let mut outs = Vec::new();
    for (name, angles) in [
        ("lissajous", lissajous as imaging_support::Angles),
        ("raster", raster),
    ] {
        let input = dir.path().join(format!("{name}.csv"));
        let samples = stud_samples(angles, 5_000.0);
        write_recording_csv(std::fs::File::create(&input).unwrap(), &samples).unwrap();
        let out = dir.path().join(name);
        let (_, report) = reconstruct_succeeds(
            scanhil_reconstruct(&input, &out).args([
                "--feature-height",
                "--subtract-plane",
                "--pitch-mm",
                "0.1",
            ]),
            &out,
        );
        for file in [
            "height_map.png",
            "snapshots.png",
            "profiles.svg",
            "profiles.csv",
        ] {
            assert!(report.files.iter().any(|f| f == file), "{name}: {file}");
        }
        // The readable map: at least 500 px wide, missing cells in the named grey.
        let png = image::open(out.join("height_map.png")).unwrap().to_rgb8();
        assert!(
            png.width() >= 500 && png.height() >= 500,
            "{:?}",
            png.dimensions()
        );
        assert!(report.coverage_fraction < 1.0);
        assert!(png.pixels().any(|p| p.0 == MISSING_RGB), "{name}");
        // Fig. 6: four snapshots from the frame's start, coverage growing.
        let frame = report.frame.unwrap();
        assert_eq!((frame.start_s, frame.length_s), (0.0, 0.9998));
        let coverage: Vec<f64> = report
            .snapshots
            .iter()
            .map(|s| s.coverage_fraction)
            .collect();
        assert_eq!(coverage.len(), 4, "{name}");
        assert!(
            coverage[0] < coverage[1] && coverage.windows(2).all(|w| w[0] <= w[1]),
            "{name}: {coverage:?}"
        );
        assert_eq!(coverage[3], report.coverage_fraction);
        // Fig. 10: the sections cross at the feature, and its height shows in them.
        assert_eq!(
            report.profile_centre.as_ref().unwrap().from,
            "feature_points"
        );
        let profiles = Profiles::read_csv_file(&out.join("profiles.csv")).unwrap();
        // At 5 kHz the raster's lines are 0.2 mm apart along y: its x section may run
        // between two lines; its y section crosses every line.
        let top = profiles
            .along(Section::Y)
            .filter_map(|p| p.height_mm)
            .fold(f64::MIN, f64::max);
        assert!((top - STUD_HEIGHT_MM).abs() < 0.05, "{name}: {top}");
        assert!(profiles.along(Section::X).count() == report.grid.nx);
        outs.push(out);
    }

    let compared = dir.path().join("compared");
    let run = scanhil_compare(&outs[0], &outs[1], &compared)
        .args(["--labels", "Lissajous,raster"])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let single = image::open(outs[0].join("snapshots.png")).unwrap();
    let both = image::open(compared.join("snapshots.png")).unwrap();
    // Two rows of four panels (over both grids' extent: the width differs a little).
    assert!(
        both.width().abs_diff(single.width()) < single.width() / 10,
        "{} against {}",
        both.width(),
        single.width()
    );
    assert!(
        both.height() > single.height() * 3 / 2,
        "{:?}",
        both.height()
    );
    let svg = std::fs::read_to_string(compared.join("profiles.svg")).unwrap();
    for needle in ["Lissajous", "raster", "section along x", "section along y"] {
        assert!(svg.contains(needle), "{needle}");
    }

    // A folder without the data: refused, naming the folder and the file.
    let bare = dir.path().join("bare");
    std::fs::create_dir_all(&bare).unwrap();
    for file in ["report.json", "points.ply"] {
        std::fs::copy(outs[1].join(file), bare.join(file)).unwrap();
    }
    let run = scanhil_compare(&outs[0], &bare, &dir.path().join("c2"))
        .output()
        .unwrap();
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains(&format!("{}: no profiles.csv", bare.display())),
        "{stderr}"
    );
}

/// `scanhil compare A B --out OUT`.
fn scanhil_compare(
    a: &std::path::Path,
    b: &std::path::Path,
    out: &std::path::Path,
) -> std::process::Command {
    let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_scanhil"));
    command.arg("compare").arg(a).arg(b).arg("--out").arg(out);
    command
}

#[test]
fn reconstruct_refuses_a_search_radius_that_would_scan_the_whole_grid_per_cell() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rec.csv");
    let samples = plane_samples(GeometryModel::SmallAngle);
    write_recording_csv(std::fs::File::create(&input).unwrap(), &samples).unwrap();
    for radius in ["1e6", "0", "nan"] {
        let run = scanhil_reconstruct(&input, &dir.path().join("out"))
            .args(["--radius-pitches", radius])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{radius}: {stderr}");
        assert!(stderr.contains("--radius-pitches"), "{stderr}");
    }
}

#[test]
fn reconstruct_refuses_a_pitch_too_fine_for_the_points_naming_the_flag_and_the_smallest_pitch() {
    // 0.002 mm over the plane's points once took 6.4 GB before failing unnamed.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rec.csv");
    let samples = plane_samples(GeometryModel::SmallAngle);
    write_recording_csv(std::fs::File::create(&input).unwrap(), &samples).unwrap();
    let out = dir.path().join("out");
    let run = scanhil_reconstruct(&input, &out)
        .args(["--pitch-mm", "0.0001"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("--pitch-mm 0.0001: grid of "), "{stderr}");
    let smallest = stderr
        .trim_end()
        .rsplit("at least ")
        .next()
        .and_then(|rest| rest.strip_suffix(" mm"))
        .expect("the smallest pitch");
    assert!(!out.exists(), "refused before writing");
    // The smallest pitch named is laid (121 points leave such a grid too sparse to draw its
    // profiles, which is another matter).
    let run = scanhil_reconstruct(&input, &out)
        .args(["--pitch-mm", smallest])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        stdout.contains(&format!("cells of {smallest} mm")),
        "{stdout}"
    );
}

#[test]
fn reconstruct_takes_negative_rectangles_and_refuses_feature_settings_that_cannot_be_measured() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rec.csv");
    let samples = stud_samples(lissajous, 10_000.0);
    write_recording_csv(std::fs::File::create(&input).unwrap(), &samples).unwrap();
    let out = dir.path().join("out");
    // The base plane around the stud, and a piece of its ring wall's top as the feature:
    // the field's lower bounds are negative.
    let (cx, cy) = field_centre();
    let plane_rect = format!("{},{},{},{}", cx - 20.0, cx + 20.0, cy - 20.0, cy + 20.0);
    let feature_rect = format!("{},{},{},{}", cx + 3.6, cx + 4.5, cy - 1.0, cy + 1.0);
    assert!(plane_rect.starts_with('-'), "{plane_rect}");
    let (_, report) = reconstruct_succeeds(
        scanhil_reconstruct(&input, &out).args([
            "--feature-height",
            "--plane-rect",
            &plane_rect,
            "--feature-rect",
            &feature_rect,
        ]),
        &out,
    );
    let feature = report.feature.expect("the feature measured");
    assert!(
        (feature.height_mm - STUD_HEIGHT_MM).abs() < 0.05,
        "{feature:?}"
    );
    for (args, named) in [
        (&["--plane-rect", "5,-5,-5,5"][..], "--plane-rect"),
        (&["--feature-rect", "-1,1,1,-1"], "--feature-rect"),
        (&["--feature-rect", "-1,1,nan,1"], "--feature-rect"),
        (&["--feature-rect", "-1,1,1"], "--feature-rect"),
        (
            &["--plane-rect", "1,2,3,4", "--plane-rect", "1,2,3,4"],
            "--plane-rect",
        ),
        (&["--edge-margin-mm", "-0.1"], "--edge-margin-mm"),
        (&["--min-height-mm", "inf"], "--min-height-mm"),
        (&["--ransac-threshold-mm", "0"], "--ransac-threshold-mm"),
        (&["--pitch-mm", "-0.1"], "pitch"),
    ] {
        let run = scanhil_reconstruct(&input, &dir.path().join("refused"))
            .arg("--feature-height")
            .args(args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(named), "{args:?}: {stderr}");
        assert!(
            !dir.path().join("refused").exists(),
            "refused before writing"
        );
    }
}

#[test]
fn write_outputs_draws_the_pictures_or_leaves_them_out_and_writes_the_rest_either_way() {
    let options = plane_and_feature();
    let mut imaging = image_samples(&stud_samples(lissajous, 10_000.0), &options).unwrap();
    imaging.score_progressive(
        None,
        ScanFrame::spanning(imaging.reconstruction.cloud.points.iter().map(|p| p.t_s)),
    );
    let pictures = [HEIGHT_MAP_PNG, PROGRESSIVE_SVG, SNAPSHOTS_PNG, PROFILES_SVG];
    let written = |figures| {
        let dir = tempfile::tempdir().unwrap();
        let report = write_outputs(
            &imaging,
            dir.path(),
            PlyEncoding::BinaryLittleEndian,
            &Default::default(),
            figures,
        )
        .unwrap();
        let drawn: Vec<bool> = pictures
            .iter()
            .map(|f| dir.path().join(f).exists())
            .collect();
        let rest = ["points.ply", "height_map.csv", "profiles.csv"]
            .iter()
            .all(|f| dir.path().join(f).exists());
        (drawn, rest, report.map_range_mm.is_some(), report.snapshots)
    };
    let (drawn, rest, range, snapshots) = written(Figures::Drawn);
    assert_eq!(drawn, [true; 4]);
    assert!(rest && range);
    let (left_out, rest_left, no_range, same_snapshots) = written(Figures::LeftOut);
    assert_eq!(left_out, [false; 4]);
    assert!(rest_left && !no_range);
    assert_eq!(
        same_snapshots, snapshots,
        "the report's figures are computed either way"
    );
}
