"""A law's state before the record, found on a grid before a fit frees it with the rest: the Iwan
bank's memory of the run a record was cut from (last_reversal_beyond;
tether.nuisance.last_reversal_grid says why), the age of the preload a load-rig record starts
under (creep_preload_age; tether.nuisance.preload_age_grid) and the load a load-rig record's Iwan
bank was last unloaded at (iwan_relaxed_load; tether.nuisance.relaxed_load_grid)."""
from __future__ import annotations

import math
from typing import Callable, Mapping, Sequence

import numpy as np

from .. import nuisance as NZ
from ..traces import Trace

MEMORY = "last_reversal_beyond"
#: each scanned state's grid (a function of the trace)
GRIDS = {MEMORY: NZ.last_reversal_grid, "creep_preload_age": NZ.preload_age_grid,
         "iwan_relaxed_load": NZ.relaxed_load_grid}
#: the states held at their start while the law's other parameters are fitted, then scanned: the
#: law found without the state is a start the scan can only improve on (a preload's creep, whose
#: error is flat once the age passes a cell's time; docs/discovery.md, "A preload's creep")
SCANNED_AFTER_LAW = ("creep_preload_age",)
#: the parameters that move with the state (the bank's force at the start moves the payload's
#: state; the preload's creep moves the elongation's start): at each value of the grid they are
#: corrected along their columns of the Jacobian
COUPLED = ("x0", "v0", "offset_measured", "offset_input")
#: their finite-difference steps, relative to the record's span (x0, offsets) and to its span per
#: second (v0)
COUPLED_STEP = 1e-3


def scan_memory(values: Mapping[str, float], free: Sequence[str], trace: Trace,
                box: Mapping[str, tuple[float, float]],
                residual_of: Callable[[Mapping[str, float]], np.ndarray], name: str = MEMORY) -> dict:
    """``values`` with the state ``name`` moved to the value of its grid (GRIDS) or its own whose
    residual, with the free COUPLED parameters corrected by linear least squares, is least; those
    corrections applied. A value that fails to simulate is passed over."""
    lo, hi = box.get(name, (-math.inf, math.inf))
    coupled = [n for n in COUPLED if n in free]
    r0 = _residual_or_none(residual_of, values)
    if r0 is None:
        return dict(values)
    J = _coupled_columns(values, coupled, trace, residual_of, r0)
    best, best_rss = dict(values), _projected(r0, J, values, coupled)[0]
    for b in GRIDS[name](trace):
        if not lo <= b <= hi or b == values[name]:
            continue
        trial = {**values, name: b}
        r = _residual_or_none(residual_of, trial)
        if r is None:
            continue
        rss, corrected = _projected(r, J, trial, coupled)
        if rss < best_rss:
            best, best_rss = corrected, rss
    return best


def _coupled_columns(values, coupled, trace, residual_of, r0) -> np.ndarray | None:
    """Finite-difference columns of the residual in the coupled parameters (None if one fails)."""
    span = float(np.ptp(np.asarray(trace.measured, float))) or 1.0
    duration = float(trace.time[-1] - trace.time[0]) or 1.0
    cols = []
    for n in coupled:
        h = COUPLED_STEP * (abs(values[n]) + (span / duration if n == "v0" else span))
        r = _residual_or_none(residual_of, {**values, n: values[n] + h})
        if r is None:
            return None
        cols.append((r - r0) / h)
    return np.column_stack(cols) if cols else None


def _projected(r: np.ndarray, J: np.ndarray | None, values: Mapping[str, float],
               coupled: Sequence[str]) -> tuple[float, dict]:
    """The residual sum of squares with the coupled parameters' linear correction, and the values
    corrected."""
    if J is None:
        return float(r @ r), dict(values)
    step, *_ = np.linalg.lstsq(J, -r, rcond=None)
    rest = r + J @ step
    return float(rest @ rest), {**values, **{n: values[n] + float(s) for n, s in zip(coupled, step)}}


def _residual_or_none(residual_of, values) -> np.ndarray | None:
    try:
        r = np.asarray(residual_of(values), float)
    except RuntimeError:
        return None
    return r if np.all(np.isfinite(r)) else None
