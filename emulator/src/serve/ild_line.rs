//! The ILD 2300's RS422 line as it paces the sensor's output cycles, free of I/O and clocks:
//! each cycle goes out when it is measured if the line is free, its last byte arriving the
//! line's transmit time later (3 bytes of 10 bits a value at the line's baud); a cycle measured
//! while the line is still busy waits for it, and a newer one replaces it (the waiting one is
//! lost), as the optoNCDT family's manuals describe the output when the baud rate cannot carry
//! every value ("the sensor holds back the output until the last measurement value has been
//! issued in full; the next value is the last valid one, the others between are lost").
//!
//! The serve loops ask what has arrived by a loop time: in lockstep, by the end of the period
//! just stepped (so each value is delivered in the period its last byte would arrive in); in
//! real time, by the tick's start (so the line's transmit time is part of the loop's latency,
//! to the tick's resolution).

use std::collections::VecDeque;

use scanhil_protocol::ild::stream::{BITS_PER_BYTE, BYTES_PER_VALUE};

/// One output cycle on the line.
#[derive(Debug, Clone, PartialEq)]
pub struct PacedCycle {
    /// The sensor's measured-value counter of the sample.
    pub counter: u32,
    /// When its last byte arrives at the host, loop time s.
    pub arrives_s: f64,
    /// Its raw 18-bit values, first to last.
    pub values: Vec<u32>,
}

/// The line's state: what is on it or queued for it, and what the baud rate cost.
#[derive(Debug, Clone)]
pub struct IldLine {
    seconds_per_value: f64,
    /// When the line has sent everything scheduled so far, loop time s.
    free_at_s: f64,
    scheduled: VecDeque<PacedCycle>,
    /// A cycle measured while the line was busy: it goes out when the line frees.
    waiting: Option<PacedCycle>,
    lost: u64,
}

impl IldLine {
    /// An idle line at `baud`.
    #[must_use]
    pub fn new(baud: u32) -> IldLine {
        IldLine {
            seconds_per_value: BYTES_PER_VALUE as f64 * BITS_PER_BYTE / f64::from(baud.max(1)),
            free_at_s: f64::NEG_INFINITY,
            scheduled: VecDeque::new(),
            waiting: None,
            lost: 0,
        }
    }

    /// Offers a cycle of `values` for the sample with measured-value counter `counter`,
    /// measured at `measured_s` (cycles come in the order they are measured).
    pub fn push(&mut self, measured_s: f64, counter: u32, values: Vec<u32>) {
        self.settle(measured_s);
        let cycle = PacedCycle {
            counter,
            arrives_s: measured_s,
            values,
        };
        if self.free_at_s <= measured_s {
            self.schedule(cycle, measured_s);
        } else if self.waiting.replace(cycle).is_some() {
            self.lost += 1;
        }
    }

    /// The cycles whose last byte has arrived by `until_s`, in order.
    pub fn due(&mut self, until_s: f64) -> Vec<PacedCycle> {
        self.settle(until_s);
        let arrived = self
            .scheduled
            .iter()
            .take_while(|cycle| cycle.arrives_s <= until_s)
            .count();
        self.scheduled.drain(..arrived).collect()
    }

    /// Every cycle still on the line or waiting for it, in order (the end of a run: what the
    /// line would still deliver).
    pub fn drain(&mut self) -> Vec<PacedCycle> {
        self.due(f64::INFINITY)
    }

    /// Cycles lost because the line was busy (a newer cycle replaced them while they waited).
    #[must_use]
    pub fn lost(&self) -> u64 {
        self.lost
    }

    /// The waiting cycle goes out if the line is free by `t_s`.
    fn settle(&mut self, t_s: f64) {
        if self.free_at_s <= t_s
            && let Some(cycle) = self.waiting.take()
        {
            let start = self.free_at_s;
            self.schedule(cycle, start);
        }
    }

    fn schedule(&mut self, mut cycle: PacedCycle, start_s: f64) {
        cycle.arrives_s = start_s + self.seconds_per_value * cycle.values.len() as f64;
        self.free_at_s = cycle.arrives_s;
        self.scheduled.push_back(cycle);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 691 200 baud: one value takes 30 bits, 43.4 us.
    const BAUD: u32 = 691_200;
    const VALUE_S: f64 = 30.0 / 691_200.0;

    #[test]
    fn a_free_line_delivers_each_cycle_its_transmit_time_after_it_was_measured() {
        let mut line = IldLine::new(BAUD);
        line.push(0.0, 0, vec![1]);
        line.push(50e-6, 1, vec![2]);
        assert!(line.due(VALUE_S * 0.999).is_empty());
        let first = line.due(VALUE_S);
        assert_eq!(first.len(), 1);
        assert!((first[0].arrives_s - VALUE_S).abs() < 1e-15);
        let second = line.due(1.0);
        assert_eq!(second.len(), 1);
        assert!((second[0].arrives_s - (50e-6 + VALUE_S)).abs() < 1e-15);
        assert_eq!(line.lost(), 0);
    }

    #[test]
    fn cycles_the_baud_cannot_carry_wait_and_the_older_is_lost() {
        // Two values a cycle at 20 kHz: 86.8 us a cycle against 50 us between them.
        let mut line = IldLine::new(BAUD);
        for k in 0..4 {
            line.push(f64::from(k) * 50e-6, k, vec![k, 100 + k]);
        }
        let delivered = line.drain();
        // Cycle 0 goes at 0 s; cycle 1 (50 us) waits for the line, which frees at 86.8 us, and
        // goes then; cycle 2 (100 us) waits for 173.6 us, and cycle 3 (150 us) replaces it.
        let measured: Vec<u32> = delivered.iter().map(|c| c.values[0]).collect();
        assert_eq!(measured, [0, 1, 3]);
        assert_eq!(line.lost(), 1);
        let arrives: Vec<f64> = delivered.iter().map(|c| c.arrives_s).collect();
        let two = 2.0 * VALUE_S;
        for (got, want) in arrives.iter().zip([two, 2.0 * two, 3.0 * two]) {
            assert!((got - want).abs() < 1e-12, "{arrives:?}");
        }
    }

    #[test]
    fn a_waiting_cycle_goes_out_when_the_line_frees_without_a_newer_one() {
        let mut line = IldLine::new(BAUD);
        line.push(0.0, 0, vec![1, 1]);
        line.push(50e-6, 1, vec![2, 2]);
        // The second waits for the first (to 86.8 us), then takes its own 86.8 us.
        assert_eq!(line.due(2.0 * VALUE_S).len(), 1);
        assert!(line.due(4.0 * VALUE_S * 0.999).is_empty());
        assert_eq!(line.due(4.0 * VALUE_S).len(), 1);
        assert_eq!(line.lost(), 0);
    }
}
