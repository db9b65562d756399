//! Height maps as false-colour PNG images.

use std::path::Path;

use crate::ReportError;

/// A row-major grid of heights; `None` marks a cell with no measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightMapImage<'a> {
    /// Cells per row.
    pub width: usize,
    /// Number of rows; row 0 is drawn at the top.
    pub height: usize,
    /// `width * height` heights in any unit; only their range matters for the colours.
    pub cells: &'a [Option<f64>],
}

/// The colour drawn for a missing cell: magenta, which no height maps to.
pub const MISSING_RGB: [u8; 3] = [255, 0, 255];

/// Writes `map` as an RGB PNG: the lowest height dark blue, the highest yellow (a
/// viridis-like ramp), missing cells [`MISSING_RGB`]. Returns the (min, max) height the
/// colours span, or `None` when every cell is missing.
pub fn write_height_map_png(
    path: &Path,
    map: &HeightMapImage<'_>,
) -> Result<Option<(f64, f64)>, ReportError> {
    if map.width == 0 || map.height == 0 || map.cells.len() != map.width * map.height {
        return Err(ReportError::BadData {
            path: path.to_owned(),
            reason: format!(
                "height map is {}x{} but has {} cells",
                map.width,
                map.height,
                map.cells.len()
            ),
        });
    }
    let finite = map
        .cells
        .iter()
        .flatten()
        .copied()
        .filter(|h| h.is_finite());
    let range = finite.fold(None, |acc: Option<(f64, f64)>, h| match acc {
        None => Some((h, h)),
        Some((lo, hi)) => Some((lo.min(h), hi.max(h))),
    });
    let mut pixels = Vec::with_capacity(map.cells.len() * 3);
    for cell in map.cells {
        let rgb = match (cell, range) {
            (Some(h), Some((lo, hi))) if h.is_finite() => {
                let t = if hi > lo { (h - lo) / (hi - lo) } else { 0.5 };
                ramp(t)
            }
            _ => MISSING_RGB,
        };
        pixels.extend_from_slice(&rgb);
    }
    let too_large = |_| ReportError::BadData {
        path: path.to_owned(),
        reason: "height map too large for a PNG".into(),
    };
    let width = u32::try_from(map.width).map_err(too_large)?;
    let height = u32::try_from(map.height).map_err(too_large)?;
    image::save_buffer(path, &pixels, width, height, image::ColorType::Rgb8).map_err(|source| {
        ReportError::Image {
            path: path.to_owned(),
            source,
        }
    })?;
    Ok(range)
}

/// A perceptually ordered dark-blue → green → yellow ramp for `t` in [0, 1].
fn ramp(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let t = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f64;
    let mix = |k: usize| (STOPS[i][k] + (STOPS[i + 1][k] - STOPS[i][k]) * f).round() as u8;
    [mix(0), mix(1), mix(2)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png_with_missing_cells_marked() {
        let dir = std::env::temp_dir().join(format!("scanhil-report-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("map.png");
        let cells = [Some(0.0), None, Some(1.0), Some(0.5)];
        let map = HeightMapImage {
            width: 2,
            height: 2,
            cells: &cells,
        };
        assert_eq!(write_height_map_png(&path, &map).unwrap(), Some((0.0, 1.0)));
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (2, 2));
        assert_eq!(img.get_pixel(1, 0).0, MISSING_RGB);
        assert_eq!(img.get_pixel(0, 0).0, ramp(0.0));
        assert_eq!(img.get_pixel(0, 1).0, ramp(1.0));
    }

    #[test]
    fn refuses_a_grid_whose_size_does_not_match() {
        let cells = [Some(0.0); 3];
        let map = HeightMapImage {
            width: 2,
            height: 2,
            cells: &cells,
        };
        let err = write_height_map_png(Path::new("x.png"), &map).unwrap_err();
        assert!(err.to_string().contains("2x2 but has 3 cells"), "{err}");
    }
}
