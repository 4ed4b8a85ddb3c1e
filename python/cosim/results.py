"""Read a cosim run back as numpy arrays (and pandas frames, if pandas is installed).

>>> import cosim
>>> run = cosim.open_run("examples/out/chamber_detonation")
>>> run.nodes
['bar', 'gas']
>>> run.report("gas")["point2.pressure"]          # one float64 per window
>>> run.report("bar")["com_displacement"]         # (windows, 3), as "momentum"
>>> run.balance()["energy_residual"]
>>> run.fields("surface", "bar")["velocity"]      # (messages, points, components)
>>> run.report("gas").to_pandas()

The tables are those of ``cosim export`` (the same reader, in Rust): one row per recorded
window, ``window`` and ``time`` (simulated, s) first, NaN where a window lacks a key. A vector
has one name: one (windows, 3) array here and in ``history.npz`` (a node's ``K_x``, ``K_y``,
``K_z`` are the array ``K``), the columns ``K_x``, ``K_y``, ``K_z`` in every flat table (CSV,
Parquet, ``to_pandas()``). The interface fields are decoded from the recorded coupling
messages. Values are SI.
"""

import json
from pathlib import Path

import numpy as np

from ._cosim import read_fields, read_json_messages, read_tables

__all__ = ["FieldSeries", "Run", "Table", "open_run"]


class Table(dict):
    """Columns of one channel's history: ``key -> numpy array`` (1-D per window, or
    (windows, n) for vectors)."""

    def to_pandas(self):
        """The table as a pandas DataFrame (vectors as ``key_x``, ``key_y``, ``key_z``, as in
        ``cosim export``'s CSV and Parquet)."""
        import pandas as pd

        cols = {}
        for key, a in self.items():
            if a.ndim == 1:
                cols[key] = a
            else:
                names = "xyz" if a.shape[1] <= 3 else [str(i) for i in range(a.shape[1])]
                for i, n in enumerate(names):
                    cols[f"{key}_{n}"] = a[:, i]
        return pd.DataFrame(cols)

    def __repr__(self):
        rows = next((len(a) for a in self.values()), 0)
        keys = [k if a.ndim == 1 else f"{k} {a.shape[1:]}" for k, a in self.items()]
        shown = ", ".join(keys[:12]) + (f", … ({len(keys) - 12} more)" if len(keys) > 12 else "")
        return f"cosim.Table({rows} windows; {shown})"


class FieldSeries(dict):
    """The interface fields one node sent on one coupling: ``field -> (messages, points,
    components)`` arrays; ``window`` and ``time`` per message of each field in
    ``self.window[field]`` / ``self.time[field]`` (the set-up message is window 0)."""

    def __init__(self, coupling, sender):
        super().__init__()
        self.coupling = coupling
        self.sender = sender
        self.window = {}
        self.time = {}

    def __repr__(self):
        shapes = ", ".join(f"{k} {a.shape}" for k, a in self.items())
        return f"cosim.FieldSeries({self.coupling!r}, {self.sender!r}: {shapes})"


class Run:
    """A run's output folder (or one recording): its recorded histories and fields."""

    def __init__(self, path):
        path = Path(path)
        self.path = path
        self.recording = path / "run.mcap" if path.is_dir() else path
        if not self.recording.exists():
            raise FileNotFoundError(f"{path}: no recording (run.mcap) there")
        folder = path if path.is_dir() else path.parent
        summary = folder / "summary.json"
        #: the run's summary.json as a dict (None when the run wrote none)
        self.summary = json.loads(summary.read_text()) if summary.exists() else None
        raw, complete = read_tables(str(self.recording))
        #: False when the recording ended early (a killed run): what it holds is still read
        self.complete = complete
        self._tables = {}
        for name, cols in raw.items():
            t = Table()
            for key, (width, data) in cols.items():
                a = np.frombuffer(data, dtype="<f8")
                t[key] = a if width == 1 else a.reshape(-1, width)
            self._tables[name] = t
        self._fields = None
        self._json = None

    @property
    def nodes(self):
        """The nodes that reported, in name order."""
        return sorted(n for n in self._tables if n != "balance")

    def report(self, node):
        """The node's per-window report: energies, momentum, impulses, substeps, wall time
        and its named scalars (probes, displacements, ...)."""
        try:
            return self._tables[node]
        except KeyError:
            raise KeyError(f"no node {node!r} in this run; nodes: {self.nodes}") from None

    def balance(self):
        """The coordinator's energy and momentum balance per window."""
        return self._tables["balance"]

    def channel(self, topic):
        """Every JSON message recorded on ``topic`` (e.g. ``/cosim/case``,
        ``/cosim/lagrange/<coupling>``) as a list of dicts, in recording order."""
        if self._json is None:
            self._json = read_json_messages(str(self.recording))
        return [json.loads(text) for t, _, text in self._json if t == topic]

    @property
    def topics(self):
        """The JSON channels of the recording."""
        if self._json is None:
            self._json = read_json_messages(str(self.recording))
        return sorted({t for t, _, _ in self._json})

    @property
    def case(self):
        """The case as recorded at the start of the run."""
        msgs = self.channel("/cosim/case")
        return msgs[0] if msgs else None

    def couplings(self):
        """``(coupling, sender)`` pairs that sent interface fields."""
        self._load_fields()
        return sorted(self._fields)

    def fields(self, coupling, sender):
        """The interface fields ``sender`` sent on ``coupling``."""
        self._load_fields()
        try:
            return self._fields[(coupling, sender)]
        except KeyError:
            raise KeyError(
                f"no fields from {sender!r} on {coupling!r}; recorded: {sorted(self._fields)}"
            ) from None

    def _load_fields(self):
        if self._fields is not None:
            return
        series, self.ragged_fields = read_fields(str(self.recording))
        out = {}
        for coupling, sender, field, comps, points, windows, times, values in series:
            s = out.setdefault((coupling, sender), FieldSeries(coupling, sender))
            s[field] = np.frombuffer(values, dtype="<f8").reshape(-1, points, comps)
            s.window[field] = np.frombuffer(windows, dtype="<u8")
            s.time[field] = np.frombuffer(times, dtype="<f8")
        self._fields = out

    def __repr__(self):
        return f"cosim.Run({str(self.path)!r}, nodes={self.nodes}, complete={self.complete})"


def open_run(path):
    """Open a run's output folder (or its ``run.mcap``)."""
    return Run(path)
