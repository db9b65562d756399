//! Which conformance checks run: the table of every check (its node, whether it can harm a
//! real bench, and what to look at on the bench when it fails), and the selection a
//! `scanhil conformance` command line makes of it (`--check NAME`, `--skip NAME`,
//! `--destructive`). Pure: checked before any link opens.
//!
//! On a real link (a device, not the emulator `conformance` starts itself) the checks that can
//! harm the bench run only with `--destructive`: `over_current_fault` commands 8 A, twice a
//! 4 A amplifier's limit, into the coils; `survives_garbage_slcan_lines` sends garbage lines
//! that test the adapter's firmware as much as the node (an adapter without length checks puts
//! a short garbage frame on the bus). Left out, they are listed as skipped with the reason.
//!
//! The timing checks depend on how the node is clocked (`--timing`): in lockstep
//! `answers_in_time` (each Step answered within the allowance); in real time, where the node
//! runs on its own clock, `readings_on_time` and `reading_rate`. The checks of the other
//! timing are not listed.

use scanhil_protocol::validation::Invalid;

use super::scenario::TimingMode;

/// One conformance check as the table knows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CheckSpec {
    /// The check's name (`answers_in_time`).
    pub name: &'static str,
    /// The node it checks: `fsm` or `sensor`.
    pub node: &'static str,
    /// Whether it can harm a real bench (runs there only with `--destructive`).
    pub destructive: bool,
    /// The timing it applies to (`None`: both).
    pub timing: Option<TimingMode>,
    /// What to look at on the bench when it fails, one line.
    pub bench_hint: &'static str,
}

/// Every check, in the order conformance runs them.
pub const CHECKS: [CheckSpec; 14] = [
    CheckSpec {
        name: "answers_in_time",
        node: "fsm",
        destructive: false,
        timing: Some(TimingMode::Lockstep),
        bench_hint: "the node's receive-to-answer path: its loop time, the adapter's and USB's latency, and --answer-allowance-s against both",
    },
    CheckSpec {
        name: "readings_on_time",
        node: "fsm",
        destructive: false,
        timing: Some(TimingMode::Realtime),
        bench_hint: "the node's loop timer and CAN transmit path (no silence as long as --watchdog-periods periods), the adapter's and USB's latency (the FTDI latency timer) and the bus load",
    },
    CheckSpec {
        name: "reading_rate",
        node: "fsm",
        destructive: false,
        timing: Some(TimingMode::Realtime),
        bench_hint: "the node's configured control rate against --rate-hz, and its clock (timer prescaler, crystal)",
    },
    CheckSpec {
        name: "angle_sequence_gapless",
        node: "fsm",
        destructive: false,
        timing: None,
        bench_hint: "the node's AngleReading counter (one per Step, following the Step counter) and frames lost on the bus (candump -e: error frames, adapter overruns, bus load)",
    },
    CheckSpec {
        name: "angles_in_range",
        node: "fsm",
        destructive: false,
        timing: None,
        bench_hint: "the angle sensor's scaling (urad per count), axis order and sign, and that the amplifiers drive the coils (enable line, fuses, coil wiring)",
    },
    CheckSpec {
        name: "status_frames",
        node: "fsm",
        destructive: false,
        timing: None,
        bench_hint: "the node's heartbeat (Status frames enabled, their rate) and the adapter's acceptance filter",
    },
    CheckSpec {
        name: "over_current_fault",
        node: "fsm",
        destructive: true,
        timing: None,
        bench_hint: "the driver's current limit setting and its OverCurrent fault frame (a driver that clamps silently fails here)",
    },
    CheckSpec {
        name: "survives_malformed_frames",
        node: "fsm",
        destructive: false,
        timing: None,
        bench_hint: "the node's length (DLC) checks: a loop frame with a short payload must be ignored, not acted on or fatal",
    },
    CheckSpec {
        name: "survives_garbage_slcan_lines",
        node: "fsm",
        destructive: true,
        timing: None,
        bench_hint: "the SLCAN adapter's firmware (version, line parser): garbage lines must be refused with BEL, never reset it or reach the bus",
    },
    CheckSpec {
        name: "link_timeout_fault",
        node: "fsm",
        destructive: false,
        timing: None,
        bench_hint: "the node's watchdog: armed, its periods against --watchdog-periods, and that it zeroes the coils and sends a LinkTimeout fault",
    },
    CheckSpec {
        name: "sensor_values_decode",
        node: "sensor",
        destructive: false,
        timing: None,
        bench_hint: "the RS422 line: the baud on both ends (BAUDRATE), A/B wiring and termination, the USB adapter's latency timer",
    },
    CheckSpec {
        name: "sensor_counter_gapless",
        node: "sensor",
        destructive: false,
        timing: None,
        bench_hint: "the sensor's output load against its baud (BR > 33 x MR x m / ODR) and the host reading the line in time",
    },
    CheckSpec {
        name: "sensor_values_in_range",
        node: "sensor",
        destructive: false,
        timing: None,
        bench_hint: "the sensor's output settings (OUTDIST_RS422, OUTADD_RS422) against what GETOUTINFO_RS422 reports",
    },
    CheckSpec {
        name: "sensor_survives_bad_commands",
        node: "sensor",
        destructive: false,
        timing: None,
        bench_hint: "the sensor's firmware and command line end (CR LF): bad commands must be refused with Exx and GETINFO still answered",
    },
];

