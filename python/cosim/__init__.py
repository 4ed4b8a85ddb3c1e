"""Write a cosim solver node in Python, and read a run's results back.

Reading: ``cosim.open_run("examples/out/CASE")`` gives a :class:`Run` whose ``report(node)``,
``balance()`` and ``fields(coupling, sender)`` return numpy arrays (see ``cosim.results``).

A solver is a class built as ``Solver(model, params)`` (``params`` is the node's
``[nodes.NAME.params]`` table as a dict) with these methods:

``describe()``
    ``{"model": str, "units": "SI", "interfaces": [{"name": str, "points": int,
    "provides": [field, ...], "accepts": [field, ...]}]}``
``interface(name)``
    the interface's points as an (n, 3) array (or ``{"positions", "normals", "weights"}``)
``setup(bindings, inbox, outbox)`` (optional)
    once before the first window: the couplings (:class:`Binding`), what peers sent at
    set-up, and the set-up fields to send
``stable_dt()``
    the solver's stable time step (s)
``advance(window, inbox, outbox)``
    advance from ``window.t0`` to exactly ``window.t1``; read fields with
    ``inbox[interface, name]`` (read-only numpy views), write them into
    ``outbox.put(interface, name, (points, components))`` (writable views) or assign
    ``outbox[interface, name] = array``; return the report dict (``kinetic_energy``,
    ``internal_energy``, ``external_work``, ``interface_work``, ``momentum`` [3],
    ``momentum_gross``, ``external_impulse`` [3], ``applied_impulse``,
    ``interface_impulse`` [3], ``substeps``, ``scalars`` {name: value}), or None and
    have ``report()`` return it
``write_output(t, window, directory)``, ``save_state() -> bytes``, ``load_state(bytes)``
    optional

The arrays of ``inbox`` and ``outbox`` view the runtime's own buffers: they are valid during
the call only (copy what you keep). Raise :class:`ConfigError` for a bad parameter and
:class:`InterfaceError` for a bad coupling input; any other exception fails the node with its
traceback. End the script with ``raise SystemExit(cosim.run_node(Solver))``.
"""

import sys

from ._cosim import Binding, Inbox, Outbox, Window
from ._cosim import run_node as _run_node
from .results import FieldSeries, Run, Table, open_run

__all__ = [
    "Binding",
    "FieldSeries",
    "Run",
    "Table",
    "ConfigError",
    "Inbox",
    "InterfaceError",
    "Outbox",
    "Window",
    "open_run",
    "run_node",
]


class ConfigError(Exception):
    """A bad parameter: ``key`` in the node's params and why. The run names it as
    ``nodes.<node>.params.<key>``."""

    def __init__(self, key, reason):
        super().__init__(f"{key}: {reason}")
        self.key = key
        self.reason = reason


class InterfaceError(Exception):
    """A coupling input that is missing or malformed on ``interface``."""

    def __init__(self, interface, reason):
        super().__init__(f"interface {interface}: {reason}")
        self.interface = interface
        self.reason = reason


def run_node(factory, argv=None):
    """Run ``factory(model, params)`` as a node of a cosim run and return the exit code
    (0 finished, 1 failed, 2 bad command line, 3 aborted by the coordinator).

    ``argv`` is the node's command line, program first (default ``sys.argv``): ``cosim run``
    starts the script with ``--run RUN --node NAME --transport shm|zenoh``.
    """
    args = list(sys.argv if argv is None else argv)
    return _run_node(factory, [str(a) for a in args])
