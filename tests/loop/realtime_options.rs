//! Real-time options over ptys: a busy-polling, pinned scan reports what it had, both ends'
//! wake-up probes, its jitter beside the probe and every missed deadline attributed (facts
//! that add up whatever the machine's load; nothing is timed); SCHED_FIFO without the privilege
//! gives one warning per end naming what was refused, and the scan goes on without it.

use std::os::unix::process::CommandExt;

use crate::util::{
    assert_ran_every_period, number, realtime_scan_args, report, run_scanhil, run_scanhil_with,
};

/// `CAP_IPC_LOCK` and `CAP_SYS_NICE` (linux/capability.h).
const CAP_IPC_LOCK: nix::libc::c_ulong = 14;
const CAP_SYS_NICE: nix::libc::c_ulong = 23;

/// Asserts `0 <= min <= median <= p99 <= max` of the stats at `pointer` (`min` 0 where a
/// summary gives none) and returns median, p99 and max.
fn ordered(report: &serde_json::Value, pointer: &str) -> (f64, f64, f64) {
    let min = report
        .pointer(&format!("{pointer}/min_s"))
        .map_or(0.0, |_| number(report, &format!("{pointer}/min_s")));
    let median = number(report, &format!("{pointer}/median_s"));
    let p99 = number(report, &format!("{pointer}/p99_s"));
    let max = number(report, &format!("{pointer}/max_s"));
    assert!(
        0.0 <= min && min <= median && median <= p99 && p99 <= max,
        "{pointer}: min {min} median {median} p99 {p99} max {max}"
    );
    (median, p99, max)
}

/// Asserts one side's share of the missed deadlines is consistent; returns its count.
fn side_misses(report: &serde_json::Value, side: &str) -> f64 {
    let pointer = format!("/timing/deadline_misses/{side}");
    let count = number(report, &format!("{pointer}/count"));
    let unmeasured = number(report, &format!("{pointer}/unmeasured"));
    assert!(unmeasured <= count, "{side}");
    let measured = count - unmeasured;
    let worst = report.pointer(&format!("{pointer}/worst_s")).expect(side);
    let p99 = report.pointer(&format!("{pointer}/p99_s")).expect(side);
    assert_eq!(
        worst.is_null(),
        measured == 0.0,
        "{side}: a worst delay iff some measured"
    );
    if let (Some(worst), Some(p99)) = (worst.as_f64(), p99.as_f64()) {
        assert!(
            0.0 <= p99 && p99 <= worst,
            "{side}: p99 {p99} worst {worst}"
        );
    }
    count
}

#[test]
fn a_busy_polling_pinned_scan_reports_its_probes_jitter_and_who_missed() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let two_cpus = std::thread::available_parallelism().is_ok_and(|n| n.get() >= 2);
    // Two busy-polling ends on one CPU are refused; on a one-CPU machine neither is pinned.
    let pinned: &[&str] = if two_cpus {
        &[
            "--busy-poll",
            "--probe-s",
            "0.05",
            "--cpu",
            "0",
            "--emulator-cpu",
            "1",
        ]
    } else {
        &["--busy-poll", "--probe-s", "0.05"]
    };
    let args = realtime_scan_args(out.path(), "0.2", pinned);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let output = run_scanhil(&args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    // A loaded machine may leave the host behind when the node's duration ends (a hang-up,
    // exit 3, said on stderr); either way the report is complete.
    let report = match output.status.code() {
        Some(3) => {
            assert!(stderr.contains("scan stopped early"), "{stderr}");
            report(out.path())
        }
        _ => assert_ran_every_period(&output, out.path()),
    };
    let host = &report["timing"]["controller"]["scheduling"];
    let node = &report["timing"]["emulator"]["scheduling"];
    assert_eq!(host["in_effect"]["busy_poll"], true, "{host}");
    assert_eq!(node["in_effect"]["busy_poll"], true, "{node}");
    if two_cpus {
        assert_eq!(host["in_effect"]["cpu"], 0, "{host}");
        assert_eq!(node["in_effect"]["cpu"], 1, "{node}");
    }
    // Each end's probe: one wake-up per period of its 50 ms, ordered.
    for end in ["controller", "emulator"] {
        let probe = format!("/timing/{end}/scheduling/wakeup_probe");
        assert_eq!(
            number(&report, &format!("{probe}/periods")),
            1000.0,
            "{end}"
        );
        ordered(&report, &probe);
    }
    // The loop's tick lateness beside the emulator's probe, and their ratio.
    let (_, loop_p99, _) = ordered(&report, "/timing/jitter_against_probe/loop_tick_lateness");
    let (_, probe_p99, _) = ordered(&report, "/timing/jitter_against_probe/wakeup_probe");
    let jitter = &report["timing"]["jitter_against_probe"];
    if probe_p99 > 0.0 {
        let ratio = number(jitter, "/p99_ratio");
        assert!(
            (ratio - loop_p99 / probe_p99).abs() <= 1e-9 * ratio,
            "{jitter}"
        );
        assert_eq!(jitter["within_target"], ratio <= 2.0, "{jitter}");
    }
    // Tick lateness and period agree on the ticks that started a whole period late.
    let late = number(&report, "/timing/emulator/tick_lateness/overruns");
    assert_eq!(
        late,
        number(&report, "/timing/emulator/tick_lateness/above_nominal")
    );
    assert_eq!(
        late,
        number(&report, "/timing/emulator/period_jitter/overruns")
    );
    // Every missed deadline but period 0's (no reading precedes it) is attributed, once.
    let total = number(&report, "/timing/deadline_misses/total");
    let sides =
        side_misses(&report, "node") + side_misses(&report, "host") + side_misses(&report, "link");
    assert_eq!(sides, total, "{}", report["timing"]["deadline_misses"]);
    assert_eq!(
        total,
        number(&report, "/timing/emulator/stale_command_periods") - 1.0,
        "{}",
        report["timing"]
    );
    assert!(
        report["emulator"]["summary"]["timing"]
            .get("missed_deadlines")
            .is_none(),
        "the long list is replaced by its attribution"
    );
    assert!(
        stdout.contains("real time: busy-poll on") && stdout.contains("deadline: missed in"),
        "{stdout}"
    );
}

