//! Height maps: loading a grid of heights from a PNG or CSV file, and the triangulated
//! surface through it with a grid-walking ray intersection.
//!
//! Grid convention: row 0 is the +y edge, column 0 the -x edge (an image as seen from
//! above, x to the right, y up). Between samples the surface is two triangles per cell, split
//! along the cell's diagonal from (col, row) to (col + 1, row + 1). Outside the grid the edge
//! heights continue.

use std::path::Path;

use nalgebra::{Point3, Vector3};

use super::SurfaceError;
use super::hit::{Hit, T_MIN_MM};

/// Longest ray stretch walked for a ray that runs level with the map, mm.
const LEVEL_RAY_LIMIT_MM: f64 = 1.0e4;

/// A grid of heights as read from a file, before it is placed in space.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightGrid {
    /// Samples per row.
    pub cols: usize,
    /// Number of rows.
    pub rows: usize,
    /// Heights in mm, row-major, row 0 first.
    pub heights_mm: Vec<f64>,
}

impl HeightGrid {
    /// Reads a `.png` (8- or 16-bit grey; `value / max * height_scale_mm`) or `.csv` (numbers
    /// separated by commas, one row per line, `#` comments; `value * height_scale_mm`) file.
    ///
    /// # Errors
    /// [`SurfaceError`] naming the file and, for CSV, the line and column of a bad number.
    pub fn load(path: &Path, height_scale_mm: f64) -> Result<HeightGrid, SurfaceError> {
        let bytes = std::fs::read(path).map_err(|source| SurfaceError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, path, height_scale_mm)
    }

    /// Reads a height map from the bytes of the file `origin`, whose extension (`.png` or
    /// `.csv`) says the format, as [`HeightGrid::load`] does.
    ///
    /// # Errors
    /// As [`HeightGrid::load`], naming `origin`.
    pub fn from_bytes(
        bytes: &[u8],
        origin: &Path,
        height_scale_mm: f64,
    ) -> Result<HeightGrid, SurfaceError> {
        let extension = origin
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let grid = match extension.as_deref() {
            Some("png") => Self::from_png(bytes, origin, height_scale_mm)?,
            Some("csv") => Self::from_csv(bytes, origin, height_scale_mm)?,
            _ => {
                return Err(SurfaceError::UnsupportedFile {
                    path: origin.to_path_buf(),
                });
            }
        };
        if grid.cols < 2 || grid.rows < 2 {
            return Err(SurfaceError::HeightMapTooSmall {
                path: origin.to_path_buf(),
                cols: grid.cols,
                rows: grid.rows,
            });
        }
        Ok(grid)
    }

    fn from_png(bytes: &[u8], path: &Path, scale: f64) -> Result<HeightGrid, SurfaceError> {
        let image_error = |message: String| SurfaceError::Image {
            path: path.to_path_buf(),
            message,
        };
        let image =
            image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::Png)
                .decode()
                .map_err(|e| image_error(e.to_string()))?;
        let (cols, rows) = (image.width() as usize, image.height() as usize);
        let heights_mm = match image {
            image::DynamicImage::ImageLuma8(img) => img
                .pixels()
                .map(|p| f64::from(p.0[0]) / 255.0 * scale)
                .collect(),
            image::DynamicImage::ImageLuma16(img) => img
                .pixels()
                .map(|p| f64::from(p.0[0]) / 65535.0 * scale)
                .collect(),
            other => {
                return Err(image_error(format!(
                    "expected an 8- or 16-bit greyscale PNG, found {:?}",
                    other.color()
                )));
            }
        };
        Ok(HeightGrid {
            cols,
            rows,
            heights_mm,
        })
    }

    fn from_csv(bytes: &[u8], path: &Path, scale: f64) -> Result<HeightGrid, SurfaceError> {
        let text = std::str::from_utf8(bytes).map_err(|error| SurfaceError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidData, error),
        })?;
        let mut heights_mm = Vec::new();
        let (mut cols, mut rows) = (0, 0);
        for (line_index, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let bad = |column: usize, reason: String| SurfaceError::Csv {
                path: path.to_path_buf(),
                line: line_index + 1,
                column,
                reason,
            };
            let mut count = 0;
            for (column_index, cell) in line.split(',').enumerate() {
                let value: f64 = cell.trim().parse().map_err(|_| {
                    bad(
                        column_index + 1,
                        format!("`{}` is not a number", cell.trim()),
                    )
                })?;
                if !value.is_finite() {
                    return Err(bad(
                        column_index + 1,
                        format!("`{}` is not finite", cell.trim()),
                    ));
                }
                heights_mm.push(value * scale);
                count += 1;
            }
            if rows > 0 && count != cols {
                return Err(bad(
                    count,
                    format!("row has {count} values, the first row has {cols}"),
                ));
            }
            cols = count;
            rows += 1;
        }
        Ok(HeightGrid {
            cols,
            rows,
            heights_mm,
        })
    }
}

