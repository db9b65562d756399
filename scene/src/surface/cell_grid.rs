//! A uniform grid of cells in x and y, one face per cell (often a group of faces): a ray tests only the cells its path crosses inside the grid's box, however many
//! cells there are (the Duplo brick's studs sit one per cell). The grid is a spatial index
//! only: it holds its cells' faces whatever they are, and never looks into them.
//!
//! Cells are found conservatively (the path's x-y extent inside the padded box, widened by
//! [`super::bounds::PAD_MM`]), so the grid answers as the flat list of its faces.

use nalgebra::{Point3, Vector3};

use super::bounds::{Aabb, PAD_MM};

/// Faces sorted into a `columns` x `rows` grid of `cell_mm` square cells.
#[derive(Debug, Clone, PartialEq)]
pub struct CellGrid<F> {
    /// A box around every cell's face (the grid's x-y extent and the faces' z range).
    bounds: Aabb,
    /// Smallest x and y of cell (0, 0), mm.
    corner_mm: [f64; 2],
    /// Cell side, mm.
    cell_mm: f64,
    /// Cells along x.
    columns: usize,
    /// Cells along y.
    rows: usize,
    /// One face per cell, column-major: cell (i, j) at `i * rows + j`.
    cells: Vec<F>,
}

impl<F> CellGrid<F> {
    /// A grid of `cells` (column-major, `columns * rows` of them, each face inside its cell)
    /// with cell (0, 0) starting at `corner_mm`, whose faces lie between `z_min` and `z_max`.
    ///
    /// # Panics
    /// When `cells` does not have `columns * rows` faces or `cell_mm` is not positive (the
    /// shapes that build grids pass constants).
    #[must_use]
    pub fn new(
        corner_mm: [f64; 2],
        cell_mm: f64,
        (columns, rows): (usize, usize),
        (z_min, z_max): (f64, f64),
        cells: Vec<F>,
    ) -> CellGrid<F> {
        assert!(cells.len() == columns * rows && cell_mm > 0.0);
        let far = |n: usize, start: f64| start + n as f64 * cell_mm;
        CellGrid {
            bounds: Aabb::around(
                Point3::new(corner_mm[0], corner_mm[1], z_min),
                Point3::new(far(columns, corner_mm[0]), far(rows, corner_mm[1]), z_max),
            ),
            corner_mm,
            cell_mm,
            columns,
            rows,
            cells,
        }
    }

    /// Every cell's face, column-major.
    #[must_use]
    pub fn faces(&self) -> &[F] {
        &self.cells
    }

    /// The faces of the cells the ray `origin + t dir`, `t_min <= t <= t_max`, may meet, in
    /// grid order (none when it misses the grid's box).
    pub fn faces_along(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        t_min: f64,
        t_max: f64,
    ) -> impl Iterator<Item = &F> {
        let span = self.bounds.span(origin, dir, t_min, t_max);
        let (columns, rows) = span.map_or((0..0, 0..0), |(enter, exit)| {
            let (a, b) = (origin + enter * dir, origin + exit * dir);
            (
                self.cell_range(a.x, b.x, self.corner_mm[0], self.columns),
                self.cell_range(a.y, b.y, self.corner_mm[1], self.rows),
            )
        });
        columns
            .flat_map(move |i| self.cells[i * self.rows..(i + 1) * self.rows][rows.clone()].iter())
    }

    /// The cells along one axis between coordinates `a` and `b` (either order), padded.
    fn cell_range(&self, a: f64, b: f64, start: f64, count: usize) -> std::ops::Range<usize> {
        let index = |v: f64| {
            ((v - start) / self.cell_mm)
                .floor()
                .clamp(0.0, (count - 1) as f64)
        };
        let (low, high) = (a.min(b) - PAD_MM, a.max(b) + PAD_MM);
        if !(low.is_finite() && high.is_finite()) {
            return 0..count;
        }
        index(low) as usize..index(high) as usize + 1
    }
}