#[test]
fn sched_fifo_without_the_privilege_warns_on_both_ends_and_the_scan_goes_on() {
    let out = tempfile::tempdir().expect("a temporary folder");
    let args = realtime_scan_args(
        out.path(),
        "0.05",
        &["--sched-fifo-priority", "50", "--probe-s", "0.01"],
    );
    let output = run_scanhil_with(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        |command| {
            // SAFETY: between fork and exec the child only makes two system calls per limit,
            // async-signal-safe, touching no memory of the parent.
            unsafe {
                command.pre_exec(|| {
                    // Without CAP_SYS_NICE and CAP_IPC_LOCK (root keeps neither across exec
                    // once they leave the bounding set; a user has neither), an RLIMIT_RTPRIO
                    // and RLIMIT_MEMLOCK of 0 refuse SCHED_FIFO and mlockall with EPERM. The
                    // emulator this scan starts inherits all of it.
                    for capability in [CAP_SYS_NICE, CAP_IPC_LOCK] {
                        let _ = nix::libc::prctl(nix::libc::PR_CAPBSET_DROP, capability, 0, 0, 0);
                    }
                    let none = nix::libc::rlimit {
                        rlim_cur: 0,
                        rlim_max: 0,
                    };
                    for resource in [nix::libc::RLIMIT_RTPRIO, nix::libc::RLIMIT_MEMLOCK] {
                        if nix::libc::setrlimit(resource, &none) != 0 {
                            return Err(std::io::Error::last_os_error());
                        }
                    }
                    Ok(())
                });
            }
        },
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_ran_every_period(&output, out.path());
    for end in ["scanhil", "scanhil-emulator"] {
        for refused in [
            format!("{end}: warning: SCHED_FIFO at priority 50 not granted (EPERM"),
            format!("{end}: warning: locking memory (mlockall) not granted (EPERM"),
        ] {
            assert_eq!(
                stderr.matches(&refused).count(),
                1,
                "{refused}\nin:\n{stderr}"
            );
        }
    }
    let report = report(out.path());
    for end in ["controller", "emulator"] {
        let in_effect = &report["timing"][end]["scheduling"]["in_effect"];
        assert!(
            in_effect["sched_fifo_priority"].is_null(),
            "{end}: {in_effect}"
        );
        assert_eq!(in_effect["memory_locked"], false, "{end}: {in_effect}");
        assert_eq!(
            in_effect["warnings"].as_array().map(Vec::len),
            Some(2),
            "{end}"
        );
    }
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("host SCHED_FIFO not granted, memory not locked"),
        "{stdout}"
    );
}