/// A height grid placed in space: absolute z per sample, sample spacing and position.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightField {
    cols: usize,
    rows: usize,
    z_mm: Vec<f64>,
    x0_mm: f64,
    y0_mm: f64,
    pixel_mm: f64,
    z_min_mm: f64,
    z_max_mm: f64,
}

impl HeightField {
    /// Places `grid` with sample spacing `pixel_mm`, centred on `(center_x_mm, center_y_mm)`,
    /// heights added to `base_z_mm`.
    #[must_use]
    pub fn new(
        grid: HeightGrid,
        pixel_mm: f64,
        center_x_mm: f64,
        center_y_mm: f64,
        base_z_mm: f64,
    ) -> HeightField {
        let z_mm: Vec<f64> = grid.heights_mm.iter().map(|h| base_z_mm + h).collect();
        let z_min_mm = z_mm.iter().copied().fold(f64::INFINITY, f64::min);
        let z_max_mm = z_mm.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        HeightField {
            cols: grid.cols,
            rows: grid.rows,
            x0_mm: center_x_mm - 0.5 * (grid.cols - 1) as f64 * pixel_mm,
            y0_mm: center_y_mm + 0.5 * (grid.rows - 1) as f64 * pixel_mm,
            pixel_mm,
            z_mm,
            z_min_mm,
            z_max_mm,
        }
    }

    /// z of sample (col, row), clamped to the grid.
    fn z_at(&self, col: i64, row: i64) -> f64 {
        let c = col.clamp(0, self.cols as i64 - 1) as usize;
        let r = row.clamp(0, self.rows as i64 - 1) as usize;
        self.z_mm[r * self.cols + c]
    }

    fn corner(&self, col: i64, row: i64) -> Point3<f64> {
        Point3::new(
            self.x0_mm + col as f64 * self.pixel_mm,
            self.y0_mm - row as f64 * self.pixel_mm,
            self.z_at(col, row),
        )
    }

    /// Grid coordinates (fractional column, row) of a point.
    fn grid_coordinates(&self, x_mm: f64, y_mm: f64) -> (f64, f64) {
        (
            (x_mm - self.x0_mm) / self.pixel_mm,
            (self.y0_mm - y_mm) / self.pixel_mm,
        )
    }

    /// The surface's z at (x, y), interpolated on the cell's triangles.
    #[must_use]
    pub fn height_at(&self, x_mm: f64, y_mm: f64) -> f64 {
        let (u, v) = self.grid_coordinates(x_mm, y_mm);
        let (i, j) = (u.floor() as i64, v.floor() as i64);
        let (fu, fv) = (u - i as f64, v - j as f64);
        let (h00, h10, h11, h01) = (
            self.z_at(i, j),
            self.z_at(i + 1, j),
            self.z_at(i + 1, j + 1),
            self.z_at(i, j + 1),
        );
        if fu >= fv {
            h00 + fu * (h10 - h00) + fv * (h11 - h10)
        } else {
            h00 + fv * (h01 - h00) + fu * (h11 - h01)
        }
    }

