"""The start of a fit from the data (no hand-picked values): initial_estimate, by rig (payload_start,
load_start), remembered per (data, model, fixed values), since a discovery asks for the same
record's and model's starts again and again."""

from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import json
import threading
from typing import Callable, Mapping, Sequence

import numpy as np

from .. import identify_native as idn
from ..traces import Trace, read_trace
from .load_start import load_estimate
from .parameters import fmu_defaults, model_spec
from .payload_start import payload_estimate


#: Trace fields that say where a trace was read from or describe it, not what it holds
_NOT_DATA = ("stem", "csv_path", "json_path", "description")


def _trace_digest(trace: Trace) -> bytes:
    """A digest of everything a trace holds (every field's value, arrays by their bytes), not of
    where it was read from."""
    h = hashlib.blake2b(digest_size=20)
    for f in dataclasses.fields(trace):
        if f.name in _NOT_DATA:
            continue
        v = getattr(trace, f.name)
        h.update(f.name.encode() + b"=")
        if isinstance(v, np.ndarray):
            h.update(str(v.dtype).encode() + np.ascontiguousarray(v).tobytes())
        elif isinstance(v, dict):
            h.update(json.dumps(v, sort_keys=True, default=repr).encode())
        else:
            h.update(repr(v).encode())
        h.update(b"|")
    return h.digest()


#: the start values last computed (key: the traces' digests, the model, the fixed values): a
#: discovery asks for the same record's and model's starts again and again (a free vibration with
#: hysteresis: 46 estimates, 21 distinct, 12 s of Bouc-Wen searches repeated)
_ESTIMATES: dict = {}
_ESTIMATES_KEPT = 32
_ESTIMATES_LOCK = threading.Lock()


def _remembered(estimate: Callable[..., dict]) -> Callable[..., dict]:
    """initial_estimate computed once per (traces' data, model, fixed values); callers get a copy."""
    @functools.wraps(estimate)
    def wrapper(traces, spec, fixed=None, **options):
        traces = [t if isinstance(t, Trace) else read_trace(t) for t in traces]
        if options:
            return estimate(traces, spec, fixed, **options)
        key = (tuple(_trace_digest(t) for t in traces), repr(model_spec(spec)),
               tuple(sorted((k, float(v)) for k, v in (fixed or {}).items())))
        with _ESTIMATES_LOCK:
            hit = _ESTIMATES.get(key)
        if hit is None:
            hit = estimate(traces, spec, fixed)
            with _ESTIMATES_LOCK:
                _ESTIMATES[key] = hit
                while len(_ESTIMATES) > _ESTIMATES_KEPT:
                    _ESTIMATES.pop(next(iter(_ESTIMATES)))
        return copy.deepcopy(hit)
    return wrapper


@_remembered
def initial_estimate(traces: Sequence[Trace], spec, fixed: Mapping[str, float] | None = None) -> dict:
    """Start values for every parameter of ``spec`` from the data (see the docstring of tether.fit);
    parameters the data cannot inform keep the FMU's start values (or ``fixed``, values known
    otherwise, e.g. the elastic law under a creep test). Keys starting with '_' are scales for the
    fit (stiffness, amplitude, frequency), not parameters."""
    spec = model_spec(spec)
    traces = [t if isinstance(t, Trace) else read_trace(t) for t in traces]
    defaults = {**fmu_defaults(), **{k: float(v) for k, v in (fixed or {}).items()}}
    est = {n: defaults[n] for n in spec.parameters if n in defaults}
    load = [t for t in traces if t.rig == "load"]
    payload = [t for t in traces if t.rig == "payload"]
    if load:
        est.update(load_estimate(load, spec, defaults))
    if payload:
        per = [payload_estimate(t, spec) for t in payload]
        keys = set().union(*per)
        for k in keys:
            vals = [p[k] for p in per if k in p and np.all(np.isfinite(p[k]))]
            if not vals:
                continue
            if k.startswith("_k_taylor"):
                continue
            if load and k in ("EA", "a1", "a2", "a3"):
                continue                      # the static law from the load tests wins
            est[k] = float(np.mean(vals))
        if spec.hysteresis == "kawabata" and not load:
            # payload only: the virgin curve's tangent at the balance gives the scale of F_ref
            k_lin = float(np.mean([p["_k_lin"] for p in per]))
            tr = payload[0]
            L0, w = float(tr.length_m), idn.payload_masses(tr)[0] * float(tr.gravity_m_s2)
            LT = est.get("kaw_LT", defaults["kaw_LT"])
            pexp = 2.0 / LT - 1.0
            if w > 0 and k_lin > 0:
                eps_b = pexp * w / (k_lin * L0)           # F = C eps^p: dF/deps = p F / eps at the balance
                est["kaw_F_ref"] = w * (defaults["kaw_eps_ref"] / eps_b) ** pexp
    return {k: v for k, v in est.items() if k in spec.parameters or k.startswith("_")}
