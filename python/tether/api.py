"""The Python API's functions behind ``tether.simulate``, ``tether.fit`` and ``tether.discover``
(docs/api.md). Each takes traces as paths (NAME.csv, NAME.csv.gz, NAME.json or NAME) or as
:class:`tether.Trace` objects (``tether.read_trace``, ``Trace.from_arrays``, ``Trace.from_dataframe``).
"""

from __future__ import annotations

import os
from typing import Mapping, Sequence

from .traces import Trace, read_trace

TraceLike = "Trace | str | os.PathLike"


def _trace(trace) -> Trace:
    return trace if isinstance(trace, Trace) else read_trace(trace, require_measured=False)


def simulate(trace, model="linear", params: Mapping[str, float] | None = None, **options):
    """Simulate ``trace`` with ``model`` (a model string such as ``"linear+boucwen"``) and
    ``params`` (FMU parameter name -> value; FMU start values for the rest; the trace's length,
    mass, gravity and initial state win). Returns a :class:`tether.run.SimResult` (``time``,
    ``predicted``, ``tension``, ``rms_error(measured)``). The trace may be input-only."""
    from .run import simulate as run_simulate

    return run_simulate(_trace(trace), model, params, **options)


def fit(traces, model, *, free: Sequence[str] | None = None, params: Mapping[str, float] | None = None,
        **options):
    """Fit one parameter set of ``model`` to one trace or a list of traces with the identification
    engine. ``free``: names to fit (default: what the experiments determine); ``params``: start
    values (default: estimates from the data). Returns a :class:`tether.fit.FitResult`
    (``parameters``, ``values``, ``std_error``, ``intervals``, ``rms``, ``as_dict()``); options as
    :func:`tether.fit.fit_traces` (``fixed``, ``progress``, ``n_starts``, ...)."""
    from .fit import fit_traces

    if isinstance(traces, (str, os.PathLike, Trace)):
        traces = [traces]
    return fit_traces([t if isinstance(t, Trace) else read_trace(t) for t in traces], model, free=free,
                      start=params, **options)


def discover(trace, start: str = "linear", **options):
    """Which effects does ``trace`` show that the ``start`` model lacks? Runs the discovery loop
    (README, "Discovery") and returns a :class:`tether.discover.Discovery`; its JSON form (the
    CLI's OUT.json) is ``tether.discover.discovery_document(d)``. Options: ``progress`` (a
    function of one line), ``budget`` (seconds, default 900), ``max_steps``."""
    from .discover import discover as run_discover

    return run_discover(trace if isinstance(trace, Trace) else read_trace(trace), start, **options)