    /// The nearest crossing with `T_MIN_MM < t < t_max` of the ray (unit `dir`), walking the
    /// grid cells under the part of the ray that lies between the map's lowest and highest z.
    #[must_use]
    pub fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>, t_max: f64) -> Option<Hit> {
        let (t0, t1) = if dir.z.abs() > 1e-12 {
            let ta = (self.z_max_mm - origin.z) / dir.z;
            let tb = (self.z_min_mm - origin.z) / dir.z;
            (ta.min(tb).max(0.0), ta.max(tb).min(t_max))
        } else if origin.z >= self.z_min_mm && origin.z <= self.z_max_mm {
            (0.0, t_max.min(LEVEL_RAY_LIMIT_MM))
        } else {
            return None;
        };
        if t0.is_nan() || t1.is_nan() || t0 > t1 {
            return None;
        }
        let start = origin + t0 * dir;
        let (u, v) = self.grid_coordinates(start.x, start.y);
        let (mut i, mut j) = (u.floor() as i64, v.floor() as i64);
        // Grid coordinates change by du, dv per mm along the ray.
        let (du, dv) = (dir.x / self.pixel_mm, -dir.y / self.pixel_mm);
        let axis_step = |d: f64, pos: f64, cell: i64| -> (i64, f64, f64) {
            if d > 0.0 {
                (1, t0 + ((cell + 1) as f64 - pos) / d, 1.0 / d)
            } else if d < 0.0 {
                (-1, t0 + (cell as f64 - pos) / d, -1.0 / d)
            } else {
                (0, f64::INFINITY, f64::INFINITY)
            }
        };
        let (step_i, mut next_u, delta_u) = axis_step(du, u, i);
        let (step_j, mut next_v, delta_v) = axis_step(dv, v, j);
        let cells = ((t1 - t0) * (du.abs() + dv.abs())).ceil() as usize + 2;
        for _ in 0..cells {
            if let Some(hit) = self.intersect_cell(i, j, origin, dir, t_max) {
                return Some(hit);
            }
            if next_u.min(next_v) > t1 {
                break;
            }
            if next_u < next_v {
                i += step_i;
                next_u += delta_u;
            } else {
                j += step_j;
                next_v += delta_v;
            }
        }
        None
    }

    fn intersect_cell(
        &self,
        i: i64,
        j: i64,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        t_max: f64,
    ) -> Option<Hit> {
        let (p00, p10, p11, p01) = (
            self.corner(i, j),
            self.corner(i + 1, j),
            self.corner(i + 1, j + 1),
            self.corner(i, j + 1),
        );
        [
            triangle(origin, dir, &p00, &p10, &p11, t_max),
            triangle(origin, dir, &p00, &p11, &p01, t_max),
        ]
        .into_iter()
        .flatten()
        .min_by(|a, b| a.t_mm.total_cmp(&b.t_mm))
    }
}

