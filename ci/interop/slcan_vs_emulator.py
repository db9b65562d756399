#!/usr/bin/env python3
"""python-can's slcan interface as an independent client of the emulated mirror node.

Starts `scanhil-emulator serve --fsm slcan:pty` (the emulator creates a pty pair and prints its
path), opens that path with python-can's `slcan` interface, and runs lockstep periods: each
period it sends a CoilCommand and a Step encoded with cantools from protocol/scanhil.dbc,
and waits for the AngleReading, which it decodes with the same DBC. Checks: every answer
arrives, the sequence counters follow the steps without a gap, the angles are finite and in
range, the mirror moves under a constant coil current, a Status frame arrives, and the
emulator ends its run cleanly when the client closes the line.

Usage: slcan_vs_emulator.py EMULATOR_BINARY SCENE_FILE DBC_FILE [PERIODS]
Exit status 0 when every check passed.
"""

import json
import math
import subprocess
import sys

import can
import cantools

FULL_RANGE_RAD = math.radians(1.5)


def fail(message):
    print(f"slcan_vs_emulator: FAIL: {message}", file=sys.stderr)
    sys.exit(1)


def main():
    if len(sys.argv) < 4:
        fail(__doc__)
    emulator, scene, dbc_path = sys.argv[1:4]
    periods = int(sys.argv[4]) if len(sys.argv) > 4 else 400
    db = cantools.database.load_file(dbc_path)
    coil = db.get_message_by_name("CoilCommand")
    step = db.get_message_by_name("Step")
    angle = db.get_message_by_name("AngleReading")
    status_fsm = db.get_message_by_name("StatusFsm")

    proc = subprocess.Popen(
        [emulator, "serve", "--scene", scene, "--fsm", "slcan:pty",
         "--lockstep-answer-allowance-s", "0.5"],
        stdout=subprocess.PIPE, text=True)
    ready = json.loads(proc.stdout.readline())
    if ready.get("event") != "ready":
        fail(f"emulator did not say ready: {ready}")
    path = ready["fsm"].split(":", 1)[1]
    print(f"emulator serving the mirror node on {path}")

    bus = can.Bus(interface="slcan", channel=path, bitrate=1_000_000)
    seqs, statuses, alphas = [], 0, []
    try:
        for k in range(periods):
            data = coil.encode({"Seq": k % 65536, "CurrentA": 0.2, "CurrentB": 0.2})
            bus.send(can.Message(arbitration_id=coil.frame_id, data=data, is_extended_id=False))
            bus.send(can.Message(arbitration_id=step.frame_id,
                                 data=step.encode({"Step": k}), is_extended_id=False))
            while True:
                msg = bus.recv(timeout=5.0)
                if msg is None:
                    fail(f"no AngleReading for period {k}")
                if msg.arbitration_id == status_fsm.frame_id:
                    statuses += 1
                    continue
                if msg.arbitration_id != angle.frame_id:
                    continue
                decoded = angle.decode(msg.data)
                seqs.append(int(decoded["Seq"]))
                for axis in ("Alpha", "Beta"):
                    value = float(decoded[axis])
                    if not math.isfinite(value) or abs(value) > 1.2 * FULL_RANGE_RAD:
                        fail(f"period {k}: {axis} = {value} rad out of range")
                alphas.append(float(decoded["Alpha"]))
                break
    finally:
        bus.shutdown()
    try:
        lines = proc.communicate(timeout=10)[0].splitlines()
    except subprocess.TimeoutExpired:
        proc.kill()
        fail("the emulator did not end its run after the client closed the line")
    summary = json.loads(lines[-1]) if lines else {}
    if proc.returncode != 0 or summary.get("event") != "summary":
        fail(f"emulator exit {proc.returncode}, last line {lines[-1:] if lines else None}")
    if seqs != [k % 65536 for k in range(periods)]:
        fail(f"sequence counters not gapless: first {seqs[:5]} ... last {seqs[-5:]}")
    if statuses == 0:
        fail("no StatusFsm frame")
    if max(abs(a) for a in alphas) <= 1e-6:
        fail("the mirror did not move under a constant coil current")
    if summary["node"]["commands"] != periods:
        fail(f"emulator counted {summary['node']['commands']} commands, sent {periods}")
    print(f"OK: {periods} lockstep periods over python-can slcan, counters gapless, "
          f"{statuses} status frames, alpha reached {max(alphas) * 1e3:.3f} mrad")


if __name__ == "__main__":
    main()
