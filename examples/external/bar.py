#!/usr/bin/env python3
"""The 1-D elastic bar (model `bar-1d`) as a cosim node written in Python with numpy.

The same discretisation as the built-in `solid-node` model `bar-1d` (solid-node/src/bar.rs):
a lumped-mass spring chain advanced by central differences,
    a_n = M^-1 (f_int(u_n) + f_ext + f_coupling),  v_{n+1/2} = v_{n-1/2} + dt a_n,
    u_{n+1} = u_n + dt v_{n+1/2},
with the same parameters, interfaces and coupling behaviour (docs/architecture.md, kinematic:
driver or responder), so a run with this node as the right half of the split bar gives the
built-in results. `cosim run` starts it as `bar.py --run RUN --node NAME --transport shm`.
"""

import math
import os
import struct

import numpy as np

import cosim

FIELDS = ["position", "velocity", "force", "mass", "stiffness"]
KEYS = {"length", "x0", "elements", "young", "density", "area", "fixed", "tip_force",
        "load_end", "courant", "interfaces"}
END = {"left": 0, "right": 1}
# save_state's bytes: this header (magic, format version, nodes, couplings), then float64
# little-endian u, v, the five work and impulse sums and each coupling's force.
STATE = struct.Struct("<8sHII")
STATE_MAGIC = b"BARPYST1"
STATE_VERSION = 1


def number(params, key, default=None):
    v = params.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise cosim.ConfigError(key, f"must be a number, got {v!r}")
    return float(v)


def positive(params, key):
    v = number(params, key)
    if not (math.isfinite(v) and v > 0):
        raise cosim.ConfigError(key, f"must be > 0, got {v}")
    return v


def end_of(key, value, allow_none):
    if value in END or (allow_none and value == "none"):
        return value
    choices = '"left", "right"' + (' or "none"' if allow_none else "")
    raise cosim.ConfigError(key, f'must be {choices}, got "{value}"')


