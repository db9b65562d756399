//! Line charts with linear or logarithmic axes, written as SVG or PNG.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::{ReportError, register_font};

/// How an axis maps values to positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// Evenly spaced values.
    Linear,
    /// Evenly spaced decades; values that are not positive are left out (the line breaks).
    Log,
}

impl Axis {
    fn to_plot(self, v: f64) -> Option<f64> {
        match self {
            Axis::Linear => v.is_finite().then_some(v),
            Axis::Log => (v.is_finite() && v > 0.0).then(|| v.log10()),
        }
    }

    fn label(self, v: f64) -> String {
        match self {
            Axis::Linear => tick_label(v),
            Axis::Log => format!("{:.2e}", 10f64.powf(v)),
        }
    }
}

/// One named line of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The legend entry.
    pub label: String,
    /// (x, y) points, drawn in order; a point that cannot be drawn (not finite, or not
    /// positive on a log axis) is left out and breaks the line there.
    pub points: Vec<(f64, f64)>,
    /// Draw a marker at every point as well as the line.
    pub markers: bool,
}

/// One panel: a title, two axes and its lines.
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    /// Drawn above the panel.
    pub title: String,
    /// The x axis caption, with its unit.
    pub x_label: String,
    /// The y axis caption, with its unit.
    pub y_label: String,
    /// Linear or logarithmic x.
    pub x_axis: Axis,
    /// Linear or logarithmic y.
    pub y_axis: Axis,
    /// The lines.
    pub series: Vec<Series>,
}

/// Line colours in series order: black, then the Okabe-Ito colours (told apart with colour
/// blindness, none pale on white).
const PALETTE: [[u8; 3]; 7] = [
    [0, 0, 0],
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [86, 180, 233],
    [230, 159, 0],
];

/// Where a value of 0 goes on a log axis, which has no place for it: [`LogZero::BELOW`] times
/// below the smallest positive value drawn beside it (an exact reference's error against
/// itself, drawn in sight); the axis label says so ([`LogZero::note`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogZero {
    /// The position a 0 is drawn at.
    pub at: f64,
}

impl LogZero {
    /// How far below the smallest positive value a 0 is drawn.
    pub const BELOW: f64 = 10.0;

    /// The place of the zeros among `values`, or `None` when none is 0; 1 when no value is
    /// positive.
    #[must_use]
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<LogZero> {
        let mut smallest = f64::INFINITY;
        let mut any_zero = false;
        for v in values {
            any_zero |= v == 0.0;
            if v > 0.0 {
                smallest = smallest.min(v);
            }
        }
        let at = if smallest.is_finite() {
            smallest / LogZero::BELOW
        } else {
            1.0
        };
        any_zero.then_some(LogZero { at })
    }

    /// Where `value` is drawn: itself, or [`LogZero::at`] for a 0.
    #[must_use]
    pub fn place(self, value: f64) -> f64 {
        if value == 0.0 { self.at } else { value }
    }

    /// The axis label's note: ` (0, WHAT, drawn at 1.0e-3)`.
    #[must_use]
    pub fn note(self, what: &str) -> String {
        format!(" (0, {what}, drawn at {:.1e})", self.at)
    }
}

const PANEL_WIDTH_PX: u32 = 900;
const PANEL_HEIGHT_PX: u32 = 450;

/// Draws `charts` stacked top to bottom into `path`; `.svg` or `.png` picks the format.
pub fn draw_charts(path: &Path, charts: &[Chart]) -> Result<(), ReportError> {
    if charts.is_empty() {
        return Err(bad_data(path, "no chart to draw".into()));
    }
    let size = (PANEL_WIDTH_PX, PANEL_HEIGHT_PX * charts.len() as u32);
    // Both backends measure text with the font, so it is registered for either.
    register_font();
    match path.extension().and_then(|e| e.to_str()) {
        Some("svg") => draw_on(
            path,
            SVGBackend::new(path, size).into_drawing_area(),
            charts,
        ),
        Some("png") => draw_on(
            path,
            BitMapBackend::new(path, size).into_drawing_area(),
            charts,
        ),
        _ => Err(ReportError::UnknownFormat {
            path: path.to_owned(),
        }),
    }
}

/// A linear axis' tick label: at most three decimals, trailing zeros dropped.
pub(crate) fn tick_label(v: f64) -> String {
    let text = format!("{v:.3}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".into()
    } else {
        text.into()
    }
}

fn bad_data(path: &Path, reason: String) -> ReportError {
    ReportError::BadData {
        path: path.to_owned(),
        reason,
    }
}

