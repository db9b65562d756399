//! Real-time scheduling of a loop's thread, for `--timing realtime` on both ends: pinning to
//! one CPU (`sched_setaffinity`), `SCHED_FIFO` at a priority with all memory locked
//! (`mlockall`), and busy-polling (a flag the loops read: they spin on non-blocking reads
//! instead of waiting on readiness). Where the process may not have one of these (`EPERM`), it
//! goes on without it: [`apply`] returns one warning per refusal, naming what was not granted
//! and why, and [`InEffect`] says what the run really had.
//!
//! Also the wake-up probe ([`wakeup_probe`]): cyclictest's measurement, run for a short time
//! before the loop with the same settings, so a report can put the loop's jitter beside the
//! machine's own wake-up latency.

use std::time::Duration;

use nix::errno::Errno;
use nix::sched::{CpuSet, sched_setaffinity};
use nix::sys::mman::{MlockAllFlags, mlockall};
use nix::sys::time::TimeSpec;
use nix::time::{ClockId, ClockNanosleepFlags, clock_gettime, clock_nanosleep};
use nix::unistd::{Pid, SysconfVar, sysconf};
use thread_priority::{
    RealtimeThreadSchedulePolicy, ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
    set_thread_priority_and_policy, thread_native_id,
};

use crate::loop_timing::{PeriodRecorder, PeriodStats};

/// The highest `SCHED_FIFO` priority Linux gives.
pub const MAX_FIFO_PRIORITY: u8 = 99;

/// What a real-time loop asks of the operating system.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RealtimeOptions {
    /// Spin on non-blocking reads instead of waiting on readiness (a CPU at 100 %).
    pub busy_poll: bool,
    /// Pin the loop's thread to this CPU.
    pub cpu: Option<usize>,
    /// Run the loop's thread under `SCHED_FIFO` at this priority (1 to 99), all memory locked.
    pub sched_fifo_priority: Option<u8>,
}

/// What a run really had: the options granted, and a warning for each one refused.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct InEffect {
    /// Busy-polling (always granted when asked).
    pub busy_poll: bool,
    /// The CPU the thread is pinned to, if pinning was granted.
    pub cpu: Option<usize>,
    /// The `SCHED_FIFO` priority, if granted.
    pub sched_fifo_priority: Option<u8>,
    /// Whether `mlockall(MCL_CURRENT | MCL_FUTURE)` was granted.
    pub memory_locked: bool,
    /// One line per option that was asked for and not granted.
    pub warnings: Vec<String>,
}

/// How many CPUs the machine has online (`sysconf(_SC_NPROCESSORS_ONLN)`): a CPU to pin to is
/// below this. Not the calling process's affinity mask, which a pinned parent passes on.
///
/// # Errors
/// The OS error of `sysconf`.
pub fn online_cpus() -> Result<usize, Errno> {
    let online = sysconf(SysconfVar::_NPROCESSORS_ONLN)?.unwrap_or(1);
    Ok(usize::try_from(online).unwrap_or(1))
}

/// Checks options before any is applied: a priority within 1 to 99 and a CPU the machine has
/// online (one outside the process's cpuset is refused when applied, with a warning). Returns the field and the reason.
///
/// # Errors
/// `(field, reason)` for the first option out of range.
pub fn check(options: &RealtimeOptions) -> Result<(), (&'static str, String)> {
    if let Some(priority) = options.sched_fifo_priority
        && !(1..=MAX_FIFO_PRIORITY).contains(&priority)
    {
        return Err((
            "sched_fifo_priority",
            format!("{priority} is not between 1 and {MAX_FIFO_PRIORITY}"),
        ));
    }
    if let Some(cpu) = options.cpu {
        let online = online_cpus().map_err(|errno| ("cpu", format!("{errno}")))?;
        if cpu >= online {
            return Err((
                "cpu",
                format!(
                    "CPU {cpu} is not on this machine (CPUs 0 to {})",
                    online - 1
                ),
            ));
        }
    }
    Ok(())
}