/// The check named `name` in [`CHECKS`].
#[must_use]
pub fn spec(name: &str) -> Option<&'static CheckSpec> {
    CHECKS.iter().find(|check| check.name == name)
}

/// The names of [`CHECKS`], comma-separated, for messages.
#[must_use]
pub fn known_names() -> String {
    CHECKS.map(|check| check.name).join(", ")
}

/// Whether a check runs, and if not why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Decision {
    /// It runs.
    Run,
    /// It is left out at the user's asking (`--check`, `--skip`): not listed.
    Deselected,
    /// It is left out for the bench's safety: listed as skipped with this reason.
    Skipped(String),
}

/// The checks a command line selects.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Selection {
    /// `--check NAME`s: only these run (all when empty).
    pub only: Vec<String>,
    /// `--skip NAME`s: these do not run.
    pub skip: Vec<String>,
    /// `--destructive`: the destructive checks run on a real link too.
    pub destructive: bool,
    /// The mirror node is the emulator `conformance` started itself (no bench to harm).
    pub emulated: bool,
    /// How the node is clocked: the timing checks differ.
    pub timing: TimingMode,
}

impl Selection {
    /// Checks the names given before anything opens: each must be a check, and a check
    /// asked for by name must be able to run.
    ///
    /// # Errors
    /// An unknown name (naming the known ones, under its flag's field), a destructive check
    /// asked for with `--check` on a real link without `--destructive`, or a selection that
    /// leaves no check to run.
    pub fn check(&self) -> Result<(), Invalid> {
        for (field, names) in [("check", &self.only), ("skip", &self.skip)] {
            if let Some(unknown) = names.iter().find(|name| spec(name).is_none()) {
                return Err(Invalid::new(
                    field,
                    format!(
                        "no conformance check `{unknown}` (the checks: {})",
                        known_names()
                    ),
                ));
            }
        }
        if let Some(other) = self.only.iter().find(|name| !self.applies(name)) {
            return Err(Invalid::new(
                "check",
                format!(
                    "`{other}` is a check of the other timing than --timing {} (its timing checks: {})",
                    self.timing.name(),
                    timing_checks(self.timing)
                ),
            ));
        }
        if let Some(harmful) = self
            .only
            .iter()
            .find(|name| matches!(self.decide(name), Decision::Skipped(_)))
        {
            return Err(Invalid::new(
                "check",
                format!(
                    "`{harmful}` can harm a real bench and runs on one only with --destructive"
                ),
            ));
        }
        if !CHECKS.iter().any(|check| self.runs(check.name)) {
            return Err(Invalid::new(
                "skip",
                "the selection leaves no check to run".to_owned(),
            ));
        }
        Ok(())
    }

    /// Whether check `name` runs.
    #[must_use]
    pub fn decide(&self, name: &str) -> Decision {
        let asked = self.only.is_empty() || self.only.iter().any(|only| only == name);
        if !asked || self.skip.iter().any(|skip| skip == name) || !self.applies(name) {
            return Decision::Deselected;
        }
        match spec(name) {
            Some(check) if check.destructive && !self.emulated && !self.destructive => {
                Decision::Skipped(format!(
                    "not run on a real link without --destructive ({})",
                    harm(name)
                ))
            }
            _ => Decision::Run,
        }
    }

    /// Whether check `name` applies to the node's timing.
    fn applies(&self, name: &str) -> bool {
        spec(name).is_none_or(|check| check.timing.is_none_or(|timing| timing == self.timing))
    }

    /// Whether check `name` runs.
    #[must_use]
    pub fn runs(&self, name: &str) -> bool {
        self.decide(name) == Decision::Run
    }
}

