#!/usr/bin/env python3
"""Benchmark helper: the `echo` node of target/release/cosim-echo-node written in Python on
the `cosim` package, for the participant window benchmark (`cosim bench --only window`, which
carries this file inside the binary). Interface `port` with `points` points; a
responder answers each window's `signal` with the same values as `echo`, a driver sends
`signal` and takes `echo` (one value per point: 128 points are 1 KiB each way)."""

import cosim


class Echo:
    def __init__(self, model, params):
        if model != "echo":
            raise cosim.ConfigError("model", f'only "echo", got "{model}"')
        for key in params:
            if key != "points":
                raise cosim.ConfigError(key, "unknown parameter (echo reads: points)")
        self.points = params.get("points", 128)
        self.role = None

    def describe(self):
        fields = ["signal", "echo"]
        return {"model": "echo", "interfaces": [
            {"name": "port", "points": self.points, "provides": fields, "accepts": fields}]}

    def interface(self, name):
        return [[float(i), 0.0, 0.0] for i in range(self.points)]

    def setup(self, bindings, inbox, outbox):
        self.role = bindings[0].role if bindings else None

    def stable_dt(self):
        return 1.0

    def advance(self, window, inbox, outbox):
        if self.role == "responder":
            outbox.put("port", "echo", self.points)[:] = inbox["port", "signal"]
        elif self.role == "driver":
            outbox.put("port", "signal", self.points)[:] = window.index
        return {"substeps": 1}


if __name__ == "__main__":
    raise SystemExit(cosim.run_node(Echo))
