#!/usr/bin/env python3
"""Decode cosim protocol messages from PROTOCOL.md alone (Python 3 standard library only).

Usage: wire_decode.py FILE.bin...        print each envelope as JSON
       wire_decode.py --check DIR        decode every DIR/*.bin and compare it with the
                                         DIR/*.json beside it; exit 1 on any difference

This is an independent reading of the written contract, not a port of the Rust code: the
message layouts below are transcribed from PROTOCOL.md ("Messages"), and the primitive
rules (header, varints, strings, sequences, Option, enum tags, f64, the f64 byte string)
from its section "Bytes". The JSON it prints has the shape of the golden vectors' JSON:
structs as objects, enums as {"Variant": {...}} (unit variants as "Variant"), tuples and
fixed arrays as lists, Field values as a list of numbers.
"""
import json
import math
import struct
import sys
from pathlib import Path

MAGIC = b"CSIM"
VERSION = 4
HEADER_LEN = 20
MAX_BODY = 1 << 30


class WireError(Exception):
    pass


class Reader:
    def __init__(self, data: bytes):
        self.data = data
        self.pos = 0

    def take(self, n: int) -> bytes:
        if n < 0 or self.pos + n > len(self.data):
            raise WireError(f"needs {n} bytes at offset {self.pos}, {len(self.data) - self.pos} left")
        b = self.data[self.pos:self.pos + n]
        self.pos += n
        return b

    def varint(self, bits: int) -> int:
        """Unsigned varint: < 251 is the value; 251/252/253/254 announce u16/u32/u64/u128 LE."""
        first = self.take(1)[0]
        if first < 251:
            return first
        width = {251: 16, 252: 32, 253: 64, 254: 128}.get(first)
        if width is None:
            raise WireError(f"varint marker {first} is reserved")
        if width > bits:
            raise WireError(f"varint of {width} bits where a u{bits} is expected")
        return int.from_bytes(self.take(width // 8), "little")

    def f64(self) -> float:
        return struct.unpack("<d", self.take(8))[0]


# The message types of PROTOCOL.md, field by field, in wire order.
#   "u16" "u32" "u64"  varint        "bool"  one byte, 0 or 1     "f64"  8 bytes LE
#   "str"              varint length + UTF-8
#   ("vec", T)         varint count + elements      ("opt", T)  byte 0 | byte 1 + value
#   ("arr", T, n)      n elements, no count         ("tuple", T, U)  elements, no count
#   ("enum", name)     varint variant index         "f64bytes"  varint byte count + LE f64s
#   any other string   a struct below
STRUCTS = {
    "Binding": [("coupling", "str"), ("kind", ("enum", "CouplingKind")), ("interface", "str"),
                ("role", ("enum", "Role")), ("peer", "str"), ("peer_interface", "str"),
                ("sends", ("vec", "str")), ("receives", ("vec", "str")), ("input_lag", "u64")],
    "Hello": [("protocol_version", "u16"), ("node", "str"), ("model", "str"), ("pid", "u32"),
              ("capabilities", ("vec", "str")), ("token", "str")],
    "Welcome": [("run", "str"), ("model", "str"), ("params_toml", "str"),
                ("bindings", ("vec", "Binding")), ("output_dir", "str"), ("heartbeat_ms", "u64")],
    "Reject": [("reason", "str")],
    "InterfaceDescription": [("name", "str"), ("points", "u64"), ("provides", ("vec", "str")),
                             ("accepts", ("vec", "str"))],
    "Describe": [("model", "str"), ("interfaces", ("vec", "InterfaceDescription")),
                 ("stable_dt", "f64"), ("units", "str"), ("warnings", ("vec", "str"))],
    "Cells": [("kind", ("enum", "CellKind")), ("connectivity", ("vec", "u32"))],
    "InterfaceMesh": [("ids", ("vec", "u64")), ("positions", ("vec", ("arr", "f64", 3))),
                      ("cells", ("opt", "Cells")), ("normals", ("vec", ("arr", "f64", 3))),
                      ("weights", ("vec", "f64"))],
    "Mesh": [("coupling", "str"), ("interface", "str"), ("mesh", "InterfaceMesh")],
    "Advance": [("window", "u64"), ("t0", "f64"), ("t1", "f64"), ("write_output", "bool"),
                ("checkpoint", "bool")],
    "Field": [("name", "str"), ("components", "u32"), ("values", "f64bytes")],
    "Fields": [("coupling", "str"), ("window", "u64"), ("time", "f64"),
               ("fields", ("vec", "Field"))],
    "StepReport": [("kinetic_energy", "f64"), ("internal_energy", "f64"),
                   ("external_work", "f64"), ("interface_work", "f64"),
                   ("momentum", ("arr", "f64", 3)), ("momentum_gross", "f64"),
                   ("external_impulse", ("arr", "f64", 3)), ("applied_impulse", "f64"),
                   ("interface_impulse", ("arr", "f64", 3)), ("substeps", "u64"),
                   ("wall_s", "f64"), ("coupling_wait_s", "f64"), ("idle_s", "f64"),
                   ("scalars", ("vec", ("tuple", "str", "f64")))],
    "Done": [("window", "u64"), ("report", "StepReport")],
    "Heartbeat": [("window", "u64"), ("substeps", "u64"), ("waiting", "bool")],
    "Finish": [("reason", "str")],
    "Abort": [("reason", "str")],
    "Failed": [("reason", "str")],
    "Decouple": [("coupling", "str"), ("window", "u64"), ("reason", "str")],
}

# Enums: variant names in index order; a variant with data names its struct, else None.
# CouplingKind's variants are written in lower case in JSON (its serde rename).
ENUMS = {
    "Role": [("Driver", None), ("Responder", None)],
    "CouplingKind": [("kinematic", None), ("immersed", None), ("lagrange", None)],
    "CellKind": [("Line", None), ("Triangle", None), ("Quad", None)],
    # Message kind in the header = variant index + 1.
    "Message": [(n, n) for n in ["Hello", "Welcome", "Reject", "Describe", "Mesh", "Advance",
                                 "Fields", "Done", "Heartbeat", "Finish", "Abort", "Failed",
                                 "Decouple"]],
}


def read(r: Reader, t):
    if t in ("u16", "u32", "u64"):
        return r.varint(int(t[1:]))
    if t == "bool":
        b = r.take(1)[0]
        if b > 1:
            raise WireError(f"bool byte {b} at offset {r.pos - 1}")
        return b == 1
    if t == "f64":
        return r.f64()
    if t == "str":
        n = r.varint(64)
        try:
            return r.take(n).decode("utf-8")
        except UnicodeDecodeError as e:
            raise WireError(f"string is not UTF-8: {e}") from None
    if t == "f64bytes":
        n = r.varint(64)
        if n % 8:
            raise WireError(f"{n} bytes is not a whole number of f64 values")
        return list(struct.unpack(f"<{n // 8}d", r.take(n)))
    if isinstance(t, tuple):
        if t[0] == "vec":
            n = r.varint(64)
            if n > len(r.data) - r.pos:  # every element takes at least one byte
                raise WireError(f"sequence of {n} elements in {len(r.data) - r.pos} bytes")
            return [read(r, t[1]) for _ in range(n)]
        if t[0] == "arr":
            return [read(r, t[1]) for _ in range(t[2])]
        if t[0] == "tuple":
            return [read(r, x) for x in t[1:]]
        if t[0] == "opt":
            tag = r.take(1)[0]
            if tag > 1:
                raise WireError(f"Option tag {tag} at offset {r.pos - 1}")
            return read(r, t[1]) if tag == 1 else None
        if t[0] == "enum":
            variants = ENUMS[t[1]]
            i = r.varint(32)
            if i >= len(variants):
                raise WireError(f"{t[1]} has no variant {i}")
            name, payload = variants[i]
            return name if payload is None else {name: read(r, payload)}
    return {name: read(r, ft) for name, ft in STRUCTS[t]}


def decode(data: bytes) -> dict:
    """One envelope: checks the header as a receiver must, then decodes the body."""
    if len(data) < HEADER_LEN:
        raise WireError(f"{len(data)} bytes, the header alone is {HEADER_LEN}")
    magic, version, kind, _reserved, body_len, seq = struct.unpack("<4sHBBIQ", data[:HEADER_LEN])
    if magic != MAGIC:
        raise WireError(f"bad magic {magic!r}")
    if version != VERSION:
        raise WireError(f"protocol version {version}, this decoder reads {VERSION}")
    if body_len > MAX_BODY or body_len != len(data) - HEADER_LEN:
        raise WireError(f"header announces {body_len} body bytes, {len(data) - HEADER_LEN} follow")
    r = Reader(data[HEADER_LEN:])
    run = read(r, "str")
    sender = read(r, "str")
    message = read(r, ("enum", "Message"))
    if r.pos != len(r.data):
        raise WireError(f"{len(r.data) - r.pos} trailing bytes after the body")
    body_kind = [n for n, _ in ENUMS["Message"]].index(next(iter(message))) + 1
    if body_kind != kind:
        raise WireError(f"header says kind {kind}, body holds kind {body_kind}")
    return {"run": run, "sender": sender, "seq": seq, "message": message}


def same(a, b) -> bool:
    """Equal JSON values; numbers compare exactly (and -0.0 differs from 0.0)."""
    if isinstance(a, float) or isinstance(b, float):
        if isinstance(a, bool) or isinstance(b, bool):
            return False
        return (isinstance(a, (int, float)) and isinstance(b, (int, float)) and a == b
                and math.copysign(1.0, a) == math.copysign(1.0, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


def check(directory: Path) -> int:
    bins = sorted(directory.glob("*.bin"))
    bad = 0
    for p in bins:
        data = p.read_bytes()
        try:
            got = decode(data)
        except WireError as e:
            print(f"{p.name}: does not decode: {e}")
            bad += 1
            continue
        want = json.loads(p.with_suffix(".json").read_text(encoding="utf-8"))
        if not same(got, want):
            print(f"{p.name}: decodes to\n{json.dumps(got, indent=2)}\nbut the JSON beside it is\n"
                  f"{json.dumps(want, indent=2)}")
            bad += 1
            continue
        # A receiver must refuse every truncation of a valid message.
        for n in range(len(data)):
            try:
                decode(data[:n])
            except WireError:
                continue
            print(f"{p.name}: its first {n} bytes were accepted")
            bad += 1
            break
    print(f"{len(bins) - bad} of {len(bins)} vectors match")
    return 1 if bad or not bins else 0


def main() -> int:
    args = sys.argv[1:]
    if len(args) == 2 and args[0] == "--check":
        return check(Path(args[1]))
    if not args or args[0].startswith("-"):
        print(__doc__, file=sys.stderr)
        return 2
    for a in args:
        try:
            print(json.dumps(decode(Path(a).read_bytes()), indent=2, ensure_ascii=False))
        except (OSError, WireError) as e:
            print(f"{a}: {e}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
