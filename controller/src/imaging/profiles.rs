//! The paper's Fig. 10: sections of the height map along x and along y through a feature's
//! centre, against the true surface when one is known, drawn as SVG and written as CSV.
//!
//! The section along x is the row of cells holding the centre, the section along y its
//! column; each point is a cell centre with the map's height there (measured, filled or
//! missing) and the true surface's height at the same place, in the map's quantity (z_s, or
//! the height above the same base plane the map subtracts).
//!
//! `profiles.csv`: `section,position_mm,x_mm,y_mm,height_mm,true_height_mm,state`, one line
//! per cell; `section` is `x` or `y`, `position_mm` the x (section `x`) or y (section `y`)
//! of the cell centre, empty heights unknown, `state` `measured`, `filled` or `missing`.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use scanhil_report::{Axis, Chart, ReportError, Series, draw_charts};

use super::grid::HeightMap;

/// Which way a section runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Section {
    /// Along x, through the centre's row.
    X,
    /// Along y, through the centre's column.
    Y,
}

impl Section {
    /// `x` or `y`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Section::X => "x",
            Section::Y => "y",
        }
    }
}

/// Where a cell's height came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellState {
    /// Samples reached the cell.
    Measured,
    /// The fill gave it a height.
    Filled,
    /// No height.
    Missing,
}

impl CellState {
    /// `measured`, `filled` or `missing`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            CellState::Measured => "measured",
            CellState::Filled => "filled",
            CellState::Missing => "missing",
        }
    }
}

/// One cell of a section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfilePoint {
    /// The section it belongs to.
    pub section: Section,
    /// The cell centre's x, mm.
    pub x_mm: f64,
    /// The cell centre's y, mm.
    pub y_mm: f64,
    /// The map's height, mm (`None` when missing).
    pub height_mm: Option<f64>,
    /// The true surface's height in the map's quantity, mm, when known.
    pub true_height_mm: Option<f64>,
    /// Where the height came from.
    pub state: CellState,
}

impl ProfilePoint {
    /// The position along its section: x for [`Section::X`], y for [`Section::Y`], mm.
    #[must_use]
    pub fn position_mm(&self) -> f64 {
        match self.section {
            Section::X => self.x_mm,
            Section::Y => self.y_mm,
        }
    }
}

/// Where the sections cross.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProfileCentre {
    /// x, mm.
    pub x_mm: f64,
    /// y, mm.
    pub y_mm: f64,
    /// `feature_points` (the mean position of the measured feature's points) or
    /// `map_centre` (no feature measured).
    pub from: String,
}

/// Both sections of one map.
#[derive(Debug, Clone, PartialEq)]
pub struct Profiles {
    /// The cells of the section along x, then along y.
    pub points: Vec<ProfilePoint>,
}

/// The sections along x and y of `map` through `centre_mm` (clamped into the map), with the
/// true height of each cell centre from `truth` (in the map's quantity).
#[must_use]
pub fn sections(
    map: &HeightMap,
    centre_mm: (f64, f64),
    truth: impl Fn(f64, f64) -> Option<f64>,
) -> Profiles {
    let spec = map.spec;
    let index = |v: f64, min: f64, n: usize| {
        (((v - min) / spec.pitch_mm).floor().max(0.0) as usize).min(n.saturating_sub(1))
    };
    let cx = index(centre_mm.0, spec.x_min_mm, spec.nx);
    let cy = index(centre_mm.1, spec.y_min_mm, spec.ny);
    let point = |section, ix, iy| {
        let i = spec.index(ix, iy);
        let (x_mm, y_mm) = spec.centre_mm(ix, iy);
        let state = match (map.heights_mm[i], map.samples[i]) {
            (None, _) => CellState::Missing,
            (Some(_), 0) => CellState::Filled,
            (Some(_), _) => CellState::Measured,
        };
        ProfilePoint {
            section,
            x_mm,
            y_mm,
            height_mm: map.heights_mm[i],
            true_height_mm: truth(x_mm, y_mm),
            state,
        }
    };
    let along_x = (0..spec.nx).map(|ix| point(Section::X, ix, cy));
    let along_y = (0..spec.ny).map(|iy| point(Section::Y, cx, iy));
    Profiles {
        points: along_x.chain(along_y).collect(),
    }
}

/// Why `profiles.csv` could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ProfilesError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: io::Error,
    },
    /// A line is not a profile line.
    #[error("{path}:{line}: {reason}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        reason: String,
    },
}

/// The header of `profiles.csv`.
pub const PROFILES_CSV_HEADER: &str =
    "section,position_mm,x_mm,y_mm,height_mm,true_height_mm,state";

impl Profiles {
    /// The points of one section, in order of position.
    pub fn along(&self, section: Section) -> impl Iterator<Item = &ProfilePoint> {
        self.points.iter().filter(move |p| p.section == section)
    }

