#!/usr/bin/env python3
"""Run a fixed set of cases with one build of cosim and compare two such sets of outputs.

Usage: same_outputs.py run BIN_DIR OUT_DIR [CASE ...]   run the cases with BIN_DIR/cosim
       same_outputs.py diff OUT_A OUT_B                 compare two OUT_DIRs; exit 1 on any
                                                        difference
       same_outputs.py list                             the cases and how each is run

A refactoring that must not change results is checked by running the cases with the build
before it and the build after it, then `diff`. Every run gets the same run id and output
folder name, so topics and paths agree; the comparison then holds, per case:

  * the recording (`run.mcap`, read with the official `mcap` package): the same channels with
    the same number of messages; on every wire channel the same messages in the same order,
    decoded field by field (tools/wire_decode.py) and equal bit for bit; on every JSON channel
    the same documents; log times equal;
  * `summary.json`: equal, key by key.

What differs from one run to the next on the same build is left out ("timings aside"): wall
times, waits, idle and compute seconds and fractions, the window breakdown, process ids and
tokens, the recording's size in bytes, and heartbeats (how many a node sends depends on how
long it computes), and with them the envelopes' sequence numbers and the recording's message
count. A message a node sends is logged at the coordinator's time of arrival, which depends on
how far ahead the windows ran: its content is compared, its log time is not. The output
folder's path is written `<out>` in both.
Install the reader once: python3 -m pip install mcap
"""
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import wire_decode  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
EXTERNAL = EXAMPLES / "external"

# name: (case file, variant or None, extra --set values)
CASES = {
    "split_bar": ("split_bar.toml", None, []),
    "split_bar_chain": ("split_bar_chain.toml", None, []),
    "split_bar_lagrange": ("split_bar_lagrange.toml", None, []),
    "chamber_small": ("chamber_detonation.toml", "small", []),
    "crash_tube_small": ("crash_tube.toml", "small", []),
    "seed003_cantilever_small": ("seed003_cantilever.toml", "small", []),
    "seed003_cantilever_split_small": ("seed003_cantilever_split.toml", "small", []),
    "seed003_notch_small": ("seed003_notch.toml", "small", []),
    "seed003_three_small": ("seed003_three.toml", "small", []),
    "seed003_wave_small": ("seed003_wave.toml", "small", []),
    "seed003_wave_split_small": ("seed003_wave_split.toml", "small", []),
    "python_bar": ("split_bar.toml", None, [f"right.solver={EXTERNAL / 'bar.py'}"]),
    "c_bar": ("split_bar.toml", None, [f"right.solver={EXTERNAL / 'bar-c'}"]),
}

# Keys whose values are timings or identities of one process, at any depth.
TIMING = re.compile(
    r"(^|_)(wall|wait|idle|compute|stalls|pid|token|bytes|fraction|overhead|loop)(_|$)"
    r"|_us$|_s$|^window_breakdown$|^seq$"
)


def masked(value, out_dir: str):
    """`value` with timing keys dropped and the output folder written `<out>`."""
    if isinstance(value, dict) and "messages" in value and "segment" in value:
        # The recording's message count includes the heartbeats.
        value = {k: v for k, v in value.items() if k != "messages"}
    if isinstance(value, dict):
        return {k: masked(v, out_dir) for k, v in value.items() if not TIMING.search(k)}
    if isinstance(value, list):
        # A node's scalars travel as [name, value] pairs.
        named = lambda v: isinstance(v, list) and len(v) == 2 and isinstance(v[0], str)
        return [masked(v, out_dir) for v in value if not (named(v) and TIMING.search(v[0]))]
    if isinstance(value, str):
        return value.replace(out_dir, "<out>")
    return value


