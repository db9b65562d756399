//! Height maps drawn for people: each map on x and y axes in mm (square cells, +y up), its
//! heights in false colour on one scale shared by every panel, a colour bar labelled in mm,
//! missing cells in a grey named under the bar, and a title. One PNG holds one or more panels
//! (rows of panels), so progressive snapshots and two scans side by side share one scale.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::chart::tick_label;
use crate::{ReportError, register_font};

/// One height map: a regular grid of square cells, placed in mm.
#[derive(Debug, Clone, PartialEq)]
pub struct MapPanel<'a> {
    /// Drawn above the panel.
    pub title: String,
    /// The x of the left edge of column 0, mm.
    pub x_min_mm: f64,
    /// The y of the lower edge of row 0, mm.
    pub y_min_mm: f64,
    /// The side of a cell, mm.
    pub pitch_mm: f64,
    /// Columns (along x).
    pub nx: usize,
    /// Rows (along y).
    pub ny: usize,
    /// `nx * ny` heights in mm, row-major, row 0 the lowest y (drawn at the bottom); `None`
    /// marks a missing cell.
    pub heights_mm: &'a [Option<f64>],
}

impl MapPanel<'_> {
    /// The panel's extent `(x0, x1, y0, y1)`, mm.
    fn extent_mm(&self) -> (f64, f64, f64, f64) {
        (
            self.x_min_mm,
            self.x_min_mm + self.nx as f64 * self.pitch_mm,
            self.y_min_mm,
            self.y_min_mm + self.ny as f64 * self.pitch_mm,
        )
    }
}

/// Height maps on one colour scale and one extent in mm.
#[derive(Debug, Clone, PartialEq)]
pub struct MapFigure<'a> {
    /// Drawn at the top.
    pub title: String,
    /// The colour bar's caption: what the heights are, with the unit, e.g. `z_s (mm)`.
    pub quantity: String,
    /// Rows of panels, drawn top to bottom, each row left to right.
    pub rows: Vec<Vec<MapPanel<'a>>>,
}

/// The colour of a missing cell: a mid grey, which the colour ramp never reaches.
pub const MISSING_RGB: [u8; 3] = [170, 170, 170];

/// The longer side of a panel's map area when the figure has one panel, px.
pub const SINGLE_MAP_SIDE_PX: u32 = 640;
/// The longer side of each panel's map area when the figure has several, px.
pub const PANEL_MAP_SIDE_PX: u32 = 380;

const TITLE_PX: u32 = 44;
const PANEL_TITLE_PX: u32 = 28;
const MARGIN_PX: u32 = 14;
const X_LABELS_PX: u32 = 48;
const Y_LABELS_PX: u32 = 76;
const BAR_COLUMN_PX: u32 = 190;
const BAR_LABELS_PX: u32 = 84;
const LEGEND_PX: u32 = 70;
const SMALLEST_MAP_SIDE_PX: u32 = 120;

/// Draws `figure` as a PNG at `path` and returns the (min, max) height its colours span, or
/// `None` when no cell has a height. Every panel is drawn over the same x and y range (the
/// union of the panels' grids) with square cells, so panels compare position by position.
///
/// # Errors
/// [`ReportError::UnknownFormat`] for a name not ending in `.png`; [`ReportError::BadData`]
/// for no panel or a panel whose cells do not match its size; [`ReportError::Drawing`] when
/// the file cannot be written.
pub fn draw_height_maps(
    path: &Path,
    figure: &MapFigure<'_>,
) -> Result<Option<(f64, f64)>, ReportError> {
    if path.extension().and_then(|e| e.to_str()) != Some("png") {
        return Err(ReportError::UnknownFormat {
            path: path.to_owned(),
        });
    }
    let bad = |reason: String| ReportError::BadData {
        path: path.to_owned(),
        reason,
    };
    let panels: Vec<&MapPanel<'_>> = figure.rows.iter().flatten().collect();
    if panels.is_empty() {
        return Err(bad("no height map to draw".into()));
    }
    for p in &panels {
        let placed = [p.x_min_mm, p.y_min_mm, p.pitch_mm]
            .iter()
            .all(|v| v.is_finite())
            && p.pitch_mm > 0.0;
        if p.nx == 0 || p.ny == 0 || p.heights_mm.len() != p.nx * p.ny || !placed {
            return Err(bad(format!(
                "height map '{}' is {}x{} cells of {} mm at ({}, {}) mm but has {} cells",
                p.title,
                p.nx,
                p.ny,
                p.pitch_mm,
                p.x_min_mm,
                p.y_min_mm,
                p.heights_mm.len()
            )));
        }
    }
    let range = panels
        .iter()
        .flat_map(|p| p.heights_mm.iter().flatten().copied())
        .filter(|h| h.is_finite())
        .fold(None, |acc: Option<(f64, f64)>, h| match acc {
            None => Some((h, h)),
            Some((lo, hi)) => Some((lo.min(h), hi.max(h))),
        });
    let extent = panels.iter().map(|p| p.extent_mm()).fold(
        (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ),
        |a, e| (a.0.min(e.0), a.1.max(e.1), a.2.min(e.2), a.3.max(e.3)),
    );
    let layout = Layout::new(figure, extent);
    register_font();
    let root = BitMapBackend::new(path, layout.size_px()).into_drawing_area();
    draw_figure(&root, figure, &layout, range).map_err(|reason| ReportError::Drawing {
        path: path.to_owned(),
        reason,
    })?;
    Ok(range)
}

