#!/usr/bin/env python3
"""Checks the loop run over a real CAN bus (ci/vm/loop-vcan.sh) against the same scan over pty links.

OUT holds three output folders of `scanhil scan fixtures/scenarios/vcan-small.json`:
  vcan/     the mirror node and the sensor's Distance frames on socketcan:vcan0, with
            vcan/candump.log, what `candump -L vcan0` recorded beside the two programs;
  pty-can/  the mirror node on SLCAN over a pty, the Distance frames on it (--sensor fsm);
  pty-ild/  the default emulated links: SLCAN for the mirror, the ILD RS422 stream for the sensor.

Checks:
1. The capture, read by cantools' candump log parser: every line is a frame on vcan0, every frame
   decodes with the DBC, wall-clock stamps never go back; Step.Step and AngleReading.Seq run
   0, 1, ..., N-1 (N = the report's periods) without a gap, CoilCommand.Seq 0, 1, ..., N with the
   last one the zero (0 A, 0 A) that ends a complete run (coils at zero at every end), the Distance
   frames' IldCounter counts up by one (18 bits) and there is one per sensor sample the emulator
   sent; the last frame is the node's StatusFsm(ready) that ends the run.
2. The bus carried exactly what the controller recorded in vcan/fsm.log (its candump log of the
   link, stamped with loop time and named `fsm`, the same on every transport): the controller's
   frames and the emulator's (mirror and sensor nodes; senders per the DBC) are the same (id, data) sequences, in the
   same order, in both. The merged order differs and must: the controller logs a frame when it
   reads it, so the node's Distance frames of period k, sent after AngleReading(k), are logged
   after the controller's CoilCommand(k + 1) although they were on the bus before it. The stamps
   (wall clock vs loop time) and the interface column differ too.
3. Lockstep determinism across transports:
   - fsm.log of vcan and pty-can are identical byte for byte (same frames, same loop-time stamps);
   - points.ply, height_map.csv/.png, tracking.svg, progressive.svg, snapshots.png and
     profiles.svg/.csv are identical byte for byte in all three folders (the point cloud, the
     height map, the tracking record, the reconstruction error against scan time, the snapshots
     and the sections);
   - report.json is identical in all three, every number compared exactly (JSON floats are written
     shortest-round-trip, so equal numbers are equal bits), except the fields that name or count the
     transport itself: scenario.links (the links asked for), links.mirror_link (the mirror link's
     own report: its URI, transport, adapter and traffic), links.sensor (the ILD stream's own
     counters, zero when the sensor is on CAN) and emulator.summary.link.frames_sent (the Distance
     frames travel on the mirror's link on CAN, on their own line with ILD), sensor_setup and
     emulator.summary.sensor.commands_answered (the ILD line is configured over its ASCII
     commands; on CAN there is none), and the wall-clock fields of a lockstep report: run_time_s
     and each scene part's measured cost per period (emulator.summary.parts) (timing.controller and timing.emulator are null,
     and are compared as such).
4. The sensor's data is the same on both of its transports: the output cycles of pty-ild/sensor.ild,
   the raw ILD RS422 stream as `scanhil decode --format ild` reads it, carry the values the
   pty-ild report's sensor_setup.output_values names (GETOUTINFO_RS422's order): their DIST1
   values equal the IldRaw of the Distance frames on vcan0, and their COUNTER values (when the
   rig streams the counter) the frames' IldCounter. The paper's bench streams the distance alone
   (distance and counter do not fit 691 200 baud at 20 kHz), so the host counts the cycles and
   places the first at the counter the emulator declares: samples.sensor_clock.counter_offset
   and emulator.summary.sensor.baud (the ILD line's) are transport fields there too.
5. Both runs ended cleanly: complete, every period done, no sequence gap or malformed frame seen by
   the controller, the emulator finished by itself (exit status 0, not killed) on every transport.

Usage: vcan_loop_check.py OUT DBC SCANHIL_BINARY
Prints one line per failed check and a summary; exit status 1 on any failure.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import cantools
from cantools.logreader import Parser

BYTE_IDENTICAL = [
    "points.ply",
    "height_map.csv",
    "height_map.png",
    "tracking.svg",
    "progressive.svg",
    "snapshots.png",
    "profiles.svg",
    "profiles.csv",
]
# Report fields that describe or count the transport, per compared folder (JSON paths, prefixes).
# The wall-clock figures of a lockstep report: run_time_s and each scene part's measured cost
# per period (emulator.summary.parts, measured before the run).
WALL_CLOCK_FIELDS = [
    ("run_time_s",),
    ("emulator", "summary", "parts", "plant_us_per_period"),
    ("emulator", "summary", "parts", "bare_us_per_period"),
    ("emulator", "summary", "parts", "parts", "*", "us_per_period"),
]
TRANSPORT_FIELDS = {
    "pty-can": [*WALL_CLOCK_FIELDS, ("scenario", "links", "fsm")],
    "pty-ild": [
        *WALL_CLOCK_FIELDS,
        ("scenario", "links", "fsm"),
        ("scenario", "links", "sensor"),
        ("links", "sensor"),
        ("sensor_setup",),
        ("emulator", "summary", "link", "frames_sent"),
        ("emulator", "summary", "sensor", "commands_answered"),
        ("emulator", "summary", "sensor", "baud"),
        ("samples", "sensor_clock", "counter_offset"),
    ],
}
# The mirror link's own report (its URI, transport, adapter and traffic) describes the transport
# in every compared folder.
for fields in TRANSPORT_FIELDS.values():
    fields.append(("links", "mirror_link"))
CANDUMP_LINE = re.compile(r"^\((\d+\.\d+)\) (\S+) ([0-9A-F]{3}|[0-9A-F]{8})#([0-9A-F]*)$")

from tally import Tally

TALLY = Tally("vcan_loop_check")
check = TALLY.check


def read_candump(path):
    """(stamp, interface, id, data) per line; a line that is not candump -L is a failure."""
    frames = []
    for number, line in enumerate(path.read_text(encoding="ascii").splitlines(), 1):
        match = CANDUMP_LINE.match(line)
        if check(match is not None, f"{path}:{number}: not a candump -L line: {line!r}"):
            stamp, interface, frame_id, data = match.groups()
            frames.append((float(stamp), interface, int(frame_id, 16), bytes.fromhex(data)))
    return frames


def gapless(values, modulus, what, start=None):
    if not check(values, f"no {what} on the bus"):
        return
    if start is not None:
        check(values[0] == start, f"{what} starts at {values[0]}, not {start}")
    for i, (a, b) in enumerate(zip(values, values[1:])):
        if not check(b == (a + 1) % modulus, f"{what} jumps from {a} to {b} (frame {i + 1} of them)"):
            return


def check_capture(out, db, report, summary):
    capture = out / "vcan" / "candump.log"
    frames = read_candump(capture)
    with capture.open(encoding="ascii") as f:
        entries = [e for e in Parser(f) if e is not None]
    check(len(entries) == len(frames), f"cantools read {len(entries)} frames of {len(frames)} lines")
    check(all(f[1] == "vcan0" for f in frames), "a frame on another interface than vcan0")
    check(all(a[0] <= b[0] for a, b in zip(frames, frames[1:])), "capture stamps go back in time")

    signals = {}
    for i, entry in enumerate(entries):
        try:
            message = db.get_message_by_frame_id(entry.frame_id)
            decoded = message.decode(bytes(entry.data), decode_choices=False)
        except Exception as error:  # noqa: BLE001 -- any decoding failure is the finding
            check(False, f"frame {i} ({entry.frame_id:#x}#{bytes(entry.data).hex()}) does not decode: {error}")
            continue
        signals.setdefault(message.name, []).append(decoded)

    periods = report["periods"]["planned"]
    # One CoilCommand per period and the final zero of a complete run (coils at zero at every end).
    for name, signal, modulus, count in [("CoilCommand", "Seq", 1 << 16, periods + 1),
                                         ("Step", "Step", 1 << 32, periods),
                                         ("AngleReading", "Seq", 1 << 16, periods)]:
        values = [s[signal] for s in signals.get(name, [])]
        check(len(values) == count, f"{len(values)} {name} frames for {periods} periods (expected {count})")
        gapless(values, modulus, f"{name}.{signal}", start=0)
    final = signals.get("CoilCommand", [{}])[-1]
    check(final.get("CurrentA") == 0 and final.get("CurrentB") == 0,
          f"the last CoilCommand on the bus is not the zero of the run's end: {final}")
    distances = [(s["IldRaw"], s["IldCounter"]) for s in signals.get("Distance", [])]
    counters = [counter for _, counter in distances]
    gapless(counters, 1 << 18, "Distance.IldCounter")
    sent = summary["sensor"]["samples"]
    check(len(counters) == sent, f"{len(counters)} Distance frames on the bus, the emulator sent {sent}")
    last = entries[-1] if entries else None
    last_is_ready = (last is not None and db.get_message_by_frame_id(last.frame_id).name == "StatusFsm"
                     and signals["StatusFsm"][-1]["State"] == 1)
    check(last_is_ready, "the capture does not end with the node's StatusFsm(ready)")
    counts = ", ".join(f"{len(v)} {k}" for k, v in sorted(signals.items()))
    print(f"vcan_loop_check: capture: {len(frames)} frames on vcan0 decode with the DBC ({counts})")

    recorded = read_candump(out / "vcan" / "fsm.log")
    # The controller records a frame when it reads it, so the node's Distance frames of period k,
    # on the bus before CoilCommand(k + 1), come after it in fsm.log: compare each sender's frames
    # in order (each sender's frames reach the bus in the order sent).
    for side, from_controller in [("controller", True), ("node", False)]:
        def sent_by_side(log):
            return [(f[2], f[3]) for f in log
                    if ("Controller" in db.get_message_by_frame_id(f[2]).senders) == from_controller]
        on_bus, in_record = sent_by_side(frames), sent_by_side(recorded)
        check(on_bus == in_record,
              f"the bus carried other {side} frames than the controller recorded ({len(on_bus)} vs {len(in_record)})")
    check(len(frames) == len(recorded), f"{len(frames)} frames on the bus, {len(recorded)} in the controller's record")
    span = frames[-1][0] - frames[0][0] if frames else 0.0
    print(f"vcan_loop_check: capture: compared, sender by sender and in order, with the "
          f"controller's fsm.log ({len(recorded)} frames; {span:.2f} s of wall clock on the bus for "
          f"{recorded[-1][0] if recorded else 0:.6f} s of loop time)")
    return distances


def check_ild_stream(scanhil, capture, distances, output_values):
    """The ILD stream's cycles (laid out as output_values says) against the Distance frames'
    (IldRaw, IldCounter): DIST1 against IldRaw, COUNTER (when streamed) against IldCounter."""
    result = subprocess.run([scanhil, "decode", str(capture), "--format", "ild"],
                            capture_output=True, text=True, check=False)
    if not check(result.returncode == 0, f"scanhil decode --format ild {capture}: {result.stderr.strip()}"):
        return
    words = [json.loads(line) for line in result.stdout.splitlines()]
    per_cycle = len(output_values)
    laid_out = (per_cycle > 0 and "DIST1" in output_values and len(words) % per_cycle == 0
                and all(w["index"] == i % per_cycle for i, w in enumerate(words)))
    if not check(laid_out, f"{capture}: the cycles are not {' '.join(output_values)} each"):
        return
    cycles = [words[i:i + per_cycle] for i in range(0, len(words), per_cycle)]
    dist = output_values.index("DIST1")
    counter = output_values.index("COUNTER") if "COUNTER" in output_values else None
    streamed = [(c[dist]["raw"], c[counter]["raw"] if counter is not None else None) for c in cycles]
    expected = [(raw, count if counter is not None else None) for raw, count in distances]
    what = "(value, counter)" if counter is not None else "distance (no counter)"
    check(streamed == expected, f"{capture}: {len(cycles)} {what} ILD cycles differ from the {len(distances)} Distance frames on vcan0")
    print(f"vcan_loop_check: sensor: the {len(cycles)} {what} cycles of the ILD stream equal the Distance frames on vcan0")


def differences(a, b, path=()):
    """JSON paths (tuples) where a and b differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b)):
            yield from differences(a.get(key), b.get(key), path + (key,))
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            yield from differences(x, y, path + (i,))
    elif a != b or type(a) is not type(b):
        yield path


