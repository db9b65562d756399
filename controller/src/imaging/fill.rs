//! Filling the missing cells of a height map, when asked.
//!
//! - [`FillMethod::Nearest`]: a missing cell takes the height of the nearest measured cell
//!   (exact Euclidean distance between cell centres, from the two-pass distance transform of
//!   Felzenszwalb and Huttenlocher; ties go to the lower row, then the lower column).
//! - [`FillMethod::Diffusion`]: missing cells are the harmonic interpolant of the measured
//!   ones: the discrete Laplace equation is solved over the missing cells with the measured
//!   cells held fixed (Dirichlet) and zero slope at the grid border (Neumann), by successive
//!   over-relaxation (the optimal factor for the grid size) started from the nearest fill. Holes get smooth surfaces that meet every
//!   measured edge without overshoot (maximum principle).
//!
//! Filled cells keep `samples == 0`, so they stay distinguishable from measured ones.

use super::grid::HeightMap;

/// How to fill missing cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FillMethod {
    /// Leave missing cells missing.
    None,
    /// Copy the nearest measured cell.
    Nearest,
    /// Harmonic (Laplace) interpolation of the measured cells.
    Diffusion,
}

/// The diffusion fill stops when no cell changes by more than this in a sweep, in mm.
pub const DIFFUSION_TOLERANCE_MM: f64 = 1e-6;
/// The most SOR sweeps the diffusion fill makes.
pub const DIFFUSION_MAX_SWEEPS: usize = 10_000;

/// What a fill did.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FillReport {
    /// The method used.
    pub method: FillMethod,
    /// How many cells were filled.
    pub filled_cells: usize,
    /// SOR sweeps made (diffusion only).
    pub sweeps: usize,
    /// The largest change in the last sweep, in mm (diffusion only).
    pub last_update_mm: f64,
}

/// Fills the missing cells of `map` in place. A map with no measured cell stays empty.
pub fn fill_missing(map: &mut HeightMap, method: FillMethod) -> FillReport {
    let missing: Vec<usize> = (0..map.heights_mm.len())
        .filter(|&i| map.heights_mm[i].is_none())
        .collect();
    let mut report = FillReport {
        method,
        filled_cells: 0,
        sweeps: 0,
        last_update_mm: 0.0,
    };
    if method == FillMethod::None || missing.is_empty() || missing.len() == map.heights_mm.len() {
        return report;
    }
    let nearest = nearest_known(map);
    for &i in &missing {
        map.heights_mm[i] = nearest[i].and_then(|k| map.heights_mm[k]);
    }
    report.filled_cells = missing.len();
    if method == FillMethod::Diffusion {
        let (sweeps, last) = relax(map, &missing);
        report.sweeps = sweeps;
        report.last_update_mm = last;
    }
    report
}

/// For every cell, the index of the nearest cell holding a height (itself if it has one).
fn nearest_known(map: &HeightMap) -> Vec<Option<usize>> {
    let (nx, ny) = (map.spec.nx, map.spec.ny);
    let known = |ix: usize, iy: usize| map.heights_mm[iy * nx + ix].is_some();
    // Pass 1, per column: the nearest known row (by |dy|) for every row.
    let mut column_nearest = vec![None::<usize>; nx * ny];
    for ix in 0..nx {
        let mut last = None;
        for iy in 0..ny {
            if known(ix, iy) {
                last = Some(iy);
            }
            column_nearest[iy * nx + ix] = last;
        }
        let mut next = None;
        for iy in (0..ny).rev() {
            if known(ix, iy) {
                next = Some(iy);
            }
            let slot = &mut column_nearest[iy * nx + ix];
            if let Some(n) = next
                && slot.is_none_or(|l| n - iy < iy - l)
            {
                *slot = Some(n);
            }
        }
    }
    // Pass 2, per row: minimise (x - x')^2 + g(x')^2 by the lower envelope of parabolas.
    let mut result = vec![None; nx * ny];
    let mut hull_x = vec![0usize; nx];
    let mut hull_start = vec![0f64; nx + 1];
    for iy in 0..ny {
        let g = |ix: usize| -> Option<f64> {
            column_nearest[iy * nx + ix].map(|r| (r as f64 - iy as f64).powi(2))
        };
        let mut k: isize = -1;
        for q in 0..nx {
            let Some(gq) = g(q) else { continue };
            loop {
                if k < 0 {
                    k = 0;
                    hull_x[0] = q;
                    hull_start[0] = f64::NEG_INFINITY;
                    break;
                }
                let p = hull_x[k as usize];
                let gp = g(p).unwrap_or(f64::INFINITY);
                let s = ((gq + (q * q) as f64) - (gp + (p * p) as f64)) / (2.0 * (q - p) as f64);
                if s <= hull_start[k as usize] {
                    k -= 1;
                } else {
                    k += 1;
                    hull_x[k as usize] = q;
                    hull_start[k as usize] = s;
                    break;
                }
            }
        }
        if k < 0 {
            continue;
        }
        hull_start[k as usize + 1] = f64::INFINITY;
        let mut j = 0usize;
        for ix in 0..nx {
            while hull_start[j + 1] < ix as f64 {
                j += 1;
            }
            let col = hull_x[j];
            result[iy * nx + ix] = column_nearest[iy * nx + col].map(|row| row * nx + col);
        }
    }
    result
}

/// SOR sweeps of the discrete Laplace equation over the `missing` cells.
fn relax(map: &mut HeightMap, missing: &[usize]) -> (usize, f64) {
    let (nx, ny) = (map.spec.nx, map.spec.ny);
    let mut h: Vec<f64> = map.heights_mm.iter().map(|v| v.unwrap_or(0.0)).collect();
    // The optimal SOR factor for the Laplace equation on the longer grid side.
    let omega = 2.0 / (1.0 + (std::f64::consts::PI / nx.max(ny) as f64).sin());
    let mut last = 0.0;
    for sweep in 1..=DIFFUSION_MAX_SWEEPS {
        last = 0.0f64;
        for &i in missing {
            let (ix, iy) = (i % nx, i / nx);
            let mut sum = 0.0;
            let mut n = 0.0;
            if ix > 0 {
                sum += h[i - 1];
                n += 1.0;
            }
            if ix + 1 < nx {
                sum += h[i + 1];
                n += 1.0;
            }
            if iy > 0 {
                sum += h[i - nx];
                n += 1.0;
            }
            if iy + 1 < ny {
                sum += h[i + nx];
                n += 1.0;
            }
            if n == 0.0 {
                continue;
            }
            let update = omega * (sum / n - h[i]);
            h[i] += update;
            last = last.max(update.abs());
        }
        if last <= DIFFUSION_TOLERANCE_MM {
            for &i in missing {
                map.heights_mm[i] = Some(h[i]);
            }
            return (sweep, last);
        }
    }
    for &i in missing {
        map.heights_mm[i] = Some(h[i]);
    }
    (DIFFUSION_MAX_SWEEPS, last)
}