/// Pixel sizes of a figure.
struct Layout {
    rows: u32,
    columns: u32,
    panel_px: (u32, u32),
    extent_mm: (f64, f64, f64, f64),
}

impl Layout {
    fn new(figure: &MapFigure<'_>, extent_mm: (f64, f64, f64, f64)) -> Layout {
        let rows = figure.rows.len() as u32;
        let columns = figure.rows.iter().map(Vec::len).max().unwrap_or(1) as u32;
        let long_side = if rows * columns == 1 {
            SINGLE_MAP_SIDE_PX
        } else {
            PANEL_MAP_SIDE_PX
        };
        let (span_x, span_y) = (extent_mm.1 - extent_mm.0, extent_mm.3 - extent_mm.2);
        let short =
            |ratio: f64| ((long_side as f64 * ratio).round() as u32).max(SMALLEST_MAP_SIDE_PX);
        let (map_w, map_h) = if span_x >= span_y {
            (long_side, short(span_y / span_x))
        } else {
            (short(span_x / span_y), long_side)
        };
        Layout {
            rows,
            columns,
            panel_px: (
                map_w + Y_LABELS_PX + 2 * MARGIN_PX,
                map_h + X_LABELS_PX + PANEL_TITLE_PX + 2 * MARGIN_PX,
            ),
            extent_mm,
        }
    }

    fn size_px(&self) -> (u32, u32) {
        (
            self.columns * self.panel_px.0 + BAR_COLUMN_PX,
            TITLE_PX + (self.rows * self.panel_px.1).max(3 * LEGEND_PX),
        )
    }

    /// The x and y ranges, mm, that fill a map area of `map_px` pixels with square cells and
    /// hold the whole extent, centred on it.
    fn ranges_mm(&self, map_px: (u32, u32)) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
        let (x0, x1, y0, y1) = self.extent_mm;
        let (w, h) = (map_px.0.max(1) as f64, map_px.1.max(1) as f64);
        let mm_per_px = ((x1 - x0) / w).max((y1 - y0) / h);
        let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        let (hx, hy) = (0.5 * w * mm_per_px, 0.5 * h * mm_per_px);
        ((cx - hx)..(cx + hx), (cy - hy)..(cy + hy))
    }
}

type Drawn = Result<(), String>;

fn draw_figure(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    figure: &MapFigure<'_>,
    layout: &Layout,
    range: Option<(f64, f64)>,
) -> Drawn {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (title_area, body) = root.split_vertically(TITLE_PX);
    centred_text(&title_area, &figure.title, 22, None)?;
    let (maps, bar_column) = body.split_horizontally(layout.columns * layout.panel_px.0);
    let colours = Colours::new(range);
    for (r, row) in figure.rows.iter().enumerate() {
        for (c, panel) in row.iter().enumerate() {
            let area = maps.clone().shrink(
                (c as u32 * layout.panel_px.0, r as u32 * layout.panel_px.1),
                layout.panel_px,
            );
            draw_panel(&area, panel, layout, &colours)?;
        }
    }
    let bar_height = (layout.rows * layout.panel_px.1).max(3 * LEGEND_PX);
    let bar_column = bar_column.shrink((0, 0), (BAR_COLUMN_PX, bar_height));
    draw_colour_bar(&bar_column, &figure.quantity, &colours)?;
    root.present().map_err(|e| err(&e))
}

/// Draws `text` centred vertically in `area`, horizontally on `x_px` (the middle when `None`).
fn centred_text(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    text: &str,
    size: u32,
    x_px: Option<u32>,
) -> Drawn {
    let (w, h) = area.dim_in_pixel();
    let x = x_px.unwrap_or(w / 2);
    let style = ("sans-serif", size)
        .into_font()
        .into_text_style(area)
        .pos(Pos::new(HPos::Center, VPos::Center));
    area.draw_text(text, &style, (x as i32, h as i32 / 2))
        .map_err(|e| e.to_string())
}

