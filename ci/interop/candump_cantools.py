#!/usr/bin/env python3
"""cantools as an independent decoder of the project's candump logs.

Reads a candump -L log written by the project (protocol/examples/write-candump.rs) with two
independent readers: cantools' log parser (the one `python3 -m cantools decode` uses) and
python-can's CanutilsLogReader. cantools decodes every frame with protocol/scanhil.dbc; the
physical values must equal what `scanhil decode --format candump` prints for the same log,
within one count of each signal's scale. Frame counts, ids, message names, timestamps and
the raw bytes (python-can) must agree too.

Usage: candump_cantools.py SCANHIL_BINARY LOG DBC
Prints one line per check and `interop: N passed, M failed`; exit status 1 on any failure.
"""

import json
import subprocess
import sys

import can
import cantools
from cantools.logreader import Parser

from tally import Tally

TALLY = Tally("candump_cantools")
check = TALLY.check


def main():
    if len(sys.argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    scanhil, log, dbc_path = sys.argv[1:4]
    db = cantools.database.load_file(dbc_path)

    result = subprocess.run(
        [scanhil, "decode", log, "--format", "candump"],
        capture_output=True, text=True, check=False,
    )
    check(result.returncode == 0, f"scanhil decode exit {result.returncode}: {result.stderr}")
    ours = [json.loads(line) for line in result.stdout.splitlines()]

    with open(log, encoding="ascii") as f:
        entries = [e for e in Parser(f) if e is not None]
    check(len(entries) == len(ours), f"cantools read {len(entries)} frames, scanhil {len(ours)}")

    fd_seen = 0
    for i, (entry, mine) in enumerate(zip(entries, ours)):
        at = f"frame {i} (id {entry.frame_id:#x})"
        message = db.get_message_by_frame_id(entry.frame_id)
        check(message.name == mine["message"], f"{at}: cantools {message.name}, scanhil {mine['message']}")
        check(entry.frame_id == mine["id"], f"{at}: id {mine['id']}")
        fd_seen += message.is_fd
        decoded = message.decode(bytes(entry.data), decode_choices=False, scaling=True)
        check(set(decoded) == set(mine["signals"]), f"{at}: signal names {sorted(decoded)} vs {sorted(mine['signals'])}")
        for signal in message.signals:
            theirs = decoded.get(signal.name)
            value = mine["signals"].get(signal.name)
            if theirs is None or value is None:
                continue
            check(abs(theirs - value) <= abs(signal.scale), f"{at}: {signal.name} cantools {theirs} scanhil {value}")
        stamp = entry.timestamp.timestamp() if hasattr(entry.timestamp, "timestamp") else entry.timestamp
        check(abs(stamp - mine["t"]) < 1e-5, f"{at}: t cantools {stamp} scanhil {mine['t']}")
    check(fd_seen > 0, "the log exercised no CAN FD message")

    python_can = list(can.CanutilsLogReader(log))
    check(len(python_can) == len(entries), f"python-can read {len(python_can)} frames, cantools {len(entries)}")
    for i, (msg, entry) in enumerate(zip(python_can, entries)):
        check(msg.arbitration_id == entry.frame_id and bytes(msg.data) == bytes(entry.data),
              f"frame {i}: python-can {msg.arbitration_id:#x} {bytes(msg.data).hex()} vs cantools {bytes(entry.data).hex()}")
        message = db.get_message_by_frame_id(msg.arbitration_id)
        check(msg.is_fd == message.is_fd, f"frame {i}: python-can is_fd {msg.is_fd}, DBC {message.is_fd}")

    print(f"candump_cantools: {len(ours)} frames compared ({fd_seen} CAN FD)")
    return TALLY.finish()


if __name__ == "__main__":
    sys.exit(main())
