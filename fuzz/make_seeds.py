#!/usr/bin/env python3
"""Writes the fuzz targets' seed inputs into fuzz/corpus/<target>/seed-*: small valid inputs
of each format, taken from the repository's fixtures or written here as the formats define
them; and AFL++'s dictionaries into fuzz/dictionaries/ (the JSON documents' keys and words,
the SLCAN, ILD and PLY keywords). The seeds and dictionaries are committed, so this runs only
when a format or a fixture changes. Inputs the fuzzers find are kept beside the seeds."""

import json
import pathlib
import struct
import zlib

ROOT = pathlib.Path(__file__).resolve().parent.parent
CORPUS = ROOT / "fuzz" / "corpus"
FIXTURES = ROOT / "fixtures"


def write(target, name, data):
    folder = CORPUS / target
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"seed-{name}").write_bytes(data if isinstance(data, bytes) else data.encode())


def ild_word(raw, first):
    raw &= (1 << 18) - 1
    return bytes([raw & 0x3F, 0x40 | ((raw >> 6) & 0x3F), 0x80 | (0 if first else 0x40) | ((raw >> 12) & 0x3F)])


def ild_cycles(cycles):
    return b"".join(ild_word(raw, i == 0) for cycle in cycles for i, raw in enumerate(cycle))


def png(width, height, depth, rows):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    raw = b"".join(b"\x00" + row for row in rows)
    header = struct.pack(">IIBBBBB", width, height, depth, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw))
            + chunk(b"IEND", b""))


def ply(encoding, points):
    names = ["x", "y", "z", "t_s", "d_alpha_rad", "d_beta_rad", "z_meas_mm"]
    header = f"ply\nformat {encoding} 1.0\ncomment scanhil point cloud\ncomment model exact_reflection\n"
    header += f"element vertex {len(points)}\n"
    header += "".join(f"property double {n}\n" for n in names) + "end_header\n"
    if encoding == "ascii":
        body = "".join(" ".join(repr(v) for v in p) + "\n" for p in points).encode()
    else:
        order = "<" if encoding == "binary_little_endian" else ">"
        body = b"".join(struct.pack(order + "7d", *p) for p in points)
    return header.encode() + body


def dictionary(name, tokens):
    folder = ROOT / "fuzz" / "dictionaries"
    folder.mkdir(parents=True, exist_ok=True)
    lines = []
    for index, token in enumerate(sorted(set(tokens))):
        text = "".join(c if c.isprintable() and c not in '"\\' else f"\\x{ord(c):02x}" for c in token)
        lines.append(f'token_{index}="{text}"')
    (folder / f"{name}.dict").write_text("\n".join(lines) + "\n")


def json_words(value, keys, words):
    if isinstance(value, dict):
        for key, item in value.items():
            keys.add(key)
            json_words(item, keys, words)
    elif isinstance(value, list):
        for item in value:
            json_words(item, keys, words)
    elif isinstance(value, str) and len(value) <= 40:
        words.add(value)


def dictionaries():
    keys, words = set(), set()
    for path in FIXTURES.glob("*/*.json"):
        json_words(json.loads(path.read_text()), keys, words)
    tokens = [f'"{key}":' for key in keys] + [f'"{word}"' for word in words]
    dictionary("json", tokens + ["true", "false", "null", "1e300", "-1", "NaN", "{}", "[]"])
    dictionary("slcan", ["\r", "\x07", "t", "T", "r", "R", "d", "D", "b", "B", "S8", "Y2", "O",
                         "L", "C", "V", "N", "z", "Z", "(", ")", "#", "##", "#R", " vcan0 ",
                         "1700000000.000000"])
    dictionary("ild", ["\r\n", "->", "GETINFO", "MEASRATE", "ECHO", "ON", "OFF", "OUTPUT",
                       "RS422", "NONE", "ANALOG", "OUTDIST_RS422", "DIST1", "OUTADD_RS422",
                       "COUNTER", "TIMESTAMP", "BAUDRATE", "691200", "LASERPOW", "FULL", "E04 ",
                       "W05 ", "Name: ", "Measuring range: ", "mm", "49.14", "2.5"])
    dictionary("ply", ["ply\n", "format ", "ascii", "binary_little_endian", "binary_big_endian",
                       " 1.0\n", "comment ", "model ", "exact_reflection", "small_angle",
                       "element ", "vertex", "face", "property ", "list ", "uchar", "int",
                       "float", "double", "end_header\n", "x", "y", "z", "t_s", "d_alpha_rad",
                       "d_beta_rad", "z_meas_mm"])