/// The colour ramp over the figure's height range.
struct Colours {
    range: (f64, f64),
    any: bool,
}

impl Colours {
    fn new(range: Option<(f64, f64)>) -> Colours {
        match range {
            Some((lo, hi)) if hi > lo => Colours {
                range: (lo, hi),
                any: true,
            },
            // One height only: a bar of ±0.5 mm around it, the cells in its middle colour.
            Some((lo, _)) => Colours {
                range: (lo - 0.5, lo + 0.5),
                any: true,
            },
            None => Colours {
                range: (0.0, 1.0),
                any: false,
            },
        }
    }

    fn of(&self, h: Option<f64>) -> RGBColor {
        match h {
            Some(h) if h.is_finite() => {
                let [r, g, b] = ramp((h - self.range.0) / (self.range.1 - self.range.0));
                RGBColor(r, g, b)
            }
            _ => missing(),
        }
    }
}

fn missing() -> RGBColor {
    RGBColor(MISSING_RGB[0], MISSING_RGB[1], MISSING_RGB[2])
}

fn draw_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    panel: &MapPanel<'_>,
    layout: &Layout,
    colours: &Colours,
) -> Drawn {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let (title_area, chart_area) = area.split_vertically(PANEL_TITLE_PX);
    let (w, h) = chart_area.dim_in_pixel();
    let map_px = (
        w.saturating_sub(2 * MARGIN_PX + Y_LABELS_PX),
        h.saturating_sub(2 * MARGIN_PX + X_LABELS_PX),
    );
    let map_middle_px = MARGIN_PX + Y_LABELS_PX + map_px.0 / 2;
    centred_text(&title_area, &panel.title, 14, Some(map_middle_px))?;
    let (x_range, y_range) = layout.ranges_mm(map_px);
    let mut chart = ChartBuilder::on(&chart_area)
        .margin(MARGIN_PX)
        .x_label_area_size(X_LABELS_PX)
        .y_label_area_size(Y_LABELS_PX)
        .build_cartesian_2d(x_range, y_range)
        .map_err(|e| err(&e))?;
    let ticks = |px: u32| (px / 35).clamp(5, 12) as usize;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x (mm)")
        .y_desc("y (mm)")
        .x_labels(ticks(map_px.0))
        .y_labels(ticks(map_px.1))
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(|e| err(&e))?;
    let cells = (0..panel.ny).flat_map(|iy| {
        (0..panel.nx).map(move |ix| {
            let x0 = panel.x_min_mm + ix as f64 * panel.pitch_mm;
            let y0 = panel.y_min_mm + iy as f64 * panel.pitch_mm;
            let colour = colours.of(panel.heights_mm[iy * panel.nx + ix]);
            Rectangle::new(
                [(x0, y0), (x0 + panel.pitch_mm, y0 + panel.pitch_mm)],
                colour.filled(),
            )
        })
    });
    chart.draw_series(cells).map_err(|e| err(&e))?;
    Ok(())
}

fn draw_colour_bar(
    column: &DrawingArea<BitMapBackend<'_>, Shift>,
    quantity: &str,
    colours: &Colours,
) -> Drawn {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let (_, h) = column.dim_in_pixel();
    let (bar_area, legend) = column.split_vertically(h.saturating_sub(LEGEND_PX));
    let (lo, hi) = colours.range;
    let mut bar = ChartBuilder::on(&bar_area)
        .margin_top(PANEL_TITLE_PX + MARGIN_PX)
        .margin_bottom(MARGIN_PX)
        .margin_right(40)
        .y_label_area_size(BAR_LABELS_PX)
        .build_cartesian_2d(0.0..1.0, lo..hi)
        .map_err(|e| err(&e))?;
    let caption = if colours.any {
        quantity.to_string()
    } else {
        format!("{quantity}: no measured cell")
    };
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(caption)
        .y_labels(8)
        .y_label_formatter(&|v| tick_label(*v))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(|e| err(&e))?;
    const STEPS: usize = 256;
    let step = (hi - lo) / STEPS as f64;
    bar.draw_series((0..STEPS).map(|i| {
        let y0 = lo + i as f64 * step;
        Rectangle::new(
            [(0.0, y0), (1.0, y0 + step)],
            colours.of(Some(y0 + 0.5 * step)).filled(),
        )
    }))
    .map_err(|e| err(&e))?;
    // The missing cells' swatch, named.
    let (x, y) = (BAR_LABELS_PX as i32 - 30, 12);
    legend
        .draw(&Rectangle::new(
            [(x, y), (x + 22, y + 22)],
            missing().filled(),
        ))
        .map_err(|e| err(&e))?;
    legend
        .draw(&Rectangle::new([(x, y), (x + 22, y + 22)], BLACK))
        .map_err(|e| err(&e))?;
    let style = ("sans-serif", 14).into_font();
    legend
        .draw_text("missing", &style.clone().into(), (x + 30, y + 3))
        .map_err(|e| err(&e))?;
    legend
        .draw_text("(no sample)", &style.into(), (x - 20, y + 32))
        .map_err(|e| err(&e))?;
    Ok(())
}

