#!/usr/bin/env python3
"""Independent check of a run's VTK output with meshio (PyPI), the reader many of our users
script their post-processing with.

Usage: check_vtk.py DIR [--min-files N] [--require FIELD ...]

Walks DIR recursively and opens every .vtu and .vtk file with meshio. For each it checks:
  - the file parses and has at least one point and one cell;
  - every point or cell array has one entry per point / cell and only finite values;
  - with --require FIELD, every file of a series that should carry FIELD has it as a point or
    cell array (a name is matched exactly, or as a prefix followed by "_", e.g. alpha_air).
It also checks that every ParaView series index (.pvd) in DIR names files that exist.
Prints one line per file and exits non-zero on any problem, or when fewer than --min-files
files were found.
Install the reader once: python3 -m pip install meshio
"""
import argparse
import math
import os
import re
import sys

try:
    import meshio
except ImportError:  # pragma: no cover
    sys.exit("check_vtk: the 'meshio' package is missing: python3 -m pip install meshio")


def finite(values):
    flat = values.reshape(-1)
    return all(math.isfinite(float(x)) for x in flat)


def has(names, want):
    return any(n == want or n.startswith(want + "_") for n in names)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--min-files", type=int, default=1)
    ap.add_argument("--require", action="append", default=[])
    a = ap.parse_args()
    problems = []
    found = 0
    for root, _, files in sorted(os.walk(a.dir)):
        for name in sorted(files):
            path = os.path.join(root, name)
            if name.endswith(".pvd"):
                text = open(path, encoding="utf-8").read()
                for f in re.findall(r'file="([^"]+)"', text):
                    if not os.path.isfile(os.path.join(root, f)):
                        problems.append(f"{path}: names missing file {f}")
                continue
            if not (name.endswith(".vtu") or name.endswith(".vtk")):
                continue
            found += 1
            try:
                m = meshio.read(path)
            except Exception as e:  # noqa: BLE001 - report every reader failure
                problems.append(f"{path}: meshio cannot read it: {e}")
                continue
            npts = len(m.points)
            ncells = sum(len(c.data) for c in m.cells)
            names = list(m.point_data) + list(m.cell_data)
            print(f"{path}: {npts} points, {ncells} cells, arrays {', '.join(sorted(names))}")
            if npts == 0 or ncells == 0:
                problems.append(f"{path}: empty mesh")
            if not finite(m.points):
                problems.append(f"{path}: non-finite coordinates")
            for k, v in m.point_data.items():
                if len(v) != npts:
                    problems.append(f"{path}: point array {k} has {len(v)} entries, {npts} points")
                elif not finite(v):
                    problems.append(f"{path}: point array {k} has non-finite values")
            for k, blocks in m.cell_data.items():
                n = sum(len(b) for b in blocks)
                if n != ncells:
                    problems.append(f"{path}: cell array {k} has {n} entries, {ncells} cells")
                elif not all(finite(b) for b in blocks):
                    problems.append(f"{path}: cell array {k} has non-finite values")
            for want in a.require:
                if not has(names, want):
                    problems.append(f"{path}: no array '{want}'")
    if found < a.min_files:
        problems.append(f"{found} VTK files found in {a.dir}, expected at least {a.min_files}")
    for p in problems:
        print("PROBLEM:", p, file=sys.stderr)
    print(f"check_vtk: {found} files, {len(problems)} problems")
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