/// Applies `options` to the calling thread (threads it starts later inherit them). Each
/// refusal becomes a warning in the result, not an error: the run goes on without it.
#[must_use]
pub fn apply(options: &RealtimeOptions) -> InEffect {
    let mut effect = InEffect {
        busy_poll: options.busy_poll,
        ..InEffect::default()
    };
    if let Some(cpu) = options.cpu {
        let mut set = CpuSet::new();
        let pinned = set
            .set(cpu)
            .and_then(|()| sched_setaffinity(Pid::from_raw(0), &set));
        match pinned {
            Ok(()) => effect.cpu = Some(cpu),
            Err(errno) => effect.warnings.push(not_granted(
                &format!("pinning to CPU {cpu}"),
                errno,
                "CAP_SYS_NICE or a CPU in the process's affinity mask",
            )),
        }
    }
    if let Some(priority) = options.sched_fifo_priority {
        let granted = ThreadPriorityValue::try_from(priority)
            .map_err(|_| Errno::EINVAL)
            .and_then(|value| {
                set_thread_priority_and_policy(
                    thread_native_id(),
                    ThreadPriority::Crossplatform(value),
                    ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
                )
                .map_err(|error| match error {
                    thread_priority::Error::OS(code) => Errno::from_raw(code),
                    _ => Errno::EINVAL,
                })
            });
        match granted {
            Ok(()) => effect.sched_fifo_priority = Some(priority),
            Err(errno) => effect.warnings.push(not_granted(
                &format!("SCHED_FIFO at priority {priority}"),
                errno,
                &format!("CAP_SYS_NICE or an RLIMIT_RTPRIO of at least {priority} (`ulimit -r`)"),
            )),
        }
        match mlockall(MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE) {
            Ok(()) => effect.memory_locked = true,
            Err(errno) => effect.warnings.push(not_granted(
                "locking memory (mlockall)",
                errno,
                "CAP_IPC_LOCK or an RLIMIT_MEMLOCK above the process's size (`ulimit -l`)",
            )),
        }
    }
    effect
}

/// The warning for an option the OS refused: what, the error, and what would grant it.
#[must_use]
pub fn not_granted(what: &str, errno: Errno, needs: &str) -> String {
    format!("warning: {what} not granted ({errno}); it needs {needs}; running without it")
}

/// cyclictest's measurement: sleeps to absolute deadlines `period` apart on the monotonic clock
/// (`clock_nanosleep(TIMER_ABSTIME)`) for `duration`, and records how late each wake-up came.
/// Overruns are wake-ups later than one period. `None` when `duration` holds no period.
///
/// # Errors
/// The OS error of reading the clock or sleeping (other than an interrupting signal).
pub fn wakeup_probe(period: Duration, duration: Duration) -> Result<Option<PeriodStats>, Errno> {
    let wakeups = if period.is_zero() {
        0
    } else {
        duration.as_nanos() / period.as_nanos()
    };
    let mut latencies = PeriodRecorder::new(period.as_secs_f64());
    let start = Duration::from(clock_gettime(ClockId::CLOCK_MONOTONIC)?);
    for k in 1..=wakeups {
        let deadline = start + period.saturating_mul(u32::try_from(k).unwrap_or(u32::MAX));
        let request = TimeSpec::from_duration(deadline);
        loop {
            match clock_nanosleep(
                ClockId::CLOCK_MONOTONIC,
                ClockNanosleepFlags::TIMER_ABSTIME,
                &request,
            ) {
                Ok(_) => break,
                Err(Errno::EINTR) => {}
                Err(errno) => return Err(errno),
            }
        }
        let woke = Duration::from(clock_gettime(ClockId::CLOCK_MONOTONIC)?);
        let late = woke.saturating_sub(deadline);
        latencies.record(late.as_secs_f64());
        if late > period {
            latencies.overrun();
        }
    }
    Ok(latencies.stats())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refusal_names_what_why_and_what_would_grant_it() {
        let warning = not_granted("SCHED_FIFO at priority 80", Errno::EPERM, "CAP_SYS_NICE");
        assert!(warning.starts_with("warning: SCHED_FIFO at priority 80 not granted"));
        assert!(
            warning.contains("(EPERM: Operation not permitted)"),
            "{warning}"
        );
        assert!(warning.contains("needs CAP_SYS_NICE"), "{warning}");
    }

    #[test]
    fn out_of_range_options_are_refused_before_anything_is_applied() {
        let priority = RealtimeOptions {
            sched_fifo_priority: Some(0),
            ..RealtimeOptions::default()
        };
        assert_eq!(check(&priority).unwrap_err().0, "sched_fifo_priority");
        let cpu = RealtimeOptions {
            cpu: Some(online_cpus().expect("sysconf")),
            ..RealtimeOptions::default()
        };
        assert_eq!(check(&cpu).unwrap_err().0, "cpu");
        assert!(check(&RealtimeOptions::default()).is_ok());
    }

    #[test]
    fn the_probe_records_one_latency_per_period() {
        let stats = wakeup_probe(Duration::from_millis(1), Duration::from_millis(20))
            .expect("the monotonic clock")
            .expect("20 periods");
        assert_eq!(stats.periods, 20);
        assert!(stats.min_s >= 0.0 && stats.median_s <= stats.p99_s && stats.p99_s <= stats.max_s);
        assert!(
            wakeup_probe(Duration::from_millis(1), Duration::ZERO)
                .unwrap()
                .is_none()
        );
    }
}
