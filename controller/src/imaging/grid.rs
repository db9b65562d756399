//! Gridding scattered points onto a regular height map.
//!
//! Neither trajectory puts its samples on a grid (a Lissajous figure crosses cells at every
//! angle; a raster's fast axis is sampled along slanted triangle flanks), so every map is
//! built the same way: each sample adds to the cells near it.
//!
//! - [`GridMethod::CellMean`]: a cell's height is the mean of the samples that fall inside it.
//! - [`GridMethod::InverseDistance`] (the default): a cell's height is the inverse-distance
//!   weighted mean (weight `1 / max(d, pitch/20)^power`) of the samples within
//!   `radius_pitches * pitch` of the cell centre. With the default radius of one pitch every
//!   sample reaches its own cell (at most `pitch/sqrt(2)` away) and the four edge neighbours,
//!   which bridges the gap between neighbouring scan lines up to one pitch wide without
//!   blurring further.
//!
//! A cell no sample reaches is missing (`None`); [`super::fill`] fills missing cells when
//! asked. Row `iy = 0` is the lowest y; the PNG shows +y up and +x to the right, in mm.

use std::io::{self, Write};
use std::path::Path;

use scanhil_report::{MapFigure, MapPanel, ReportError, draw_height_maps};

/// The regular grid: origin corner, pitch and size.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GridSpec {
    /// The x of the left edge of column 0, in mm.
    pub x_min_mm: f64,
    /// The y of the lower edge of row 0, in mm.
    pub y_min_mm: f64,
    /// The side of a (square) cell, in mm.
    pub pitch_mm: f64,
    /// Number of columns (along x).
    pub nx: usize,
    /// Number of rows (along y).
    pub ny: usize,
}

/// Why a grid could not be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// The pitch is not a positive finite number.
    #[error("grid pitch {pitch_mm} mm must be positive and finite")]
    BadPitch {
        /// The pitch given.
        pitch_mm: f64,
    },
    /// There are no finite points to span a grid over.
    #[error("no finite point to span a grid over")]
    NoPoints,
    /// The grid would have more cells than allowed.
    #[error(
        "grid of {nx} x {ny} cells exceeds the limit of {limit} cells: the pitch must be at \
         least {smallest_pitch_mm} mm"
    )]
    TooLarge {
        /// Columns asked for.
        nx: usize,
        /// Rows asked for.
        ny: usize,
        /// The limit.
        limit: usize,
        /// The smallest pitch whose grid fits the limit, mm.
        smallest_pitch_mm: f64,
    },
}

/// The most cells a grid may have: 4 Mi cells (2048 x 2048, a 0.02 mm pitch over a 40 mm
/// scan, finer than the ILD 2300's spot). Imaging holds about [`BYTES_PER_CELL`] a cell (730
/// MB at the limit) and the height map's CSV about [`CSV_BYTES_PER_CELL`] (210 MB).
pub const MAX_CELLS: usize = 1 << 22;

/// Imaging's working memory per grid cell, bytes: measured with `/usr/bin/time -v` on the
/// Duplo stud scan at pitches of 0.01 and 0.005 mm (0.97 and 3.9 M cells: 175 and 176 bytes
/// a cell above the run's own 20 MB).
pub const BYTES_PER_CELL: f64 = 176.0;

/// The height map CSV's bytes per cell (a line of x, y, height, samples and state: 50 bytes
/// on that scan).
pub const CSV_BYTES_PER_CELL: f64 = 52.0;

/// Cells of a grid of `pitch_mm` over a `width_mm` x `height_mm` rectangle, as
/// [`GridSpec::spanning`] lays it: one more than the whole pitches in each direction.
#[must_use]
pub fn cells_over(width_mm: f64, height_mm: f64, pitch_mm: f64) -> f64 {
    ((width_mm / pitch_mm).floor() + 1.0) * ((height_mm / pitch_mm).floor() + 1.0)
}

/// The smallest pitch whose grid over a `width_mm` x `height_mm` rectangle has at most
/// `cells` cells, mm, rounded up in its third significant digit (so it fits as printed).
#[must_use]
pub fn smallest_pitch_mm(width_mm: f64, height_mm: f64, cells: f64) -> f64 {
    // (w u + 1)(h u + 1) = cells for u = 1 / pitch.
    let (a, b, c) = (width_mm * height_mm, width_mm + height_mm, 1.0 - cells);
    let u = if a > 0.0 {
        (-b + (b * b - 4.0 * a * c).sqrt()) / (2.0 * a)
    } else {
        -c / b
    };
    round_up_3(1.0 / u)
}

