//! Line charts with linear or logarithmic axes, written as SVG or PNG.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::ReportError;

/// How an axis maps values to positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// Evenly spaced values.
    Linear,
    /// Evenly spaced decades; values that are not positive are left out of the line.
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
            Axis::Linear => format!("{v:.3}")
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string(),
            Axis::Log => format!("{:.2e}", 10f64.powf(v)),
        }
    }
}

/// One named line of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The legend entry.
    pub label: String,
    /// (x, y) points, drawn in order.
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

const PANEL_WIDTH_PX: u32 = 900;
const PANEL_HEIGHT_PX: u32 = 450;
const FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

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

fn register_font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The font is compiled in and known to parse; a failure here is a build defect.
            plotters::style::register_font("sans-serif", style, FONT)
                .unwrap_or_else(|_| panic!("bundled DejaVuSans.ttf does not parse"));
        }
    });
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
        let lines: Vec<Vec<(f64, f64)>> = chart
            .series
            .iter()
            .map(|s| {
                s.points
                    .iter()
                    .filter_map(|&(x, y)| {
                        Some((chart.x_axis.to_plot(x)?, chart.y_axis.to_plot(y)?))
                    })
                    .collect()
            })
            .collect();
        let (x_range, y_range) = bounds(lines.iter().flatten()).ok_or_else(|| {
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
            let colour = Palette99::pick(i).to_rgba();
            ctx.draw_series(LineSeries::new(
                line.iter().copied(),
                colour.stroke_width(2),
            ))
            .map_err(|e| drawing(&e))?
            .label(&series.label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour));
            if series.markers {
                ctx.draw_series(line.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                    .map_err(|e| drawing(&e))?;
            }
        }
        ctx.configure_series_labels()
            .background_style(WHITE.mix(0.8))
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
    fn log_axis_drops_non_positive_values() {
        assert_eq!(Axis::Log.to_plot(100.0), Some(2.0));
        assert_eq!(Axis::Log.to_plot(0.0), None);
        assert_eq!(Axis::Linear.to_plot(f64::NAN), None);
    }
}
