//! Gridding known surfaces, marking and filling missing cells, CSV and PNG output.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use scanhil_controller::imaging::fill::{FillMethod, fill_missing};
use scanhil_controller::imaging::grid::{GridMethod, GridSpec, grid_points};

fn plane(x: f64, y: f64) -> f64 {
    -130.0 + 0.05 * x - 0.02 * y
}

fn scattered(n: usize, seed: u64, f: impl Fn(f64, f64) -> f64) -> Vec<(f64, f64, f64)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let (x, y) = (rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0));
            (x, y, f(x, y))
        })
        .collect()
}

#[test]
fn spec_covering_centres_the_points() {
    let spec = GridSpec::covering([(-1.0, 2.0), (1.0, 3.0)], 0.5).unwrap();
    assert_eq!((spec.nx, spec.ny), (5, 3));
    assert!((spec.x_min_mm + 1.25).abs() < 1e-12 && (spec.y_min_mm - 1.75).abs() < 1e-12);
    assert_eq!(spec.cell_of(-1.0, 2.0), Some((0, 0)));
    assert_eq!(spec.cell_of(1.0, 3.0), Some((4, 2)));
    assert!(GridSpec::covering([(0.0, 0.0)], 0.0).is_err());
    assert!(GridSpec::covering(std::iter::empty(), 1.0).is_err());
    assert!(GridSpec::covering([(0.0, 0.0), (1e6, 1e6)], 1e-3).is_err());
}

#[test]
fn a_tilted_plane_grids_to_the_plane_within_slope_times_radius() {
    let points = scattered(20_000, 3, plane);
    let spec = GridSpec::spanning(-5.0, 5.0, -5.0, 5.0, 0.25).unwrap();
    let slope = 0.05f64.hypot(0.02);
    for (method, reach) in [
        (GridMethod::CellMean, 0.25 / 2f64.sqrt()),
        (GridMethod::default(), 0.25),
    ] {
        let map = grid_points(points.iter().copied(), spec, method);
        assert!(map.coverage_fraction() > 0.99, "{method:?}");
        let mut worst: f64 = 0.0;
        for iy in 0..spec.ny {
            for ix in 0..spec.nx {
                let (x, y) = spec.centre_mm(ix, iy);
                if let Some(h) = map.heights_mm[spec.index(ix, iy)] {
                    worst = worst.max((h - plane(x, y)).abs());
                }
            }
        }
        assert!(worst <= slope * reach, "{method:?}: {worst}");
        assert!(worst > 0.0);
    }
}

#[test]
fn a_step_is_exact_away_from_its_edge_and_missing_cells_are_marked() {
    let step = |x: f64, _y: f64| if x > 0.0 { 4.663 } else { 0.0 };
    // Leave a hole: no sample in the disc of radius 1.5 mm around (-2.5, 0).
    let points: Vec<_> = scattered(20_000, 4, step)
        .into_iter()
        .filter(|&(x, y, _)| (x + 2.5).hypot(y) > 1.5)
        .collect();
    let spec = GridSpec::spanning(-5.0, 5.0, -5.0, 5.0, 0.25).unwrap();
    let map = grid_points(points.iter().copied(), spec, GridMethod::default());
    for iy in 0..spec.ny {
        for ix in 0..spec.nx {
            let (x, y) = spec.centre_mm(ix, iy);
            let h = map.heights_mm[spec.index(ix, iy)];
            if (x + 2.5).hypot(y) < 1.2 {
                assert_eq!(h, None, "cell ({x}, {y}) in the hole");
            } else if x.abs() > 0.3 && (x + 2.5).hypot(y) > 1.8 {
                let h = h.unwrap_or_else(|| panic!("cell ({x}, {y}) missing"));
                assert!((h - step(x, y)).abs() < 1e-12, "cell ({x}, {y}): {h}");
            }
        }
    }
    // Filling: nearest copies the flat step level; diffusion too (the hole is flat around).
    for method in [FillMethod::Nearest, FillMethod::Diffusion] {
        let mut filled = map.clone();
        let report = fill_missing(&mut filled, method);
        assert_eq!(report.filled_cells, spec.len() - map.measured_cells());
        assert!(filled.heights_mm.iter().all(Option::is_some));
        let centre = spec.cell_of(-2.5, 0.0).unwrap();
        let i = spec.index(centre.0, centre.1);
        assert!(filled.is_filled(i));
        assert!(filled.heights_mm[i].unwrap().abs() < 1e-5, "{method:?}");
    }
}