/// `value` rounded up to three significant digits.
fn round_up_3(value: f64) -> f64 {
    if !(value.is_finite() && value > 0.0) {
        return value;
    }
    let scale = 10f64.powi(2 - value.log10().floor() as i32);
    (value * scale).ceil() / scale
}

impl GridSpec {
    /// The smallest grid of `pitch_mm` whose cells cover every finite `(x, y)` point.
    pub fn covering(
        points: impl IntoIterator<Item = (f64, f64)>,
        pitch_mm: f64,
    ) -> Result<GridSpec, GridError> {
        let mut bounds: Option<(f64, f64, f64, f64)> = None;
        for (x, y) in points {
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            bounds = Some(match bounds {
                None => (x, x, y, y),
                Some((x0, x1, y0, y1)) => (x0.min(x), x1.max(x), y0.min(y), y1.max(y)),
            });
        }
        let (x0, x1, y0, y1) = bounds.ok_or(GridError::NoPoints)?;
        GridSpec::spanning(x0, x1, y0, y1, pitch_mm)
    }

    /// A grid of `pitch_mm` centred on the rectangle `[x0, x1] x [y0, y1]`, with enough cells
    /// to cover it.
    pub fn spanning(
        x0_mm: f64,
        x1_mm: f64,
        y0_mm: f64,
        y1_mm: f64,
        pitch_mm: f64,
    ) -> Result<GridSpec, GridError> {
        if !(pitch_mm.is_finite() && pitch_mm > 0.0) {
            return Err(GridError::BadPitch { pitch_mm });
        }
        let cells = |lo: f64, hi: f64| ((hi - lo) / pitch_mm).floor().max(0.0) + 1.0;
        let (fx, fy) = (cells(x0_mm, x1_mm), cells(y0_mm, y1_mm));
        if fx * fy > MAX_CELLS as f64 {
            return Err(GridError::TooLarge {
                nx: fx as usize,
                ny: fy as usize,
                limit: MAX_CELLS,
                smallest_pitch_mm: smallest_pitch_mm(
                    x1_mm - x0_mm,
                    y1_mm - y0_mm,
                    MAX_CELLS as f64,
                ),
            });
        }
        let (nx, ny) = (fx as usize, fy as usize);
        let centre = |lo: f64, hi: f64, n: usize| 0.5 * (lo + hi) - 0.5 * n as f64 * pitch_mm;
        Ok(GridSpec {
            x_min_mm: centre(x0_mm, x1_mm, nx),
            y_min_mm: centre(y0_mm, y1_mm, ny),
            pitch_mm,
            nx,
            ny,
        })
    }

    /// Number of cells.
    #[must_use]
    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    /// Whether the grid has no cell.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The index of cell `(ix, iy)` in row-major storage.
    #[must_use]
    pub fn index(&self, ix: usize, iy: usize) -> usize {
        iy * self.nx + ix
    }

    /// The centre of cell `(ix, iy)`, in mm.
    #[must_use]
    pub fn centre_mm(&self, ix: usize, iy: usize) -> (f64, f64) {
        (
            self.x_min_mm + (ix as f64 + 0.5) * self.pitch_mm,
            self.y_min_mm + (iy as f64 + 0.5) * self.pitch_mm,
        )
    }

    /// The cell holding `(x, y)`, or `None` outside the grid.
    #[must_use]
    pub fn cell_of(&self, x_mm: f64, y_mm: f64) -> Option<(usize, usize)> {
        let fx = ((x_mm - self.x_min_mm) / self.pitch_mm).floor();
        let fy = ((y_mm - self.y_min_mm) / self.pitch_mm).floor();
        (fx >= 0.0 && fy >= 0.0 && fx < self.nx as f64 && fy < self.ny as f64)
            .then_some((fx as usize, fy as usize))
    }
}

/// How samples become cell heights (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "method", rename_all = "snake_case")]
pub enum GridMethod {
    /// The mean of the samples inside the cell.
    CellMean,
    /// Inverse-distance weighted mean of the samples within `radius_pitches` pitches of the
    /// cell centre, weight `1 / max(d, pitch/20)^power`.
    InverseDistance {
        /// The search radius in cell pitches.
        radius_pitches: f64,
        /// The distance exponent.
        power: f64,
    },
}