/// The checks that apply to `timing` only, comma-separated.
fn timing_checks(timing: TimingMode) -> String {
    CHECKS
        .iter()
        .filter(|check| check.timing == Some(timing))
        .map(|check| check.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// What a destructive check would do to a real bench.
fn harm(name: &str) -> &'static str {
    match name {
        "over_current_fault" => "it commands 8 A, beyond the amplifiers' limit, into the coils",
        _ => "its garbage lines test the adapter's firmware and may reach the bus",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(list: &[&str]) -> Vec<String> {
        list.iter().map(|&name| name.to_owned()).collect()
    }

    #[test]
    fn the_table_names_each_check_once_with_a_bench_hint() {
        for (i, check) in CHECKS.iter().enumerate() {
            assert!(
                CHECKS[..i].iter().all(|other| other.name != check.name),
                "{check:?}"
            );
            assert!(matches!(check.node, "fsm" | "sensor"), "{check:?}");
            assert!(check.bench_hint.len() > 20, "{check:?}");
        }
        let destructive: Vec<_> = CHECKS
            .iter()
            .filter(|c| c.destructive)
            .map(|c| c.name)
            .collect();
        assert_eq!(
            destructive,
            ["over_current_fault", "survives_garbage_slcan_lines"]
        );
    }

    #[test]
    fn a_real_link_skips_the_destructive_checks_unless_told() {
        let real = Selection::default();
        assert_eq!(real.decide("answers_in_time"), Decision::Run);
        for name in ["over_current_fault", "survives_garbage_slcan_lines"] {
            let Decision::Skipped(why) = real.decide(name) else {
                panic!("{name} runs on a real link");
            };
            assert!(why.contains("without --destructive"), "{why}");
            assert!(!real.runs(name));
        }
        assert!(real.decide("over_current_fault").ne(&Decision::Run));
        let told = Selection {
            destructive: true,
            ..Selection::default()
        };
        let emulated = Selection {
            emulated: true,
            ..Selection::default()
        };
        for selection in [told, emulated] {
            assert!(CHECKS.iter().all(|check| {
                selection.runs(check.name) == (check.timing != Some(TimingMode::Realtime))
            }));
        }
    }

    #[test]
    fn the_timing_checks_follow_the_nodes_timing() {
        let realtime = Selection {
            timing: TimingMode::Realtime,
            emulated: true,
            ..Selection::default()
        };
        let running: Vec<_> = CHECKS
            .iter()
            .filter(|c| realtime.runs(c.name))
            .map(|c| c.name)
            .collect();
        assert_eq!(running.len(), 13);
        assert!(!running.contains(&"answers_in_time"));
        assert!(running.contains(&"readings_on_time") && running.contains(&"reading_rate"));
        assert!(!Selection::default().runs("reading_rate"));
        let asked = Selection {
            only: names(&["answers_in_time"]),
            ..realtime
        };
        let error = asked.check().unwrap_err();
        assert_eq!(error.field, "check");
        assert!(
            error.reason.contains(
                "other timing than --timing realtime (its timing checks: readings_on_time, reading_rate)"
            ),
            "{error}"
        );
        let skipped = Selection {
            skip: names(&["answers_in_time"]),
            ..Selection::default()
        };
        assert_eq!(skipped.check(), Ok(()));
    }

    #[test]
    fn check_and_skip_select_by_name() {
        let only = Selection {
            only: names(&["status_frames", "angles_in_range"]),
            skip: names(&["angles_in_range"]),
            ..Selection::default()
        };
        assert_eq!(only.check(), Ok(()));
        let running: Vec<_> = CHECKS
            .iter()
            .filter(|c| only.runs(c.name))
            .map(|c| c.name)
            .collect();
        assert_eq!(running, ["status_frames"]);
        assert_eq!(only.decide("answers_in_time"), Decision::Deselected);
        let skip = Selection {
            skip: names(&["link_timeout_fault"]),
            emulated: true,
            ..Selection::default()
        };
        assert_eq!(skip.decide("link_timeout_fault"), Decision::Deselected);
        assert_eq!(skip.decide("over_current_fault"), Decision::Run);
    }

    #[test]
    fn names_are_checked_before_anything_opens() {
        let unknown = Selection {
            skip: names(&["frob"]),
            ..Selection::default()
        };
        let error = unknown.check().unwrap_err();
        assert_eq!(error.field, "skip");
        assert!(
            error
                .reason
                .starts_with("no conformance check `frob` (the checks: answers_in_time, "),
            "{error}"
        );
        let harmful = Selection {
            only: names(&["over_current_fault"]),
            ..Selection::default()
        };
        let error = harmful.check().unwrap_err();
        assert_eq!(error.field, "check");
        assert!(error.reason.contains("only with --destructive"), "{error}");
        let allowed = Selection {
            destructive: true,
            ..harmful
        };
        assert_eq!(allowed.check(), Ok(()));
        let nothing = Selection {
            skip: CHECKS.map(|c| c.name.to_owned()).to_vec(),
            ..Selection::default()
        };
        assert!(
            nothing
                .check()
                .unwrap_err()
                .reason
                .contains("no check to run")
        );
        // Only a check the real link leaves out is left: nothing would run.
        let only_harmful = Selection {
            skip: CHECKS
                .iter()
                .filter(|c| c.name != "over_current_fault")
                .map(|c| c.name.to_owned())
                .collect(),
            ..Selection::default()
        };
        assert!(only_harmful.check().is_err());
    }
}
