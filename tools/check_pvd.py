#!/usr/bin/env python3
"""Independent check of a run's ParaView time series with meshio (PyPI) and Python's own XML
parser: what a user opening each node's .pvd sees.

Usage: check_pvd.py DIR [--series N] [--zero-at-t0 FIELD ...]

For every .pvd under DIR (recursively) it checks that:
  - the first frame is at time 0 (the state after set-up);
  - every frame is listed once, with strictly increasing times;
  - meshio opens every listed file, with at least one point, and the same number of points
    in every frame of the series;
  - with --zero-at-t0 FIELD, the first frame's point array FIELD (where the series has it) is
    zero everywhere (e.g. the displacement of a solid at rest).
With --series N it also requires exactly N series. Prints one line per series (its name,
frames, points, first and last time) and exits non-zero on any problem.
Install the reader once: python3 -m pip install meshio
"""
import argparse
import os
import sys
import xml.etree.ElementTree as ET

try:
    import meshio
except ImportError:  # pragma: no cover
    sys.exit("check_pvd: the 'meshio' package is missing: python3 -m pip install meshio")


def check(path, zero_fields):
    problems = []
    entries = [(float(d.get("timestep")), d.get("file"))
               for d in ET.parse(path).getroot().iter("DataSet")]
    if not entries:
        return ["no frame"], 0, 0
    if entries[0][0] != 0.0:
        problems.append(f"first frame at t = {entries[0][0]}, not 0")
    files = [f for _, f in entries]
    if len(set(files)) != len(files):
        problems.append("a frame listed twice: " + ", ".join(sorted({f for f in files if files.count(f) > 1})))
    times = [t for t, _ in entries]
    if any(b <= a for a, b in zip(times, times[1:])):
        problems.append(f"times not increasing: {times}")
    points = None
    base = os.path.dirname(path)
    for i, (t, f) in enumerate(entries):
        try:
            m = meshio.read(os.path.join(base, f))
        except Exception as e:  # the reader's own errors, reported as one line
            problems.append(f"{f}: {type(e).__name__}: {e}")
            continue
        n = len(m.points)
        if n == 0:
            problems.append(f"{f}: no point")
        if points is None:
            points = n
        elif n != points:
            problems.append(f"{f}: {n} points, the series' first frame {points}")
        if i == 0:
            for name in zero_fields:
                if name in m.point_data and abs(m.point_data[name]).max() != 0.0:
                    problems.append(f"{f}: {name} not zero at t = 0")
    return problems, len(entries), points or 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--series", type=int)
    ap.add_argument("--zero-at-t0", action="append", default=[])
    a = ap.parse_args()
    found = 0
    failed = False
    for root, _, files in sorted(os.walk(a.dir)):
        for name in sorted(files):
            if not name.endswith(".pvd"):
                continue
            found += 1
            path = os.path.join(root, name)
            problems, frames, points = check(path, a.zero_at_t0)
            rel = os.path.relpath(path, a.dir)
            print(f"{rel}: {frames} frames, {points} points" + ("" if not problems else ": " + "; ".join(problems)))
            failed |= bool(problems)
    if a.series is not None and found != a.series:
        print(f"check_pvd: {found} series, expected {a.series}")
        failed = True
    print("check_pvd: FAIL" if failed else f"check_pvd: {found} series OK")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