impl Default for GridMethod {
    fn default() -> Self {
        GridMethod::InverseDistance {
            radius_pitches: 1.0,
            power: 2.0,
        }
    }
}

/// A height map: one optional height per cell and how many samples made it.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightMap {
    /// The grid.
    pub spec: GridSpec,
    /// Row-major heights in mm; `None` marks a missing cell.
    pub heights_mm: Vec<Option<f64>>,
    /// How many samples contributed to each cell; 0 for missing and filled cells.
    pub samples: Vec<u32>,
}

impl HeightMap {
    /// Cells with a measured (not filled) height.
    #[must_use]
    pub fn measured_cells(&self) -> usize {
        self.samples.iter().filter(|&&n| n > 0).count()
    }

    /// The fraction of cells with a measured height, in [0, 1].
    #[must_use]
    pub fn coverage_fraction(&self) -> f64 {
        if self.spec.is_empty() {
            return 0.0;
        }
        self.measured_cells() as f64 / self.spec.len() as f64
    }

    /// Whether cell `i` holds a filled (interpolated) height rather than a measured one.
    #[must_use]
    pub fn is_filled(&self, i: usize) -> bool {
        self.heights_mm[i].is_some() && self.samples[i] == 0
    }

    /// The map as a panel of a height map figure, titled `title`.
    #[must_use]
    pub fn panel(&self, title: impl Into<String>) -> MapPanel<'_> {
        MapPanel {
            title: title.into(),
            x_min_mm: self.spec.x_min_mm,
            y_min_mm: self.spec.y_min_mm,
            pitch_mm: self.spec.pitch_mm,
            nx: self.spec.nx,
            ny: self.spec.ny,
            heights_mm: &self.heights_mm,
        }
    }

    /// Draws the map as a PNG for people ([`draw_height_maps`]): axes in mm (+y up, +x
    /// right), heights in false colour with a colour bar captioned `quantity`, missing cells
    /// grey, `title` on top. Returns the height range the colours span.
    pub fn draw_png(
        &self,
        path: &Path,
        title: &str,
        quantity: &str,
    ) -> Result<Option<(f64, f64)>, ReportError> {
        draw_height_maps(
            path,
            &MapFigure {
                title: title.into(),
                quantity: quantity.into(),
                rows: vec![vec![self.panel(format!(
                    "{} x {} cells of {} mm, {:.1} % measured",
                    self.spec.nx,
                    self.spec.ny,
                    self.spec.pitch_mm,
                    100.0 * self.coverage_fraction()
                ))]],
            },
        )
    }

    /// Writes the map as CSV, one cell per line:
    /// `x_mm,y_mm,height_mm,samples,state` with `state` one of `measured`, `filled`,
    /// `missing` (whose `height_mm` is empty). `x_mm, y_mm` is the cell centre.
    pub fn write_csv<W: Write>(&self, mut out: W) -> io::Result<()> {
        writeln!(out, "x_mm,y_mm,height_mm,samples,state")?;
        for iy in 0..self.spec.ny {
            for ix in 0..self.spec.nx {
                let i = self.spec.index(ix, iy);
                let (x, y) = self.spec.centre_mm(ix, iy);
                let (height, state) = match self.heights_mm[i] {
                    None => (String::new(), "missing"),
                    Some(h) if self.samples[i] > 0 => (format!("{h:?}"), "measured"),
                    Some(h) => (format!("{h:?}"), "filled"),
                };
                writeln!(out, "{x:?},{y:?},{height},{},{state}", self.samples[i])?;
            }
        }
        out.flush()
    }
}

/// Builds a height map sample by sample, so a map is available after any number of
/// samples (progressive imaging) without regridding from the start.
#[derive(Debug, Clone)]
pub struct GridAccumulator {
    spec: GridSpec,
    method: GridMethod,
    weight_sum: Vec<f64>,
    weighted_height_sum: Vec<f64>,
    samples: Vec<u32>,
}

impl GridAccumulator {
    /// An empty accumulator over `spec`.
    #[must_use]
    pub fn new(spec: GridSpec, method: GridMethod) -> GridAccumulator {
        GridAccumulator {
            spec,
            method,
            weight_sum: vec![0.0; spec.len()],
            weighted_height_sum: vec![0.0; spec.len()],
            samples: vec![0; spec.len()],
        }
    }