def main():
    dictionaries()
    slcan = {
        "frames": "t1238DEADBEEF01020304\rT1ABCDEF02AABB\rr7FF2\rR000000013\r",
        "fd": "d1409" + "11" * 12 + "\rB1ABCDEF0F" + "A5" * 64 + "\r",
        "commands": "C\rS8\rY2\rO\rL\rV\rN\r\r",
        "replies": "V1013\rNSHIL\rz\rZ\r\r\x07",
    }
    for name, text in slcan.items():
        write("slcan", name, text)

    golden = (FIXTURES / "recordings" / "lockstep-golden.log").read_text().splitlines()
    candump = "\n".join(golden[:12]) + "\n"
    candump_extra = ("(1600000000.123456789) can1 1ABCDEF0#00\n(0.000000) vcan0 123#R5\n"
                     "(1.500000) vcan0 140##30001020304050607\n")
    # A technician's own capture: candump -L -x -e -8 -d (direction, error frames, raw DLC, drops).
    technician = (FIXTURES / "recordings" / "candump-technician.log").read_text()
    write("candump", "golden", candump)
    write("candump", "kinds", candump_extra)
    write("candump", "technician", technician)

    stream = ild_cycles([[32760, 7], [32770, 8], [262076, 9], [600, 10]])
    write("ild_stream", "cycles", stream)
    write("ild_stream", "gap", stream[:4] + stream[5:])

    for index, line in enumerate(golden[:40:4]):
        _, _, frame = line.split()
        ident, _, rest = frame.partition("#")
        fd = rest.startswith("#")
        payload = bytes.fromhex(rest[2:] if fd else rest)
        flags = int(rest[1], 16) if fd else 0
        kind = (3 if flags & 1 else 2) if fd else 0
        write("can_messages", f"golden-{index}",
              bytes([kind << 1]) + struct.pack("<I", int(ident, 16)) + payload)

    write("ild_commands", "setup",
          "OUTPUT NONE\rECHO OFF\rGETINFO\rMEASRATE 20\rMEASRATE\rOUTDIST_RS422 DIST1\r"
          "OUTADD_RS422 COUNTER\rLASERPOW FULL\rBAUDRATE\rOUTPUT RS422\r")
    write("ild_commands", "echo", "ECHO ON\r\nMEASRATE 7\r\nFROB\r\nOUTADD_RS422 NONE\r\n")
    info = ("GETINFO\r\nName: ILD2300\r\nSerial: 1234\r\nArticle: 4120xxx\r\n"
            "Measuring range: 100.00mm\r\nVersion: 1.0\r\n->")
    write("ild_replies", "getinfo", b"\x01" + info.encode())
    write("ild_replies", "query", b"\x00MEASRATE 20\r\n->BAUDRATE 691200\r\n->")
    write("ild_replies", "refusal", b"\x01MEASRATE 7\r\nW05 Later\r\nE04 Wrong parameter\r\n->")

    write("decode", "candump", b"\x00" + candump.encode())
    # A recorded session for replay: its first periods, its ILD stream, its host's clock.
    session = FIXTURES / "recordings" / "replay-small"
    write("replay", "fsm-log", b"\x00" + "\n".join((session / "fsm.log").read_text().splitlines()[:40]).encode() + b"\n")
    write("replay", "sensor-ild", b"\x01" + (session / "sensor.ild").read_bytes()[:120])
    clock = json.loads((session / "report.json").read_text())["samples"]["sensor_clock"]
    write("replay", "report", b"\x02" + json.dumps({"samples": {"sensor_clock": clock}}).encode())
    write("decode", "technician", b"\x00" + technician.encode())
    write("decode", "slcan", b"\x01" + slcan["frames"].encode() + b"t0214E8030000\r")
    write("decode", "ild", b"\x02" + stream)

    points = [(0.5 * i, -0.25 * i, -120.0 + i, 5e-5 * i, 1e-3, -2e-3, 120.0 - i) for i in range(4)]
    for encoding in ["ascii", "binary_little_endian", "binary_big_endian"]:
        write("ply", encoding, ply(encoding, points))

    write("surfaces", "csv", b"\x00# heights, mm\n0,0.5,1,0.5\n0,1,2,1\n0,0.5,1,0.5\n")
    write("surfaces", "png8", b"\x01" + png(4, 3, 8, [bytes([0, 64, 128, 255])] * 3))
    write("surfaces", "png16",
          b"\x01" + png(3, 3, 16, [struct.pack(">3H", 0, 30000, 65535)] * 3))

    for path in sorted((FIXTURES / "scenarios").glob("*.json")):
        write("scenario", path.stem, path.read_bytes())
    for kind, folder in enumerate(["rigs", "controllers", "scenes", "studies"]):
        for path in sorted((FIXTURES / folder).glob("*.json")):
            write("documents", f"{folder}-{path.stem}", bytes([kind]) + path.read_bytes())
    for path in [FIXTURES / "scenes" / "duplo-2x4-130mm.json", FIXTURES / "scenes" / "sphere.json"]:
        write("documents", f"truth-{path.stem}", b"\x04" + path.read_bytes())


if __name__ == "__main__":
    main()