class Bar:
    """Parameters as `[nodes.NAME.params]` of `bar-1d`."""

    def __init__(self, model, params):
        if model != "bar-1d":
            raise cosim.ConfigError("model", f'this solver has one model, "bar-1d"; got "{model}"')
        for key in params:
            if key not in KEYS:
                raise cosim.ConfigError(key, f"unknown parameter (known: {', '.join(sorted(KEYS))})")
        self.length = positive(params, "length")
        self.x0 = number(params, "x0", 0.0)
        ne = params.get("elements")
        if isinstance(ne, bool) or not isinstance(ne, int) or ne < 1:
            raise cosim.ConfigError("elements", f"must be an integer ≥ 1, got {ne!r}")
        young, density, area = (positive(params, k) for k in ("young", "density", "area"))
        self.courant = number(params, "courant", 0.9)
        if not 0.0 < self.courant <= 1.0:
            raise cosim.ConfigError("courant", f"must be in (0, 1], got {self.courant}")
        self.tip_force = number(params, "tip_force", 0.0)
        if not math.isfinite(self.tip_force):
            raise cosim.ConfigError("tip_force", "must be finite")
        self.fixed = end_of("fixed", params.get("fixed", "left"), True)
        self.load = end_of("load_end", params.get("load_end", "right"), True)
        self.interfaces = {}
        interfaces = params.get("interfaces", {})
        if not isinstance(interfaces, dict):
            raise cosim.ConfigError("interfaces", "must be a table of name = \"left\" | \"right\"")
        for name, end in interfaces.items():
            self.interfaces[name] = end_of(f"interfaces.{name}", end, False)
        self.ne = ne
        n = ne + 1
        self.h = self.length / ne
        self.k = young * area / self.h
        me = density * area * self.h
        self.m = np.full(n, me)
        self.m[0] = self.m[-1] = me / 2.0
        self.u = np.zeros(n)
        self.v = np.zeros(n)
        self.f = np.zeros(n)
        self.a = np.zeros(n)
        self.d = np.zeros(ne)
        self.external_work = self.interface_work = 0.0
        self.external_impulse = self.applied_impulse = self.interface_impulse = 0.0
        self.coupled = []
        self.dt = self.courant * self.critical_dt()

    def node(self, end):
        return 0 if end == "left" else self.ne

    def internal_force(self):
        """Spring-chain force on every node, into self.f (no allocation)."""
        np.subtract(self.u[1:], self.u[:-1], out=self.d)
        self.d *= self.k
        self.f.fill(0.0)
        self.f[:-1] += self.d
        self.f[1:] -= self.d

    def prescribed(self):
        """Nodes whose motion is imposed: the fixed end and responder ends."""
        ends = [c["end"] for c in self.coupled if c["role"] == "responder"]
        if self.fixed != "none":
            ends.append(self.fixed)
        return [self.node(e) for e in ends]

    def critical_dt(self):
        # Gershgorin bound ω² ≤ max 2 Σk/m (exact for a uniform chain: dt = h/c); a driven
        # end counts the responder's mass and stiffness bound.
        ksum = np.full(len(self.m), 2.0 * self.k)
        ksum[0] = ksum[-1] = self.k
        if len(self.m) == 1:
            ksum[0] = 0.0
        for c in self.coupled:
            if c["role"] == "driver":
                ksum[self.node(c["end"])] += c["added_stiffness"]
        return 2.0 / math.sqrt(np.max(2.0 * ksum / self.m))

    def describe(self):
        return {
            "model": "bar-1d",
            "units": "SI",
            "interfaces": [
                {"name": name, "points": 1, "provides": FIELDS, "accepts": FIELDS}
                for name in self.interfaces
            ],
        }

    def interface(self, name):
        if name not in self.interfaces:
            raise cosim.InterfaceError(name, "no such interface on this bar (see params.interfaces)")
        x = self.x0 if self.interfaces[name] == "left" else self.x0 + self.length
        return np.array([[x, 0.0, 0.0]])

    def setup(self, bindings, inbox, outbox):
        self.coupled = []
        for b in bindings:
            end = self.interfaces.get(b.interface)
            if end is None:
                raise cosim.InterfaceError(b.interface, "no such interface on this bar")
            if end == self.fixed:
                raise cosim.InterfaceError(b.interface, "is the fixed end and cannot be coupled")
            self.coupled.append({"interface": b.interface, "end": end, "role": b.role,
                                 "force": 0.0, "added_mass": 0.0, "added_stiffness": 0.0})
        self.internal_force()
        for c in self.coupled:
            i, name = self.node(c["end"]), c["interface"]
            if c["role"] == "responder":
                # The kinematic responder's set-up: its interface mass, stiffness bound and
                # constraint force at t0, for the driver.
                outbox.put(name, "mass", 1)[0] = self.m[i]
                outbox.put(name, "stiffness", 1)[0] = self.k
                outbox.put(name, "force", (1, 3))[0] = (self.f[i], 0.0, 0.0)
            else:
                m = float(require(inbox, name, "mass", 1)[0])
                k = float(require(inbox, name, "stiffness", 1)[0])
                if not (m >= 0 and k >= 0 and math.isfinite(m) and math.isfinite(k)):
                    raise cosim.InterfaceError(name, f"bad set-up mass {m} or stiffness {k}")
                self.m[i] += m
                c.update(added_mass=m, added_stiffness=k,
                         force=float(require(inbox, name, "force", 3)[0]))
        self.dt = self.courant * self.critical_dt()

    def stable_dt(self):
        return self.dt

    def advance(self, window, inbox, outbox):
        span = window.t1 - window.t0
        if not span > 0:
            raise ValueError(f"empty window [{window.t0}, {window.t1}]")
        nsub = max(math.ceil(span / self.dt - 1e-9), 1)
        dt = span / nsub
        u, v, f, m = self.u, self.v, self.f, self.m
        # This window's inputs: the driver's force, or the responder's prescribed velocity.
        imposed = []
        for c in self.coupled:
            i = self.node(c["end"])
            if c["role"] == "driver":
                c["force"] = float(require(inbox, c["interface"], "force", 3)[0])
            else:
                vel = float(require(inbox, c["interface"], "velocity", 3)[0])
                if not math.isfinite(vel):
                    raise cosim.InterfaceError(c["interface"], "non-finite velocity received")
                imposed.append((i, float(u[i]), vel))
        fixed = None if self.fixed == "none" else self.node(self.fixed)
        load = None if self.load == "none" else self.node(self.load)
        fl = self.tip_force
        for step in range(nsub):
            self.internal_force()
            if fixed is not None:
                self.external_impulse += -f[fixed] * dt  # the support reaction's impulse
            for c in self.coupled:
                i = self.node(c["end"])
                if c["role"] == "driver":
                    f[i] += c["force"]
                    self.interface_impulse += c["force"] * dt
                else:
                    self.interface_impulse += -f[i] * dt
            if load is not None:
                f[load] += fl
                self.external_impulse += fl * dt
                self.applied_impulse += abs(fl) * dt
            np.divide(f, m, out=self.a)
            self.a *= dt
            v += self.a
            if fixed is not None:
                v[fixed] = 0.0
            for i, _, vel in imposed:
                v[i] = vel
            for c in self.coupled:
                i = self.node(c["end"])
                du = dt * v[i]
                self.interface_work += (c["force"] if c["role"] == "driver" else -f[i]) * du
            if load is not None:
                self.external_work += fl * dt * v[load]
            np.multiply(v, dt, out=self.a)
            u += self.a
            for i, u0, vel in imposed:
                # Along the driver's motion (seed 004 eq. 31), from the window start: no drift.
                u[i] = u0 + (step + 1) * dt * vel
        # Outputs at t1.
        self.internal_force()
        scalars = {}
        if load is not None:
            scalars["tip_displacement"] = float(u[load])
        for c in self.coupled:
            i, name = self.node(c["end"]), c["interface"]
            if c["role"] == "driver":
                x_ref = self.x0 if c["end"] == "left" else self.x0 + self.length
                outbox.put(name, "position", (1, 3))[0] = (x_ref + u[i], 0.0, 0.0)
                outbox.put(name, "velocity", (1, 3))[0] = (v[i], 0.0, 0.0)
            else:
                outbox.put(name, "force", (1, 3))[0] = (f[i], 0.0, 0.0)
            scalars[f"{name}_displacement"] = float(u[i])
        free = np.ones(len(m), dtype=bool)
        free[self.prescribed()] = False
        mv = m[free] * v[free]
        np.subtract(u[1:], u[:-1], out=self.d)
        return {
            "kinetic_energy": float(0.5 * np.dot(mv, v[free])),
            "internal_energy": float(0.5 * self.k * np.dot(self.d, self.d)),
            "external_work": self.external_work,
            "interface_work": self.interface_work,
            "momentum": [float(mv.sum()), 0.0, 0.0],
            "momentum_gross": float(np.abs(mv).sum()),
            "external_impulse": [self.external_impulse, 0.0, 0.0],
            "applied_impulse": self.applied_impulse,
            "interface_impulse": [self.interface_impulse, 0.0, 0.0],
            "substeps": nsub,
            "scalars": scalars,
        }

    def save_state(self):
        """The state a restart needs, as versioned bytes (the runtime writes them into the
        node's checkpoint). Masses, step and coupling roles come again from setup()."""
        sums = [self.external_work, self.interface_work, self.external_impulse,
                self.applied_impulse, self.interface_impulse]
        values = np.concatenate([self.u, self.v, sums, [c["force"] for c in self.coupled]])
        head = STATE.pack(STATE_MAGIC, STATE_VERSION, len(self.u), len(self.coupled))
        return head + values.astype("<f8").tobytes()

    def load_state(self, data):
        """Restore what save_state() wrote, after setup(); a state of another format,
        version, mesh or coupling set is refused, not half-loaded."""
        if len(data) < STATE.size:
            raise ValueError(f"bar state of {len(data)} bytes is too short")
        magic, version, n, nc = STATE.unpack_from(data)
        if magic != STATE_MAGIC:
            raise ValueError("not a state of this bar (bad magic)")
        if version != STATE_VERSION:
            raise ValueError(f"bar state version {version}, this bar reads {STATE_VERSION}")
        if n != len(self.u) or nc != len(self.coupled):
            raise ValueError(f"state of {n} nodes and {nc} couplings, this bar has "
                             f"{len(self.u)} and {len(self.coupled)}")
        count = 2 * n + 5 + nc
        if len(data) != STATE.size + 8 * count:
            raise ValueError(f"bar state of {len(data)} bytes, expected {STATE.size + 8 * count}")
        values = np.frombuffer(data, dtype="<f8", count=count, offset=STATE.size)
        self.u[:] = values[:n]
        self.v[:] = values[n:2 * n]
        (self.external_work, self.interface_work, self.external_impulse,
         self.applied_impulse, self.interface_impulse) = (float(x) for x in values[2 * n:2 * n + 5])
        for c, f in zip(self.coupled, values[2 * n + 5:]):
            c["force"] = float(f)
        self.internal_force()

    def write_output(self, t, window, directory):
        """The nodes as VTK points with displacement and velocity (ParaView: bar.pvd)."""
        os.makedirs(directory, exist_ok=True)
        n = len(self.u)
        x = self.x0 + self.h * np.arange(n)

        def rows(a):
            return "\n".join(f"{p:.17g} 0 0" for p in a)

        name = f"bar_{window:06d}.vtu"
        with open(os.path.join(directory, name), "w") as out:
            out.write(f"""<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian">
<UnstructuredGrid><Piece NumberOfPoints="{n}" NumberOfCells="{n}">
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">
{rows(x)}
</DataArray></Points>
<Cells>
<DataArray type="Int64" Name="connectivity" format="ascii">{" ".join(map(str, range(n)))}</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">{" ".join(map(str, range(1, n + 1)))}</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">{" ".join(["1"] * n)}</DataArray>
</Cells>
<PointData>
<DataArray type="Float64" Name="displacement" NumberOfComponents="3" format="ascii">
{rows(self.u)}
</DataArray>
<DataArray type="Float64" Name="velocity" NumberOfComponents="3" format="ascii">
{rows(self.v)}
</DataArray>
</PointData>
</Piece></UnstructuredGrid>
</VTKFile>
""")
        # The series keeps the frames of earlier windows and drops later ones (a restarted
        # run writes the frames after its checkpoint again; a killed one may have left them).
        index = os.path.join(directory, "bar.pvd.index")
        sets = []
        if os.path.exists(index):
            with open(index) as idx:
                sets = [line.split(" ", 1) for line in idx.read().splitlines()]
        sets = [(time, f) for time, f in sets if int(f[4:-4]) < window]
        sets.append((f"{t:e}", name))
        with open(index + ".tmp", "w") as idx:
            idx.write("".join(f"{time} {f}\n" for time, f in sets))
        os.replace(index + ".tmp", index)
        with open(os.path.join(directory, "bar.pvd"), "w") as pvd:
            pvd.write('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n<Collection>\n')
            for time, f in sets:
                pvd.write(f'<DataSet timestep="{time}" file="{f}"/>\n')
            pvd.write("</Collection>\n</VTKFile>\n")


def require(inbox, interface, name, size):
    """A received field that must be there with `size` values, flattened."""
    a = inbox.get(interface, name)
    if a is None:
        raise cosim.InterfaceError(interface, f"no '{name}' field received")
    if a.size != size:
        raise cosim.InterfaceError(interface, f"'{name}' has {a.size} values, expected {size}")
    return a.reshape(-1)


if __name__ == "__main__":
    raise SystemExit(cosim.run_node(Bar))
