//! A conformance run's verdicts as a user reads them: one row per check (passed, failed or
//! skipped, what was seen), the pass/fail table with a line of what to look at on the bench
//! for each failure, and JUnit XML.

use std::fmt::Write as _;

use crate::run::check_selection::spec;

/// One check's verdict.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CheckResult {
    /// The check's name.
    pub name: &'static str,
    /// Which node it checked.
    pub node: &'static str,
    /// Passed, failed, or not run.
    pub outcome: Outcome,
    /// What was seen (skipped: why it did not run).
    pub detail: String,
    /// How long it took, s.
    pub time_s: f64,
}

/// A check's outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// It ran and passed.
    Passed,
    /// It ran and failed.
    Failed,
    /// It did not run (a destructive check on a real link without `--destructive`).
    Skipped,
}

impl CheckResult {
    /// Whether the check ran and passed.
    #[must_use]
    pub fn passed(&self) -> bool {
        self.outcome == Outcome::Passed
    }

    /// Whether the check ran and failed.
    #[must_use]
    pub fn failed(&self) -> bool {
        self.outcome == Outcome::Failed
    }
}

/// The row of a run stopped by `signal` before its checks were done: failed, so a run cut
/// short never passes.
#[must_use]
pub fn ended_early(signal: &str) -> CheckResult {
    CheckResult {
        name: RUN_ENDED_EARLY,
        node: "-",
        outcome: Outcome::Failed,
        detail: format!("interrupted by {signal}: the checks after the rows above did not run"),
        time_s: 0.0,
    }
}

/// The name of [`ended_early`]'s row.
pub const RUN_ENDED_EARLY: &str = "run_ended_early";

/// The pass/fail table, then one line per failed check on what to look at on the bench.
#[must_use]
pub fn table(results: &[CheckResult]) -> String {
    let mut text = format!("{:<6} {:<28} {:<6} detail\n", "node", "check", "result");
    for r in results {
        let result = match r.outcome {
            Outcome::Passed => "PASS",
            Outcome::Failed => "FAIL",
            Outcome::Skipped => "SKIP",
        };
        let _ = writeln!(
            text,
            "{:<6} {:<28} {:<6} {}",
            r.node, r.name, result, r.detail
        );
    }
    let count = |outcome| results.iter().filter(|r| r.outcome == outcome).count();
    let _ = write!(
        text,
        "{} checks, {} passed, {} failed, {} skipped",
        results.len(),
        count(Outcome::Passed),
        count(Outcome::Failed),
        count(Outcome::Skipped)
    );
    for r in results.iter().filter(|r| r.failed()) {
        if let Some(check) = spec(r.name) {
            let _ = write!(
                text,
                "\non the bench, {}: look at {}",
                r.name, check.bench_hint
            );
        }
    }
    text
}

/// The results as JUnit XML (one test suite, one test case per check).
#[must_use]
pub fn junit_xml(results: &[CheckResult]) -> String {
    let failures = results.iter().filter(|r| r.failed()).count();
    let skipped = results
        .iter()
        .filter(|r| r.outcome == Outcome::Skipped)
        .count();
    let total: f64 = results.iter().map(|r| r.time_s).sum();
    let mut xml = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n  <testsuite name=\"scanhil-conformance\" tests=\"{}\" failures=\"{failures}\" errors=\"0\" skipped=\"{skipped}\" time=\"{total:.6}\">\n",
        results.len()
    );
    for r in results {
        let _ = write!(
            xml,
            "    <testcase classname=\"{}\" name=\"{}\" time=\"{:.6}\"",
            r.node, r.name, r.time_s
        );
        let detail = escape(&r.detail);
        let _ = match r.outcome {
            Outcome::Passed => writeln!(xml, "><system-out>{detail}</system-out></testcase>"),
            Outcome::Failed => writeln!(xml, "><failure message=\"{detail}\"/></testcase>"),
            Outcome::Skipped => writeln!(xml, "><skipped message=\"{detail}\"/></testcase>"),
        };
    }
    xml + "  </testsuite>\n</testsuites>\n"
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(name: &'static str, outcome: Outcome, detail: &str) -> CheckResult {
        CheckResult {
            name,
            node: "fsm",
            outcome,
            detail: detail.to_owned(),
            time_s: 0.25,
        }
    }

    fn results() -> Vec<CheckResult> {
        vec![
            result("status_frames", Outcome::Passed, "3 status frames"),
            result(
                "answers_in_time",
                Outcome::Failed,
                "period 4: <late> & \"slow\"",
            ),
            result(
                "over_current_fault",
                Outcome::Skipped,
                "needs --destructive",
            ),
        ]
    }

    #[test]
    fn each_outcome_is_what_it_says() {
        let [passed, failed, skipped] = &results()[..] else {
            unreachable!()
        };
        assert!(passed.passed() && !passed.failed());
        assert!(failed.failed() && !failed.passed());
        assert!(!skipped.passed() && !skipped.failed());
    }

    #[test]
    fn the_table_has_a_row_per_check_the_counts_and_a_bench_hint_per_failure() {
        let text = table(&results());
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines[1].starts_with("fsm    status_frames") && lines[1].contains(" PASS "));
        assert!(lines[2].contains(" FAIL ") && lines[2].ends_with("period 4: <late> & \"slow\""));
        assert!(lines[3].contains(" SKIP "));
        assert_eq!(lines[4], "3 checks, 1 passed, 1 failed, 1 skipped");
        assert_eq!(lines.len(), 6, "{text}");
        assert!(
            lines[5].starts_with("on the bench, answers_in_time: look at "),
            "{text}"
        );
    }

    #[test]
    fn junit_counts_failures_and_skips_and_escapes_what_was_seen() {
        let xml = junit_xml(&results());
        assert!(
            xml.contains("tests=\"3\" failures=\"1\" errors=\"0\" skipped=\"1\" time=\"0.750000\""),
            "{xml}"
        );
        assert!(xml.contains(
            "name=\"status_frames\" time=\"0.250000\"><system-out>3 status frames</system-out>"
        ));
        assert!(
            xml.contains("<failure message=\"period 4: &lt;late&gt; &amp; &quot;slow&quot;\"/>")
        );
        assert!(xml.contains("<skipped message=\"needs --destructive\"/>"));
        assert!(xml.ends_with("  </testsuite>\n</testsuites>\n"));
    }
}