fn draw_on<DB: DrawingBackend>(
    path: &Path,
    root: DrawingArea<DB, Shift>,
    charts: &[Chart],
) -> Result<(), ReportError> {
    let drawing = |e: &dyn std::fmt::Display| ReportError::Drawing {
        path: path.to_owned(),
        reason: e.to_string(),
    };
    root.fill(&WHITE).map_err(|e| drawing(&e))?;
    for (chart, area) in charts.iter().zip(root.split_evenly((charts.len(), 1))) {
        // Each series as runs of drawable points: a value that cannot be drawn breaks it.
        let lines: Vec<Vec<Vec<(f64, f64)>>> = chart
            .series
            .iter()
            .map(|s| {
                let mut runs = vec![Vec::new()];
                for &(x, y) in &s.points {
                    match (chart.x_axis.to_plot(x), chart.y_axis.to_plot(y)) {
                        (Some(x), Some(y)) => runs.last_mut().expect("one run").push((x, y)),
                        _ => runs.push(Vec::new()),
                    }
                }
                runs.retain(|run| !run.is_empty());
                runs
            })
            .collect();
        let (x_range, y_range) = bounds(lines.iter().flatten().flatten()).ok_or_else(|| {
            bad_data(
                path,
                format!("chart '{}' has no drawable point", chart.title),
            )
        })?;
        let mut ctx = ChartBuilder::on(&area)
            .caption(&chart.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .build_cartesian_2d(x_range, y_range)
            .map_err(|e| drawing(&e))?;
        ctx.configure_mesh()
            .x_desc(&chart.x_label)
            .y_desc(&chart.y_label)
            .x_label_formatter(&|v| chart.x_axis.label(*v))
            .y_label_formatter(&|v| chart.y_axis.label(*v))
            .draw()
            .map_err(|e| drawing(&e))?;
        for (i, (series, line)) in chart.series.iter().zip(&lines).enumerate() {
            let [r, g, b] = PALETTE[i % PALETTE.len()];
            let colour = RGBColor(r, g, b).to_rgba();
            for (k, run) in line.iter().enumerate() {
                let drawn = ctx
                    .draw_series(LineSeries::new(run.iter().copied(), colour.stroke_width(2)))
                    .map_err(|e| drawing(&e))?;
                if k == 0 {
                    drawn
                        .label(&series.label)
                        .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour));
                }
                if series.markers {
                    ctx.draw_series(run.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                        .map_err(|e| drawing(&e))?;
                }
            }
        }
        ctx.configure_series_labels()
            .background_style(WHITE.mix(0.5))
            .border_style(BLACK)
            .draw()
            .map_err(|e| drawing(&e))?;
    }
    root.present().map_err(|e| drawing(&e))
}

/// The x and y ranges that hold every point, widened a little so no line sits on the frame.
fn bounds<'a>(
    points: impl Iterator<Item = &'a (f64, f64)>,
) -> Option<(std::ops::Range<f64>, std::ops::Range<f64>)> {
    let mut lo = (f64::INFINITY, f64::INFINITY);
    let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for &(x, y) in points {
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    }
    let widen = |a: f64, b: f64| {
        let pad = if b > a { (b - a) * 0.05 } else { 0.5 };
        (a - pad)..(b + pad)
    };
    lo.0.is_finite()
        .then(|| (widen(lo.0, hi.0), widen(lo.1, hi.1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_chart() -> Chart {
        Chart {
            title: "work precision".into(),
            x_label: "run time per simulated second [s]".into(),
            y_label: "max error [urad]".into(),
            x_axis: Axis::Log,
            y_axis: Axis::Log,
            series: vec![Series {
                label: "rk4".into(),
                points: vec![(1e-3, 1e-2), (1e-2, 1e-6), (0.0, 5.0)],
                markers: true,
            }],
        }
    }

    #[test]
    fn draws_svg_and_png_by_extension() {
        let dir = std::env::temp_dir().join(format!("scanhil-chart-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for name in ["c.svg", "c.png"] {
            let path = dir.join(name);
            draw_charts(&path, &[sample_chart(), sample_chart()]).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            assert!(bytes.len() > 1000, "{name} is only {} bytes", bytes.len());
        }
        let svg = std::fs::read_to_string(dir.join("c.svg")).unwrap();
        assert!(svg.contains("work precision"));
        let png = image::open(dir.join("c.png")).unwrap();
        assert_eq!(png.height(), 2 * PANEL_HEIGHT_PX);
    }

    #[test]
    fn refuses_unknown_extension_and_empty_data() {
        let err = draw_charts(Path::new("plot.pdf"), &[sample_chart()]).unwrap_err();
        assert!(matches!(err, ReportError::UnknownFormat { .. }));
        let mut empty = sample_chart();
        empty.series[0].points = vec![(-1.0, 1.0)];
        let err = draw_charts(Path::new("plot.svg"), &[empty]).unwrap_err();
        assert!(err.to_string().contains("no drawable point"), "{err}");
    }

    #[test]
    fn a_value_that_cannot_be_drawn_breaks_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("gap.svg");
        let mut chart = sample_chart();
        chart.x_axis = Axis::Linear;
        chart.y_axis = Axis::Linear;
        chart.series[0].markers = false;
        chart.series[0].points = vec![
            (0.0, 1.0),
            (1.0, 2.0),
            (2.0, f64::NAN),
            (3.0, 1.0),
            (4.0, 0.0),
        ];
        draw_charts(&path, &[chart.clone()]).unwrap();
        let broken = std::fs::read_to_string(&path)
            .unwrap()
            .matches("<polyline")
            .count();
        chart.series[0].points[2].1 = 1.5;
        draw_charts(&path, &[chart]).unwrap();
        let whole = std::fs::read_to_string(&path)
            .unwrap()
            .matches("<polyline")
            .count();
        assert_eq!(broken, whole + 1);
    }

    #[test]
    fn a_zero_is_drawn_ten_times_below_the_smallest_positive_value() {
        let zero = LogZero::of([3e-2, 0.0, 5e-1]).expect("a zero");
        assert!((zero.at - 3e-3).abs() < 1e-15, "{zero:?}");
        assert_eq!(zero.place(0.0), zero.at);
        assert_eq!(zero.place(0.5), 0.5);
        assert_eq!(
            zero.note("the reference"),
            " (0, the reference, drawn at 3.0e-3)"
        );
        assert_eq!(LogZero::of([1.0, 2.0]), None);
        assert_eq!(LogZero::of([0.0, 0.0]), Some(LogZero { at: 1.0 }));
    }

    #[test]
    fn log_axis_drops_non_positive_values() {
        assert_eq!(Axis::Log.to_plot(100.0), Some(2.0));
        assert_eq!(Axis::Log.to_plot(0.0), None);
        assert_eq!(Axis::Linear.to_plot(f64::NAN), None);
    }
}