/// A perceptually ordered dark-blue → green → yellow ramp (viridis-like) for `t` in [0, 1].
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

    /// A 20 x 10 grid of 0.5 mm cells whose height rises with x from 1 to 2 mm, the left
    /// quarter missing.
    fn heights() -> Vec<Option<f64>> {
        (0..10)
            .flat_map(|_| (0..20).map(|ix| (ix >= 5).then(|| 1.0 + (ix - 5) as f64 / 14.0)))
            .collect()
    }

    fn panel<'a>(title: &str, heights: &'a [Option<f64>]) -> MapPanel<'a> {
        MapPanel {
            title: title.into(),
            x_min_mm: -5.0,
            y_min_mm: 0.0,
            pitch_mm: 0.5,
            nx: 20,
            ny: 10,
            heights_mm: heights,
        }
    }

    #[test]
    fn a_single_map_is_large_with_square_cells_missing_grey_and_a_full_colour_bar() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("map.png");
        let cells = heights();
        let figure = MapFigure {
            title: "test map".into(),
            quantity: "height (mm)".into(),
            rows: vec![vec![panel("one", &cells)]],
        };
        assert_eq!(draw_height_maps(&path, &figure).unwrap(), Some((1.0, 2.0)));
        let img = image::open(&path).unwrap().to_rgb8();
        assert!(img.width() >= 500, "{:?}", img.dimensions());
        // The map area: a 2:1 field drawn 640 px wide, 320 px high.
        let map_w = SINGLE_MAP_SIDE_PX;
        let left = MARGIN_PX + Y_LABELS_PX;
        let top = TITLE_PX + PANEL_TITLE_PX + MARGIN_PX;
        let at = |fx: f64, fy: f64| {
            img.get_pixel(
                left + (fx * map_w as f64) as u32,
                top + (fy * (map_w / 2) as f64) as u32,
            )
            .0
        };
        // The missing left quarter is grey; the right edge is the ramp's top, the first
        // measured column its bottom.
        assert_eq!(at(0.1, 0.5), MISSING_RGB);
        assert_eq!(at(0.99, 0.5), ramp(1.0));
        assert_eq!(at(0.26, 0.5), ramp(0.0));
        // The colour bar holds both ends of the ramp.
        let bar: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
        assert!(bar.contains(&ramp(0.0)) && bar.contains(&ramp(1.0)));
    }

    #[test]
    fn panels_share_one_colour_scale() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("maps.png");
        let cells = heights();
        let raised: Vec<Option<f64>> = cells.iter().map(|h| h.map(|h| h + 1.0)).collect();
        let figure = MapFigure {
            title: "two".into(),
            quantity: "height (mm)".into(),
            rows: vec![vec![panel("a", &cells)], vec![panel("b", &raised)]],
        };
        assert_eq!(draw_height_maps(&path, &figure).unwrap(), Some((1.0, 3.0)));
        let img = image::open(&path).unwrap().to_rgb8();
        let (w, h) = img.dimensions();
        assert_eq!(
            h,
            TITLE_PX + 2 * (PANEL_MAP_SIDE_PX / 2 + 2 * MARGIN_PX + X_LABELS_PX + PANEL_TITLE_PX)
        );
        assert_eq!(
            w,
            PANEL_MAP_SIDE_PX + Y_LABELS_PX + 2 * MARGIN_PX + BAR_COLUMN_PX
        );
    }

    #[test]
    fn refuses_bad_panels_and_formats() {
        let cells = [Some(0.0); 3];
        let mut bad = panel("short", &cells);
        bad.nx = 2;
        bad.ny = 2;
        let figure = MapFigure {
            title: "t".into(),
            quantity: "q".into(),
            rows: vec![vec![bad]],
        };
        let err = draw_height_maps(Path::new("x.png"), &figure).unwrap_err();
        assert!(err.to_string().contains("'short' is 2x2 cells"), "{err}");
        let err = draw_height_maps(Path::new("x.svg"), &figure).unwrap_err();
        assert!(matches!(err, ReportError::UnknownFormat { .. }));
        let empty = MapFigure {
            rows: vec![],
            ..figure
        };
        let err = draw_height_maps(Path::new("x.png"), &empty).unwrap_err();
        assert!(err.to_string().contains("no height map"), "{err}");
    }
}
