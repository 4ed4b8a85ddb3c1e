#!/usr/bin/env python3
"""Window round trip through a participant library against the Rust node (issue 17, must-show 7).

Runs `cosim run` on a two-node case whose coupling moves `--bytes` each way per window: the
driver is always the Rust `echo` node (target/release/cosim-echo-node); the responder is, in
turn, the same node in Rust, in Python (tools/echo_node.py, package `cosim`) and, when built,
in C (tools/echo_node.c on the C participant library). The time of one window is the
wall-clock spacing of consecutive `/cosim/balance` records in the recording (the coordinator
writes one when every node has reported the window done): Advance out, the driver's velocity
to the responder, its force back, both Done in. Prints the median, p10 and p90 per responder
over `--windows` windows (the first 10 % left out as warm-up), best of `--repeat` runs
(alternating), and the ratio to the Rust responder.

Needs: cargo build --release --workspace; python3 -m pip install ./python mcap.
Usage: tools/bench_participant.py [--windows 20000] [--bytes 1024] [--repeat 3] [--transport shm]
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile

from mcap.reader import make_reader

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RELEASE = os.path.join(ROOT, "target", "release")

CASE = """
[run]
name = "bench-participant"
end_time = {end}
window = 1e-3
transport = "{transport}"
output = "out"

[nodes.a]
solver = "{rust}"
model = "echo"
[nodes.a.params]
points = {points}

[nodes.b]
solver = "{responder}"
model = "echo"
[nodes.b.params]
points = {points}

[[couplings]]
name = "echo"
kind = "kinematic"
driver = "a.port"
responder = "b.port"
driver_fields = ["velocity"]
responder_fields = ["force"]
"""


def window_times(mcap_path):
    """Wall-clock seconds between consecutive window records."""
    times = []
    with open(mcap_path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=["/cosim/balance"]):
            times.append(message.log_time)
    return [(b - a) * 1e-9 for a, b in zip(times, times[1:])]


def run_once(name, responder, args, tmp):
    case = os.path.join(tmp, f"{name}.toml")
    with open(case, "w") as f:
        f.write(CASE.format(end=args.windows * 1e-3, transport=args.transport,
                            rust=os.path.join(RELEASE, "cosim-echo-node"),
                            responder=responder, points=args.bytes // 8))
    out = os.path.join(tmp, f"out-{name}")
    subprocess.run([os.path.join(RELEASE, "cosim"), "run", case, "--output", out, "--quiet"],
                   check=True, stdout=subprocess.DEVNULL, env=dict(os.environ, COSIM_LOG="warn"))
    dts = window_times(os.path.join(out, "run.mcap"))
    if len(dts) != args.windows - 1:
        sys.exit(f"{name}: {len(dts) + 1} windows recorded, expected {args.windows}")
    dts = sorted(dts[len(dts) // 10:])
    q = statistics.quantiles(dts, n=10)
    return statistics.median(dts) * 1e6, q[0] * 1e6, q[-1] * 1e6, len(dts)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--windows", type=int, default=20000)
    ap.add_argument("--bytes", type=int, default=1024)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--transport", default="shm")
    args = ap.parse_args()
    responders = [("rust", os.path.join(RELEASE, "cosim-echo-node")),
                  ("python", os.path.join(ROOT, "tools", "echo_node.py"))]
    c_echo = os.path.join(ROOT, "tools", "echo-node-c")
    if os.path.isfile(c_echo):
        responders.append(("c", c_echo))
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeat):
            for name, exe in responders:
                res = run_once(f"{name}{r}", exe, args, tmp)
                if name not in best or res[0] < best[name][0]:
                    best[name] = res
    base = best["rust"][0]
    print(f"window round trip, {args.bytes} B each way, {args.transport}, "
          f"best of {args.repeat} runs of {args.windows} windows")
    print("| responder | median µs | p10 µs | p90 µs | windows | ratio to Rust |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, _ in responders:
        med, p10, p90, n = best[name]
        print(f"| {name} | {med:.1f} | {p10:.1f} | {p90:.1f} | {n} | {med / base:.2f} |")


if __name__ == "__main__":
    main()