/// Moller-Trumbore ray-triangle intersection; the normal faces up (+z).
fn triangle(
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
    t_max: f64,
) -> Option<Hit> {
    const EDGE_TOLERANCE: f64 = 1e-12;
    let (e1, e2) = (b - a, c - a);
    let p = dir.cross(&e2);
    let det = e1.dot(&p);
    if det.abs() < 1e-18 {
        return None;
    }
    let s = origin - a;
    let bu = s.dot(&p) / det;
    let q = s.cross(&e1);
    let bv = dir.dot(&q) / det;
    if bu < -EDGE_TOLERANCE || bv < -EDGE_TOLERANCE || bu + bv > 1.0 + EDGE_TOLERANCE {
        return None;
    }
    let t = e2.dot(&q) / det;
    if !(t > T_MIN_MM && t < t_max) {
        return None;
    }
    let n = e1.cross(&e2).normalize();
    Some(Hit {
        t_mm: t,
        point_mm: origin + t * dir,
        normal: if n.z < 0.0 { -n } else { n },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp_grid() -> HeightGrid {
        // 3 x 3, rising 1 mm per column: a plane tilted along x.
        HeightGrid {
            cols: 3,
            rows: 3,
            heights_mm: vec![0.0, 1.0, 2.0, 0.0, 1.0, 2.0, 0.0, 1.0, 2.0],
        }
    }

    #[test]
    fn ramp_heights_and_vertical_hits_agree() {
        let field = HeightField::new(ramp_grid(), 1.0, 0.0, 0.0, -100.0);
        for (x, y) in [(0.0, 0.0), (0.3, -0.7), (-0.9, 0.9)] {
            let want = -100.0 + 1.0 + x;
            assert!((field.height_at(x, y) - want).abs() < 1e-12);
            let hit = field
                .intersect(&Point3::new(x, y, 0.0), &-Vector3::z(), f64::INFINITY)
                .unwrap();
            assert!(
                (hit.point_mm.z - want).abs() < 1e-9,
                "{x} {y}: {}",
                hit.point_mm.z
            );
            let slope = Vector3::new(-1.0, 0.0, 1.0).normalize();
            assert!((hit.normal - slope).norm() < 1e-9);
        }
        // Outside the grid the edge heights continue.
        assert!((field.height_at(5.0, 0.0) - (-98.0)).abs() < 1e-12);
    }

    #[test]
    fn slanted_ray_walks_cells_to_the_right_hit() {
        // A single tall sample in a flat 5 x 5 map blocks a ray coming in sideways.
        let mut heights_mm = vec![0.0; 25];
        heights_mm[12] = 10.0;
        let field = HeightField::new(
            HeightGrid {
                cols: 5,
                rows: 5,
                heights_mm,
            },
            1.0,
            0.0,
            0.0,
            0.0,
        );
        let dir = Vector3::new(1.0, 0.0, -1.0).normalize();
        let hit = field
            .intersect(&Point3::new(-10.0, 0.0, 10.0), &dir, f64::INFINITY)
            .unwrap();
        // Going down at 45 deg towards the peak's flank (z = 10 (1 + x) for -1 < x < 0).
        assert!(
            hit.point_mm.x < 0.0 && hit.point_mm.x > -1.0,
            "{:?}",
            hit.point_mm
        );
        assert!((hit.point_mm.z - field.height_at(hit.point_mm.x, 0.0)).abs() < 1e-9);
    }

    /// The nearest hit over every cell in and around the grid, without the grid walk.
    fn brute_force(field: &HeightField, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<f64> {
        let (c, r) = (field.cols as i64, field.rows as i64);
        (-3..c + 3)
            .flat_map(|i| (-3..r + 3).map(move |j| (i, j)))
            .filter_map(|(i, j)| field.intersect_cell(i, j, origin, dir, f64::INFINITY))
            .map(|h| h.t_mm)
            .min_by(f64::total_cmp)
    }

    proptest::proptest! {
        #[test]
        fn grid_walk_finds_the_nearest_triangle(
            heights in proptest::collection::vec(0.0f64..3.0, 36),
            x in -2.0f64..2.0, y in -2.0f64..2.0, dx in -0.6f64..0.6, dy in -0.6f64..0.6,
        ) {
            let field = HeightField::new(HeightGrid { cols: 6, rows: 6, heights_mm: heights }, 0.5, 0.0, 0.0, -10.0);
            let origin = Point3::new(x, y, 0.0);
            let dir = Vector3::new(dx, dy, -1.0).normalize();
            // Only rays whose hit lies over the grid's cells are comparable with the brute force.
            let walked = field.intersect(&origin, &dir, f64::INFINITY).map(|h| h.t_mm);
            let brute = brute_force(&field, &origin, &dir);
            if let Some(b) = brute {
                let w = walked.expect("grid walk missed a hit");
                proptest::prop_assert!((w - b).abs() < 1e-9, "walk {} vs brute {}", w, b);
            }
        }
    }

    #[test]
    fn csv_errors_name_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.csv");
        std::fs::write(&path, "# heights\n0,1,2\n0,x,2\n").unwrap();
        let err = HeightGrid::load(&path, 1.0).unwrap_err().to_string();
        assert!(
            err.contains("line 3") && err.contains("column 2") && err.contains("bad.csv"),
            "{err}"
        );
        std::fs::write(&path, "0,1,2\n0,1\n").unwrap();
        let err = HeightGrid::load(&path, 1.0).unwrap_err().to_string();
        assert!(err.contains("line 2"), "{err}");
    }

    #[test]
    fn png_16_and_8_bit_scale_to_full_range() {
        let dir = tempfile::tempdir().unwrap();
        let p16 = dir.path().join("h16.png");
        image::ImageBuffer::<image::Luma<u16>, _>::from_fn(2, 2, |x, _| {
            image::Luma([if x == 0 { 0 } else { 65535 }])
        })
        .save(&p16)
        .unwrap();
        let g = HeightGrid::load(&p16, 5.0).unwrap();
        assert_eq!((g.cols, g.rows), (2, 2));
        assert_eq!(g.heights_mm, vec![0.0, 5.0, 0.0, 5.0]);
        let p8 = dir.path().join("h8.png");
        image::GrayImage::from_fn(2, 3, |_, y| image::Luma([if y == 0 { 255 } else { 51 }]))
            .save(&p8)
            .unwrap();
        let g = HeightGrid::load(&p8, 1.0).unwrap();
        assert_eq!((g.cols, g.rows), (2, 3));
        assert!((g.heights_mm[2] - 0.2).abs() < 1e-12 && g.heights_mm[0] == 1.0);
        let rgb = dir.path().join("rgb.png");
        image::RgbImage::new(2, 2).save(&rgb).unwrap();
        assert!(
            HeightGrid::load(&rgb, 1.0)
                .unwrap_err()
                .to_string()
                .contains("greyscale")
        );
    }
}