def run(bin_dir: Path, out_dir: Path, names) -> int:
    cosim = bin_dir / "cosim"
    if not cosim.is_file():
        print(f"same_outputs: no {cosim}", file=sys.stderr)
        return 2
    if "c_bar" in names and not (EXTERNAL / "bar-c").is_file():
        subprocess.run(["make", "-s", "-C", str(EXTERNAL)], check=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    failed = 0
    for name in names:
        case, variant, sets = CASES[name]
        dest = out_dir / name
        # Every build writes into the same folder, then the result is moved to `dest`.
        work = Path("/tmp") / f"same-outputs-{os.getuid()}" / name
        shutil.rmtree(work, ignore_errors=True)
        work.parent.mkdir(parents=True, exist_ok=True)
        cmd = [str(cosim), "run", str(EXAMPLES / case), "-o", str(work), "--run-id", f"same-{name}"[:24]]
        if variant:
            cmd += ["--variant", variant]
        for s in sets:
            cmd += ["--set", s]
        p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
        status = "ok" if p.returncode == 0 else f"exit {p.returncode}"
        print(f"{name}: {status}; {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ''}")
        failed += p.returncode != 0
        shutil.rmtree(dest, ignore_errors=True)
        shutil.move(str(work), str(dest))
        (dest / ".work").write_text(str(work))
    return 1 if failed else 0


def topic_is_command(topic: str) -> bool:
    """Whether the coordinator writes the topic (`cosim/RUN/NODE/cmd`)."""
    return topic.endswith("/cmd")


def recording(path: Path, out_dir: str):
    """Per channel topic: its encoding and its messages (log time, masked content)."""
    from mcap.reader import make_reader

    channels = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            ch = channels.setdefault(channel.topic, {"encoding": channel.message_encoding, "messages": []})
            if channel.message_encoding == "json":
                body = json.loads(message.data)
            else:
                env = wire_decode.decode(message.data)
                if "Heartbeat" in env["message"]:
                    continue
                body = env
            # A message a node sends is logged at the coordinator's time when it arrived,
            # which depends on how far ahead the windows ran: only its content is compared.
            when = message.log_time if channel.message_encoding == "json" or topic_is_command(channel.topic) else None
            ch["messages"].append((when, masked(body, out_dir)))
    return channels


def first_difference(a, b, path=""):
    """The path of the first place `a` and `b` differ (numbers exactly, -0.0 ≠ 0.0), or None."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{path}.{k} (only in {'the second' if k not in a else 'the first'})"
            d = first_difference(a[k], b[k], f"{path}.{k}")
            if d:
                return d
        return None
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            return f"{path} ({len(a)} against {len(b)} elements)"
        for i, (x, y) in enumerate(zip(a, b)):
            d = first_difference(x, y, f"{path}[{i}]")
            if d:
                return d
        return None
    if not wire_decode.same(a, b):
        return f"{path} ({a!r} against {b!r})"
    return None


def diff(a_dir: Path, b_dir: Path) -> int:
    names = sorted(p.name for p in a_dir.iterdir() if p.is_dir())
    if not names:
        print(f"same_outputs: nothing in {a_dir}")
        return 1
    bad = 0
    for name in names:
        a, b = a_dir / name, b_dir / name
        if not b.is_dir():
            print(f"{name}: missing in {b_dir}")
            bad += 1
            continue
        work = (a / ".work").read_text()
        problems = []
        for side in (a, b):
            if not (side / "summary.json").is_file() or not (side / "run.mcap").is_file():
                problems.append(f"{side} has no summary.json or run.mcap")
        if not problems:
            sa = masked(json.loads((a / "summary.json").read_text()), work)
            sb = masked(json.loads((b / "summary.json").read_text()), work)
            d = first_difference(sa, sb, "summary")
            if d:
                problems.append(d)
            ra, rb = recording(a / "run.mcap", work), recording(b / "run.mcap", work)
            d = first_difference(
                {t: c["encoding"] for t, c in ra.items()}, {t: c["encoding"] for t, c in rb.items()}, "channels"
            )
            if d:
                problems.append(d)
            else:
                for topic in sorted(ra):
                    d = first_difference(ra[topic]["messages"], rb[topic]["messages"], topic)
                    if d:
                        problems.append(d)
                        break
        messages = sum(len(c["messages"]) for c in ra.values()) if not problems else 0
        if problems:
            bad += 1
            print(f"{name}: DIFFERENT: {problems[0]}")
        else:
            print(f"{name}: same ({len(ra)} channels, {messages} messages compared)")
    print(f"{len(names) - bad} of {len(names)} cases give the same outputs")
    return 1 if bad else 0


def main() -> int:
    args = sys.argv[1:]
    if args[:1] == ["run"] and len(args) >= 3:
        names = args[3:] or list(CASES)
        unknown = [n for n in names if n not in CASES]
        if unknown:
            print(f"same_outputs: unknown case {unknown[0]} (see: same_outputs.py list)", file=sys.stderr)
            return 2
        return run(Path(args[1]).resolve(), Path(args[2]).resolve(), names)
    if args[:1] == ["diff"] and len(args) == 3:
        return diff(Path(args[1]), Path(args[2]))
    if args[:1] == ["list"]:
        for n, (case, variant, sets) in CASES.items():
            print(f"{n}: {case}" + (f" --variant {variant}" if variant else "") + "".join(f" --set {s}" for s in sets))
        return 0
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
