#!/usr/bin/env python3
"""A/B of `cosim-bench --only window,transport` between two builds, in alternating pairs.

usage: ab_window.py OLD_BENCH NEW_BENCH PAIRS OUTDIR

Each pair runs both binaries back to back (which goes first alternates), so a drift of the
machine's speed shifts both alike. Per row: the median over the runs of each build, the
median of the pairs' ratios new/old with its 95 % bootstrap interval, and how many pairs
had the new build slower. A row is slower only where the whole interval lies above 1.
The runs' rows are kept in OUTDIR/runs.json.
"""
import json, os, random, subprocess, sys, statistics

old, new, pairs, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
os.makedirs(out, exist_ok=True)


def rows(path):
    d = json.load(open(path))
    r = {}
    for x in d.get("results", []):
        if x.get("kernel") == "transport":
            r[f"transport {x['device']} {x['size']} B"] = x["median_step_s"] * 1e6
    for w in d.get("windows", []):
        if w["case"] == "participant":
            r[f"participant {w['node']}"] = w["median_us"]
        else:
            r[f"split bar {w['transport']} x{w.get('windows_ahead') or 'auto'}"] = w["median_us"]
    return r


runs = {"old": [], "new": []}
for k in range(pairs):
    order = [("old", old), ("new", new)] if k % 2 == 0 else [("new", new), ("old", old)]
    for tag, exe in order:
        o = f"{out}/{tag}{k}"
        p = subprocess.run([exe, "--only", "window,transport", "--no-gpu", "-o", o],
                           capture_output=True, text=True)
        if p.returncode != 0:
            print(f"{tag} pair {k}: exit {p.returncode}\n{p.stderr[-2000:]}", flush=True)
            sys.exit(1)
        runs[tag].append(rows(f"{o}/bench.json"))
    print(f"pair {k + 1}/{pairs} done", flush=True)

keys = [k for k in runs["new"][0] if all(k in r for r in runs["old"] + runs["new"])]
random.seed(1)
print(f"\n{pairs} pairs, medians in µs\n")
print("| row | old | new | new/old (median of pairs) | 95 % bootstrap interval | pairs new slower |")
print("|---|---:|---:|---:|---|---:|")
for key in keys:
    a = [r[key] for r in runs["old"]]
    b = [r[key] for r in runs["new"]]
    ratios = [y / x for x, y in zip(a, b)]
    boot = sorted(statistics.median(random.choices(ratios, k=len(ratios))) for _ in range(4000))
    print(f"| {key} | {statistics.median(a):.1f} | {statistics.median(b):.1f} | "
          f"{statistics.median(ratios):.3f} | {boot[100]:.3f}–{boot[3899]:.3f} | "
          f"{sum(r > 1 for r in ratios)}/{len(ratios)} |")
json.dump(runs, open(f"{out}/runs.json", "w"))
