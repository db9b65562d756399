//! Prints how the two geometry models compare over the mirror's +-1.5 deg range: the fields
//! of view at both ends of the sensor range, the smallest |z_s| at the far end, and the
//! largest difference in beam direction and in reconstructed point between the models.
//!
//! Run: `cargo run -p scanhil-geometry --example compare_models`.

use scanhil_geometry::{GeometryModel, Scanner};

/// Grid points per axis over +-1.5 deg.
const GRID: usize = 61;

fn grid() -> impl Iterator<Item = (f64, f64)> {
    let full = 1.5f64.to_radians();
    let step = 2.0 * full / (GRID - 1) as f64;
    (0..GRID).flat_map(move |i| {
        (0..GRID).map(move |j| (-full + i as f64 * step, -full + j as f64 * step))
    })
}

fn main() {
    let full = 1.5f64.to_radians();
    println!("model             z_meas  FOV x (narrowest row)  FOV y (centre line)  min |z_s|");
    for model in GeometryModel::ALL {
        let s = Scanner::paper(model);
        for z_meas in [70.0, 170.0] {
            let x_width = [-full, full]
                .iter()
                .map(|&a| s.point(a, full, z_meas).x - s.point(a, -full, z_meas).x)
                .fold(f64::INFINITY, f64::min);
            let y_height = s.point(-full, 0.0, z_meas).y - s.point(full, 0.0, z_meas).y;
            let closest = grid()
                .map(|(a, b)| -s.point(a, b, z_meas).z)
                .fold(f64::INFINITY, f64::min);
            println!(
                "{:<17} {z_meas:>6.1}  {x_width:>16.3} mm  {y_height:>16.3} mm  {closest:>8.3} mm",
                model.name()
            );
        }
    }
    let (small, exact) = (
        Scanner::paper(GeometryModel::SmallAngle),
        Scanner::paper(GeometryModel::ExactReflection),
    );
    let mut worst_angle = (0.0f64, 0.0, 0.0);
    let mut worst_point = (0.0f64, 0.0, 0.0);
    for (a, b) in grid() {
        let angle = small
            .beam(a, b)
            .direction
            .angle(&exact.beam(a, b).direction)
            .to_degrees();
        if angle > worst_angle.0 {
            worst_angle = (angle, a, b);
        }
        let point = (small.point(a, b, 170.0) - exact.point(a, b, 170.0)).norm();
        if point > worst_point.0 {
            worst_point = (point, a, b);
        }
    }
    println!(
        "largest beam direction difference: {:.4} deg at d_alpha {:.2} deg, d_beta {:.2} deg",
        worst_angle.0,
        worst_angle.1.to_degrees(),
        worst_angle.2.to_degrees()
    );
    println!(
        "largest point difference at z_meas 170 mm: {:.4} mm at d_alpha {:.2} deg, d_beta {:.2} deg",
        worst_point.0,
        worst_point.1.to_degrees(),
        worst_point.2.to_degrees()
    );
    let path = |s: &Scanner, a: f64| s.beam(a, 0.0).path_to_origin_mm;
    println!(
        "mirror hit shift dy at d_alpha +1.5 / -1.5 deg: small_angle {:.4} / {:.4} mm, exact {:.4} / {:.4} mm",
        path(&small, full) - 10.0,
        path(&small, -full) - 10.0,
        path(&exact, full) - 10.0,
        path(&exact, -full) - 10.0
    );
}
