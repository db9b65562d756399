#!/usr/bin/env python3
"""python-can's slcan interface, opened on a real pty, against the project's SLCAN codec.

Starts the project's pty peer (protocol/examples/slcan-pty-peer.rs), opens the pty it
prints with `can.Bus(interface="slcan")`, then
  1. receives the frames the peer wrote with the project's SLCAN encoder and checks each one
     against the frame this script defined (id, id width, remote, DLC, data, FD, BRS);
  2. sends the same frames with python-can; the peer decodes them with the project's SLCAN
     decoder and prints them as candump lines, which this script parses and compares;
  3. feeds those lines to `scanhil decode --format candump` and checks the CoilCommand that
     cantools encoded from protocol/scanhil.dbc comes back with the same physical values.

Usage: slcan_python_can.py PEER_BINARY SCANHIL_BINARY DBC
Prints `interop: N passed, M failed`; exit status 1 on any failure.
"""

import json
import os
import subprocess
import sys
import tempfile

import can
import cantools

from tally import Tally

TALLY = Tally("slcan_python_can")
check = TALLY.check


def frames(db):
    coil = db.get_message_by_name("CoilCommand")
    coil_signals = {"Seq": 513, "CurrentA": 1.5, "CurrentB": -3.856}
    fd = db.get_message_by_name("AnglesDistanceFd")
    fd_signals = {"Seq": 7, "Alpha": -0.01, "Beta": 0.02, "IldRaw": 32760,
                  "IldCounter": 262143, "SensorTime": 16777215, "Status": 0}
    return coil_signals, [
        can.Message(arbitration_id=0x123, is_extended_id=False,
                    data=bytes.fromhex("DEADBEEF01020304")),
        can.Message(arbitration_id=0x7FF, is_extended_id=False, data=b""),
        can.Message(arbitration_id=0x1ABCDEF0, is_extended_id=True, data=bytes([1, 2, 3])),
        can.Message(arbitration_id=0x321, is_extended_id=False, is_remote_frame=True, dlc=5),
        can.Message(arbitration_id=0x1FFFFFFF, is_extended_id=True, is_remote_frame=True, dlc=0),
        can.Message(arbitration_id=coil.frame_id, is_extended_id=False,
                    data=coil.encode(coil_signals)),
        can.Message(arbitration_id=fd.frame_id, is_extended_id=False, is_fd=True,
                    bitrate_switch=True, data=fd.encode(fd_signals)),
        can.Message(arbitration_id=0x10, is_extended_id=True, is_fd=True,
                    bitrate_switch=False, data=bytes(range(64))),
    ]


def candump_line(msg):
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    if msg.is_remote_frame:
        frame = f"{ident}#R" + (str(msg.dlc) if msg.dlc else "")
    elif msg.is_fd:
        frame = f"{ident}##{1 if msg.bitrate_switch else 0}{bytes(msg.data).hex().upper()}"
    else:
        frame = f"{ident}#{bytes(msg.data).hex().upper()}"
    return f"(0.000000) slcan0 {frame}"


def same(a, b, at):
    fields = ["arbitration_id", "is_extended_id", "is_remote_frame", "dlc", "is_fd", "bitrate_switch"]
    for field in fields:
        check(getattr(a, field) == getattr(b, field),
              f"{at}: {field} {getattr(a, field)!r} != {getattr(b, field)!r}")
    if not a.is_remote_frame:
        check(bytes(a.data) == bytes(b.data), f"{at}: data {bytes(a.data).hex()} != {bytes(b.data).hex()}")


def main():
    if len(sys.argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    peer_binary, scanhil, dbc_path = sys.argv[1:4]
    db = cantools.database.load_file(dbc_path)
    coil_signals, wanted = frames(db)
    tmp = tempfile.mkdtemp(prefix="slcan-interop-")
    frames_file = os.path.join(tmp, "frames.log")
    with open(frames_file, "w", encoding="ascii") as f:
        f.write("".join(candump_line(m) + "\n" for m in wanted))

    peer = subprocess.Popen([peer_binary, frames_file, str(len(wanted))],
                            stdout=subprocess.PIPE, text=True)
    first = peer.stdout.readline().split()
    if len(first) != 2 or first[0] != "PTY":
        print(f"slcan_python_can: FAIL: peer said {first!r}", file=sys.stderr)
        peer.kill()
        return 1
    bus = can.Bus(interface="slcan", channel=first[1], bitrate=1_000_000, sleep_after_open=0)
    try:
        # 1. project encoder -> python-can
        for i, want in enumerate(wanted):
            got = bus.recv(timeout=5.0)
            if not check(got is not None, f"frame {i}: nothing received from the peer"):
                break
            same(got, want, f"peer->python-can frame {i}")
        # 2. python-can -> project decoder
        for msg in wanted:
            bus.send(msg)
        lines = []
        for line in peer.stdout:
            line = line.strip()
            if line == "DONE":
                break
            check(not line.startswith("MALFORMED"), f"peer: {line}")
            if line.startswith("RECV "):
                lines.append(line[5:])
    finally:
        bus.shutdown()
    check(peer.wait(timeout=10) == 0, f"peer exit status {peer.returncode}")
    expected_lines = [candump_line(m) for m in wanted]
    check(len(lines) == len(expected_lines), f"peer decoded {len(lines)} frames, sent {len(expected_lines)}")
    for i, (got, want) in enumerate(zip(lines, expected_lines)):
        check(got == want, f"python-can->peer frame {i}: peer read {got!r}, python-can sent {want!r}")

    # 3. the peer's log through scanhil decode: physical values as cantools encoded them
    log = os.path.join(tmp, "received.log")
    with open(log, "w", encoding="ascii") as f:
        f.write("".join(line + "\n" for line in lines))
    result = subprocess.run([scanhil, "decode", log, "--format", "candump"],
                            capture_output=True, text=True, check=False)
    check(result.returncode == 0, f"scanhil decode exit {result.returncode}: {result.stderr}")
    decoded = [json.loads(l) for l in result.stdout.splitlines()]
    coils = [d for d in decoded if d["message"] == "CoilCommand"]
    if check(len(coils) == 1, f"{len(coils)} CoilCommand frames decoded"):
        coil = db.get_message_by_name("CoilCommand")
        for name, value in coil_signals.items():
            scale = coil.get_signal_by_name(name).scale
            check(abs(coils[0]["signals"][name] - value) <= scale,
                  f"CoilCommand.{name}: scanhil {coils[0]['signals'][name]} cantools input {value}")
    check(any(d["message"] == "AnglesDistanceFd" for d in decoded), "AnglesDistanceFd not decoded")

    print(f"slcan_python_can: {len(wanted)} frames each way over {first[1]}")
    return TALLY.finish()


if __name__ == "__main__":
    sys.exit(main())