    /// Adds one sample at `(x, y)` with height `h`; non-finite samples and samples reaching
    /// no cell are ignored.
    pub fn add(&mut self, x_mm: f64, y_mm: f64, h_mm: f64) {
        if !(x_mm.is_finite() && y_mm.is_finite() && h_mm.is_finite()) {
            return;
        }
        let spec = self.spec;
        match self.method {
            GridMethod::CellMean => {
                if let Some((ix, iy)) = spec.cell_of(x_mm, y_mm) {
                    self.accumulate(spec.index(ix, iy), 1.0, h_mm);
                }
            }
            GridMethod::InverseDistance {
                radius_pitches,
                power,
            } => {
                let radius = radius_pitches * spec.pitch_mm;
                let floor = spec.pitch_mm / 20.0;
                let span = |v: f64, min: f64, n: usize| {
                    let lo = ((v - radius - min) / spec.pitch_mm - 0.5).ceil().max(0.0);
                    let hi = ((v + radius - min) / spec.pitch_mm - 0.5).floor();
                    (lo, hi.min(n as f64 - 1.0))
                };
                let (x_lo, x_hi) = span(x_mm, spec.x_min_mm, spec.nx);
                let (y_lo, y_hi) = span(y_mm, spec.y_min_mm, spec.ny);
                if x_lo > x_hi || y_lo > y_hi {
                    return;
                }
                for iy in y_lo as usize..=y_hi as usize {
                    for ix in x_lo as usize..=x_hi as usize {
                        let (cx, cy) = spec.centre_mm(ix, iy);
                        let d = (cx - x_mm).hypot(cy - y_mm);
                        if d <= radius {
                            let w = d.max(floor).powf(-power);
                            self.accumulate(spec.index(ix, iy), w, h_mm);
                        }
                    }
                }
            }
        }
    }

    fn accumulate(&mut self, i: usize, w: f64, h: f64) {
        self.weight_sum[i] += w;
        self.weighted_height_sum[i] += w * h;
        self.samples[i] += 1;
    }

    /// The height map of the samples added so far.
    #[must_use]
    pub fn height_map(&self) -> HeightMap {
        HeightMap {
            spec: self.spec,
            heights_mm: self
                .weight_sum
                .iter()
                .zip(&self.weighted_height_sum)
                .map(|(&w, &wh)| (w > 0.0).then(|| wh / w))
                .collect(),
            samples: self.samples.clone(),
        }
    }
}

/// Grids `(x, y, height)` samples in one go.
#[must_use]
pub fn grid_points(
    points: impl IntoIterator<Item = (f64, f64, f64)>,
    spec: GridSpec,
    method: GridMethod,
) -> HeightMap {
    let mut acc = GridAccumulator::new(spec, method);
    for (x, y, h) in points {
        acc.add(x, y, h);
    }
    acc.height_map()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smallest_pitch_fits_the_cells_and_a_little_less_does_not() {
        for (w, h, cells) in [
            (10.0, 30.0, 1e4),
            (39.2, 12.5, MAX_CELLS as f64),
            (0.0, 5.0, 100.0),
        ] {
            let pitch = smallest_pitch_mm(w, h, cells);
            assert!(cells_over(w, h, pitch) <= cells, "{w} x {h}: {pitch}");
            assert!(cells_over(w, h, pitch * 0.98) > cells, "{w} x {h}: {pitch}");
        }
    }

    #[test]
    fn a_grid_beyond_the_limit_names_the_smallest_pitch_that_fits() {
        let error = GridSpec::spanning(0.0, 40.0, 0.0, 40.0, 1e-3).unwrap_err();
        let GridError::TooLarge {
            smallest_pitch_mm, ..
        } = error
        else {
            panic!("{error}")
        };
        assert!(GridSpec::spanning(0.0, 40.0, 0.0, 40.0, smallest_pitch_mm).is_ok());
        assert!(
            error
                .to_string()
                .ends_with(&format!("at least {smallest_pitch_mm} mm"))
        );
    }

    #[test]
    fn pitches_are_rounded_up_in_their_third_digit() {
        assert_eq!(round_up_3(0.0012301), 0.00124);
        assert_eq!(round_up_3(12.3), 12.3);
        assert_eq!(round_up_3(f64::INFINITY), f64::INFINITY);
    }
}