#[test]
fn diffusion_fills_a_hole_in_a_plane_with_the_plane_and_nearest_does_not() {
    let spec = GridSpec::spanning(-5.0, 5.0, -5.0, 5.0, 0.25).unwrap();
    let points: Vec<_> = (0..spec.ny)
        .flat_map(|iy| (0..spec.nx).map(move |ix| (ix, iy)))
        .map(|(ix, iy)| spec.centre_mm(ix, iy))
        .filter(|&(x, y)| x.abs().max(y.abs()) > 2.0)
        .map(|(x, y)| (x, y, plane(x, y)))
        .collect();
    let map = grid_points(points.iter().copied(), spec, GridMethod::CellMean);
    let error = |method| {
        let mut m = map.clone();
        let report = fill_missing(&mut m, method);
        let worst = (0..spec.len())
            .map(|i| {
                let (x, y) = spec.centre_mm(i % spec.nx, i / spec.nx);
                (m.heights_mm[i].unwrap() - plane(x, y)).abs()
            })
            .fold(0.0, f64::max);
        (worst, report)
    };
    let (diffusion, report) = error(FillMethod::Diffusion);
    assert!(diffusion < 1e-4, "{diffusion} after {report:?}");
    assert!(report.sweeps > 1 && report.sweeps < 10_000, "{report:?}");
    let (nearest, _) = error(FillMethod::Nearest);
    assert!(nearest > 0.05, "{nearest}");
}

#[test]
fn nearest_fill_picks_the_euclidean_nearest_cell() {
    let spec = GridSpec::spanning(0.0, 6.0, 0.0, 6.0, 1.0).unwrap();
    // Two measured cells: (0, 0) = 1 and (6, 3) = 2.
    let map = grid_points(
        [(0.0, 0.0, 1.0), (6.0, 3.0, 2.0)],
        spec,
        GridMethod::CellMean,
    );
    let mut filled = map.clone();
    fill_missing(&mut filled, FillMethod::Nearest);
    for iy in 0..spec.ny {
        for ix in 0..spec.nx {
            let (dx0, dy0) = (ix as f64, iy as f64);
            let (dx1, dy1) = (ix as f64 - 6.0, iy as f64 - 3.0);
            let want = if dx0.hypot(dy0) <= dx1.hypot(dy1) {
                1.0
            } else {
                2.0
            };
            let d0 = dx0.hypot(dy0);
            let d1 = dx1.hypot(dy1);
            if (d0 - d1).abs() > 1e-9 {
                assert_eq!(
                    filled.heights_mm[spec.index(ix, iy)],
                    Some(want),
                    "({ix}, {iy})"
                );
            }
        }
    }
    // Nothing measured: nothing to fill from.
    let mut empty = grid_points(std::iter::empty(), spec, GridMethod::CellMean);
    assert_eq!(
        fill_missing(&mut empty, FillMethod::Diffusion).filled_cells,
        0
    );
}

#[test]
fn csv_and_png_say_which_cells_are_measured_filled_missing() {
    let spec = GridSpec::spanning(0.0, 1.0, 0.0, 0.0, 1.0).unwrap();
    let mut map = grid_points([(0.0, 0.0, -130.5)], spec, GridMethod::CellMean);
    let mut csv = Vec::new();
    map.write_csv(&mut csv).unwrap();
    assert_eq!(
        String::from_utf8(csv).unwrap(),
        "x_mm,y_mm,height_mm,samples,state\n0.0,0.0,-130.5,1,measured\n1.0,0.0,,0,missing\n"
    );
    fill_missing(&mut map, FillMethod::Nearest);
    let mut csv = Vec::new();
    map.write_csv(&mut csv).unwrap();
    assert!(
        String::from_utf8(csv)
            .unwrap()
            .ends_with("1.0,0.0,-130.5,0,filled\n")
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("map.png");
    assert_eq!(
        map.draw_png(&path, "t", "z_s (mm)").unwrap(),
        Some((-130.5, -130.5))
    );
    let png = image::open(&path).unwrap().to_rgb8();
    assert!(png.width() >= 500, "{:?}", png.dimensions());
}

#[test]
fn png_shows_plus_y_up() {
    let spec = GridSpec::spanning(0.0, 0.0, 0.0, 1.0, 1.0).unwrap();
    let map = grid_points(
        [(0.0, 0.0, 0.0), (0.0, 1.0, 1.0)],
        spec,
        GridMethod::CellMean,
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("map.png");
    map.draw_png(&path, "t", "z_s (mm)").unwrap();
    let png = image::open(&path).unwrap().to_rgb8();
    // Down the middle of the map area (left of the colour bar): the highest value,
    // yellow-ish (high red and green), comes before the lowest, dark blue.
    let (w, h) = png.dimensions();
    let x = (w - 190) / 2;
    let column: Vec<[u8; 3]> = (0..h).map(|y| png.get_pixel(x, y).0).collect();
    let high = column
        .iter()
        .position(|p| p[0] > 200 && p[1] > 200 && p[2] < 100);
    let low = column
        .iter()
        .position(|p| p[0] < 100 && p[1] < 20 && p[2] > 60);
    assert!(
        matches!((high, low), (Some(a), Some(b)) if a < b),
        "high at {high:?}, low at {low:?}"
    );
}