    /// Writes the CSV described in the module doc.
    pub fn write_csv<W: Write>(&self, mut out: W) -> io::Result<()> {
        writeln!(out, "{PROFILES_CSV_HEADER}")?;
        let mm = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:?}"));
        for p in &self.points {
            writeln!(
                out,
                "{},{:?},{:?},{:?},{},{},{}",
                p.section.name(),
                p.position_mm(),
                p.x_mm,
                p.y_mm,
                mm(p.height_mm),
                mm(p.true_height_mm),
                p.state.name()
            )?;
        }
        out.flush()
    }

    /// Reads a CSV written by [`Profiles::write_csv`].
    ///
    /// # Errors
    /// [`ProfilesError`] naming the file, and the line and field for bad content.
    pub fn read_csv_file(path: &Path) -> Result<Profiles, ProfilesError> {
        let text = std::fs::read_to_string(path).map_err(|source| ProfilesError::Io {
            path: path.to_owned(),
            source,
        })?;
        let parse_error = |line: usize, reason: String| ProfilesError::Parse {
            path: path.to_owned(),
            line,
            reason,
        };
        let mut lines = text.lines().enumerate();
        match lines.next() {
            Some((_, header)) if header.trim() == PROFILES_CSV_HEADER => {}
            other => {
                return Err(parse_error(
                    1,
                    format!(
                        "header is '{}', expected '{PROFILES_CSV_HEADER}'",
                        other.map_or("", |(_, h)| h)
                    ),
                ));
            }
        }
        let mut points = Vec::new();
        for (i, line) in lines {
            let n = i + 1;
            if line.trim().is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let [section, _, x, y, height, truth, state] = fields[..] else {
                return Err(parse_error(
                    n,
                    format!("{} fields, expected 7", fields.len()),
                ));
            };
            let number = |name: &str, v: &str| {
                v.parse::<f64>()
                    .map_err(|_| parse_error(n, format!("{name}: '{v}' is not a number")))
            };
            let optional = |name: &str, v: &str| {
                if v.is_empty() {
                    Ok(None)
                } else {
                    number(name, v).map(Some)
                }
            };
            points.push(ProfilePoint {
                section: match section {
                    "x" => Section::X,
                    "y" => Section::Y,
                    other => {
                        return Err(parse_error(
                            n,
                            format!("section: '{other}' is neither x nor y"),
                        ));
                    }
                },
                x_mm: number("x_mm", x)?,
                y_mm: number("y_mm", y)?,
                height_mm: optional("height_mm", height)?,
                true_height_mm: optional("true_height_mm", truth)?,
                state: match state {
                    "measured" => CellState::Measured,
                    "filled" => CellState::Filled,
                    "missing" => CellState::Missing,
                    other => {
                        return Err(parse_error(
                            n,
                            format!("state: '{other}' is not measured, filled or missing"),
                        ));
                    }
                },
            });
        }
        Ok(Profiles { points })
    }
}

/// Draws the sections along x and y (two panels, height in mm against position in mm) of
/// each labelled scan, and the true surface of the first scan that has one, into `path`
/// (`.svg` or `.png`); `quantity` names the heights, e.g. `z_s (mm)`. Missing cells break
/// the lines.
///
/// # Errors
/// Nothing to draw, or the file cannot be written.
pub fn draw_profiles(
    path: &Path,
    quantity: &str,
    scans: &[(String, &Profiles)],
) -> Result<(), ReportError> {
    let truth = scans
        .iter()
        .find(|(_, p)| p.points.iter().any(|p| p.true_height_mm.is_some()));
    let charts = [Section::X, Section::Y].map(|section| {
        let line =
            |label: String, profiles: &Profiles, pick: fn(&ProfilePoint) -> Option<f64>| Series {
                label,
                points: profiles
                    .along(section)
                    .map(|p| (p.position_mm(), pick(p).unwrap_or(f64::NAN)))
                    .collect(),
                markers: false,
            };
        // The truth first: drawn underneath, in the first colour (black).
        let mut series: Vec<Series> = truth
            .map(|(label, p)| {
                let name = if scans.len() > 1 {
                    format!("true surface (at {label}'s section)")
                } else {
                    "true surface".into()
                };
                line(name, p, |p| p.true_height_mm)
            })
            .into_iter()
            .collect();
        series.extend(
            scans
                .iter()
                .map(|(label, p)| line(label.clone(), p, |p| p.height_mm)),
        );
        let through = scans.first().and_then(|(_, p)| p.along(section).next());
        let at = match (section, through) {
            (Section::X, Some(p)) => format!(" through y = {:.2} mm", p.y_mm),
            (Section::Y, Some(p)) => format!(" through x = {:.2} mm", p.x_mm),
            (_, None) => String::new(),
        };
        Chart {
            title: format!("section along {}{at}", section.name()),
            x_label: format!("{} (mm)", section.name()),
            y_label: quantity.into(),
            x_axis: Axis::Linear,
            y_axis: Axis::Linear,
            series,
        }
    });
    draw_charts(path, &charts)
}
