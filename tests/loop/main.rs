//! Loop tests: `scanhil` and `scanhil-emulator` as separate processes over pty pairs.
//!
//! Tolerances are stated where they are used. Nothing here measures time: the real-time test
//! checks only that timing statistics are present and ordered.

mod util;
// A mirror node that stops reading its line, on a real pty (for the peers and stuck-node tests).
mod deaf_node;

// The host's SLCAN `C` ends the emulator's run, in lockstep and in real time.
mod slcan_close;
// SLCAN adapters as their firmware behaves (silent, CANable, Lawicel with and without
// timestamps): conformance passes through each, a scan reports the adapter's stamps.
mod slcan_adapters;
// The emulator's watchdog: a silent controller gets zero coil currents and a LinkTimeout fault.
mod emulator_watchdog;
// Peers that stop reading: zero coils and a reason, never a blocked write.
mod peers;
// A whole scan over ptys: the Duplo stud's height, tracking error, recordings that decode.
mod scan_result;
// A dual-tone `scanhil design` made for the 1 Mbit/s bus's rate scans the Duplo stud.
mod designed_controller;
// identify --fit against a mirror that is not the paper's: parameters, refit, the twin scene.
mod fitted_twin;
// The bench-like mirror: identify sees its parts; the paper's PID scans the stud as predicted.
mod bench_scene;
// A recorded session served as the devices: bit for bit, divergence, bench capture, refusal.
mod replay;
// Lockstep determinism: the same seed twice gives bit-identical recordings and reports.
mod determinism;
// The sensor's samples on CAN or on the ILD stream: the same scan, the last period included.
mod sensor_transports;
// The real-sensor path: no declared clock, the estimate gives the declared clock's scan.
mod sensor_clock;
// The controller's watchdog: a frozen or killed emulator stops the scan with a link timeout.
mod controller_watchdog;
// The emulator a scan starts: stopped when it never becomes ready, killed with its host.
mod emulator_start;
// Conformance checks against the emulator and deliberately non-conforming nodes, with JUnit XML.
mod conformance;
// Conformance in real time: a node on its own clock, its rate and readings' timing checked.
mod conformance_realtime;
// Real time: statistics present and sane; bus-load refusal before a run.
mod timing;
// The host alone: a rig and no scene for devices it did not start; scenes checked against rigs.
mod rig_alone;
// An interrupted scan (Ctrl-C, SIGTERM): zero current, C sent, outputs written, exit 3.
mod interrupted;
// A killed scan (SIGKILL): its recording holds whole lines up to the period in flight.
mod killed;
// A node that stops reading its line: the host's blocked send ends by watchdog or SIGTERM.
mod stuck_node;
// The output folder: one scan at a time, no stale files after a re-scan.
mod out_folder;
// Faults declared in a scenario over ptys: injected, detected, reported, nothing lost.
mod faults;
// Real-time options: busy-poll and pinning reported with the wake-up probe and who missed;
// SCHED_FIFO without the privilege warns and goes on.
mod realtime_options;
// Bad values refused or warned about before a run; an OS error said once.
mod bad_input;
// Verdicts: runs that did nothing or did not track exit 4 with their reasons.
mod verdicts;
// Outputs that cannot be written (a full disk, a directory in the way): the others are.
mod output_failures;
// Recordings for a technician's tools: Unix-time stamps and a real interface name, decoded.
mod recordings;
