//! A scan against a recorded session (`scanhil scan --replay DIR`, served by
//! `scanhil-emulator replay`): the report's `replay` section and the verdict's figures, from
//! the emulator's summary line, whose `replay` compares each coil command the host sent with
//! the recorded one of its period (no I/O).

use std::path::PathBuf;

use super::verdict::ReplayFigures;

/// What the scan replays, and whether a divergence fails it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReplayRun {
    /// The recorded session's folder.
    pub recording: PathBuf,
    /// `--replay-must-match`: a coil command that differs from the recording's fails the run.
    pub must_match: bool,
}

impl ReplayRun {
    /// The report's `replay` section (the recording, `must_match`, and the emulator's
    /// comparison: `compared`, `differing`, `not_recorded`, `largest_difference_a`,
    /// `first_divergence`) and the verdict's figures, from the emulator's summary line (`None`
    /// or without `replay`: nothing was compared).
    #[must_use]
    pub fn judged(
        &self,
        summary: Option<&serde_json::Value>,
    ) -> (serde_json::Value, ReplayFigures) {
        let comparison = summary.map_or(&serde_json::Value::Null, |summary| &summary["replay"]);
        let figures = ReplayFigures {
            must_match: self.must_match,
            compared: comparison["compared"].as_u64().unwrap_or(0),
            first_divergence: comparison["first_divergence"]["period"].as_u64(),
        };
        let mut section = serde_json::json!({
            "recording": self.recording.display().to_string(),
            "must_match": self.must_match,
        });
        if let (Some(section), Some(comparison)) = (section.as_object_mut(), comparison.as_object())
        {
            section.extend(comparison.clone());
        }
        (section, figures)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(must_match: bool) -> ReplayRun {
        ReplayRun {
            recording: PathBuf::from("fixtures/recordings/replay-small"),
            must_match,
        }
    }

    #[test]
    fn the_section_holds_the_emulators_comparison_and_the_figures_its_first_divergence() {
        let summary = serde_json::json!({
            "replay": {
                "compared": 301,
                "differing": 248,
                "not_recorded": 0,
                "largest_difference_a": { "a": 0.6, "b": 1.1 },
                "first_divergence": { "period": 1, "difference_a": { "a": 0.000232, "b": 0.004005 } },
            }
        });
        let (section, figures) = run(true).judged(Some(&summary));
        assert_eq!(
            figures,
            ReplayFigures {
                must_match: true,
                compared: 301,
                first_divergence: Some(1),
            }
        );
        assert_eq!(section["recording"], "fixtures/recordings/replay-small");
        assert_eq!(section["must_match"], true);
        assert_eq!(section["differing"], 248);
        assert_eq!(section["first_divergence"]["difference_a"]["b"], 0.004005);
    }

    #[test]
    fn without_the_emulators_summary_nothing_was_compared() {
        for summary in [None, Some(serde_json::json!({ "outcome": "finished" }))] {
            let (section, figures) = run(false).judged(summary.as_ref());
            assert_eq!(figures, ReplayFigures::default());
            assert_eq!(
                section,
                serde_json::json!({
                    "recording": "fixtures/recordings/replay-small",
                    "must_match": false,
                })
            );
        }
    }
}