def within(path, allowed):
    """Whether a JSON path lies under an allowed prefix ("*" matches any key or index)."""
    return len(path) >= len(allowed) and all(a in ("*", p) for p, a in zip(path, allowed))


def check_run(name, report):
    summary = report["emulator"]["summary"] if report.get("emulator") else None
    check(report["outcome"].get("complete") is True, f"{name}: the scan did not complete: {report['outcome']}")
    check(report["periods"]["done"] == report["periods"]["planned"], f"{name}: {report['periods']}")
    mirror = report["links"]["mirror"]
    check(mirror["angle_sequence_gaps"] == 0 and mirror["malformed_frames"] == 0 and mirror["foreign_frames"] == 0,
          f"{name}: the controller saw gaps, malformed or foreign frames: {mirror}")
    emulator = report.get("emulator") or {}
    check(emulator.get("exit_status") == 0 and emulator.get("killed") is False and summary is not None,
          f"{name}: the emulator did not finish by itself: exit {emulator.get('exit_status')}, "
          f"killed {emulator.get('killed')}")
    return summary or {"sensor": {"samples": -1}}


def main():
    if len(sys.argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    out, dbc, scanhil = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
    db = cantools.database.load_file(dbc)
    reports = {name: json.loads((out / name / "report.json").read_text()) for name in ["vcan", "pty-can", "pty-ild"]}
    summaries = {name: check_run(name, report) for name, report in reports.items()}

    distances = check_capture(out, db, reports["vcan"], summaries["vcan"])
    output_values = (reports["pty-ild"].get("sensor_setup") or {}).get("output_values") or []
    check_ild_stream(scanhil, out / "pty-ild" / "sensor.ild", distances, output_values)

    check((out / "vcan" / "fsm.log").read_bytes() == (out / "pty-can" / "fsm.log").read_bytes(),
          "fsm.log differs between socketcan:vcan0 and the pty link")
    for other, allowed in TRANSPORT_FIELDS.items():
        for file in BYTE_IDENTICAL:
            first = (out / "vcan" / file).read_bytes()
            check(len(first) > 0, f"vcan/{file} is empty")
            check(first == (out / other / file).read_bytes(), f"{file} differs between vcan and {other}")
        found = list(differences(reports["vcan"], reports[other]))
        unexpected = [p for p in found if not any(within(p, a) for a in allowed)]
        check(not unexpected, f"report.json: vcan and {other} differ at {['/'.join(map(str, p)) for p in unexpected]}")
        print(f"vcan_loop_check: vcan vs {other}: {', '.join(BYTE_IDENTICAL)} identical; report.json identical "
              f"but for {sorted({'/'.join(map(str, p)) for p in found})}")
    report = reports["vcan"]
    imaging = report.get("imaging") or {}
    feature = imaging.get("feature") or {}
    print(f"vcan_loop_check: result: {imaging.get('points')} points, feature height "
          f"{feature.get('height_mm')} mm (std {feature.get('std_mm')} mm), "
          f"tracking rms alpha {report['tracking_error']['frame']['alpha']['rms_urad']:.2f} urad")
    return TALLY.finish("vcan_loop_check")


if __name__ == "__main__":
    sys.exit(main())
