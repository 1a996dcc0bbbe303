"""Which samples of the record a fit sees: the first part (the held-out test; in a load-controlled
record the first part of each stretch of the load), and every k-th sample of a long record (the
search's thinning)."""

from __future__ import annotations

import copy
import math

import numpy as np

from ..noise import _robust_std
from ..traces import Trace


def _truncated(trace: Trace, fraction: float) -> Trace:
    """The first ``fraction`` of the record (whole periods of a periodic record)."""
    n = len(trace.time)
    P = int(trace.periodic_samples or 0)
    m = max(1, int(round(fraction * n / P))) * P if P else max(20, int(round(fraction * n)))
    return _samples_of(trace, slice(0, min(m, n)))


def _samples_of(trace: Trace, index) -> Trace:
    """The record on the samples ``index`` selects (a slice or an index array)."""
    out = copy.copy(trace)
    out.time = trace.time[index]
    out.measured = trace.measured[index]
    if trace.input is not None:
        out.input = trace.input[index]
    if trace.fitted_samples is not None:
        out.fitted_samples = trace.fitted_samples[index]
    return out


def heldout_split(trace: Trace, fraction: float) -> tuple[Trace, np.ndarray]:
    """(the record as a held-out fit sees it, the held-out samples: True per sample). The first
    ``fraction`` of the record (_truncated) and the rest held out; in a load-controlled record
    (load_unload, creep) the first ``fraction`` of each stretch of the load (load_stretches: each
    ramp up, ramp down and hold), its last part held out (the fit simulates the whole record and
    sees the first parts only: Trace.fitted_samples). A load test's last part is the unloading and
    the recovery after it: a fit of the record's first part never sees the load fall, and predicts
    the recovery from a split of recoverable and unrecoverable creep that the loading alone does
    not fix (docs/discovery.md, "Where the held-out part lies")."""
    n = len(trace.time)
    stretches = load_stretches(trace) if trace.rig == "load" and trace.input is not None else []
    if len(stretches) < 2:
        part = _truncated(trace, fraction)
        return part, np.arange(n) >= len(part.time)
    held = np.zeros(n, bool)
    for a, b in stretches:
        held[a + int(round(fraction * (b - a))):b] = True
    part = copy.copy(trace)
    part.fitted_samples = ~held
    return part, held


def true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """The runs [a, b) of consecutive True samples of ``mask``."""
    edges = np.flatnonzero(np.diff(np.r_[0, np.asarray(mask, int), 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def held_out_spans(trace: Trace, held: np.ndarray) -> list[tuple[float, float]]:
    """The times [s] of the first and last sample of each run of held-out samples (heldout_split)."""
    t = np.asarray(trace.time, float)
    return [(float(t[a]), float(t[b - 1])) for a, b in true_runs(held)]


#: a stretch of the load has at least this many samples: a shorter run of one direction (the noise
#: of a measured load on a hold, a step taken within a few sample intervals) joins the stretch
#: before it
STRETCH_SAMPLES = 5

#: ... and a short run that moves the load by more than this share of its range is a step: it ends
#: the stretch it joins (a measured load's noise stays far below it)
LEVEL_STEP = 0.1

#: the load moves between two samples where it changes by more than this many times its noise
#: (the second differences' robust scale: ramps and holds have none) or CORNER_TOLERANCE of its
#: largest magnitude (the digits a CSV file keeps)
STRETCH_NOISE = 4.0


def load_stretches(trace: Trace) -> list[tuple[int, int]]:
    """The stretches [a, b) of samples over which a load-controlled record's load goes one way:
    up, down or held. Each sample takes the direction of its next sample interval; runs shorter
    than STRETCH_SAMPLES join the run before them (one that begins a stretch, the run after it),
    and a short run that moves the load by LEVEL_STEP of its range or more (a step) ends the
    stretch it joined."""
    u = np.asarray(trace.input, float)
    if len(u) < 3 or not np.ptp(u) > 0:
        return [(0, len(u))]
    du = np.diff(u)
    tol = max(STRETCH_NOISE * _robust_std(np.diff(u, 2)) / math.sqrt(6.0),
              CORNER_TOLERANCE * float(np.max(np.abs(u))))
    way = np.sign(du) * (np.abs(du) > tol)
    way = np.r_[way, way[-1]]
    edges = [0, *(np.flatnonzero(np.diff(way)) + 1).tolist(), len(u)]
    step = LEVEL_STEP * float(np.ptp(u))
    merged: list[list] = []              # [a, b, the way the stretch goes, ended by a step]
    for a, b in zip(edges[:-1], edges[1:]):
        short = b - a < STRETCH_SAMPLES
        is_step = short and abs(u[min(b, len(u) - 1)] - u[a]) > step
        if merged and merged[-1][1] - merged[-1][0] < STRETCH_SAMPLES and not merged[-1][3]:
            merged[-1][1:3] = [b, way[a]]           # a stretch still too short takes the next run's way
        elif merged and not merged[-1][3] and (short or way[a] == merged[-1][2]):
            merged[-1][1], merged[-1][3] = b, is_step
        else:
            merged.append([a, b, way[a], False])
    return [(a, b) for a, b, _, _ in merged]


#: a record whose simulation runs over more samples than this is searched on every k-th sample,
#: and its final model fitted again to the whole record: a simulation's cost grows with its
#: samples (docs/discovery.md, "Time")
SEARCH_SAMPLES = 4000


#: ... only where the input rebuilt from the kept samples (the interpolation the fits use) misses
#: the dropped ones by at most this share of the noise, carried to the measured column by the
#: ratio of the two columns' spreads: a record sampled near its input's bandwidth (the Bouc-Wen
#: benchmark's multisine) keeps every sample
THINNED_INPUT_SHARE = 0.05


#: iterations of the final fit to the whole record, which starts at the searched record's optimum
WHOLE_RECORD_ITERATIONS = 20


#: a record that is not periodic and whose input is made of straight pieces (a load test's ramps
#: and holds) keeps, beside every k-th sample, each corner of its input and the samples on both
#: sides of it, where they add at most this share to the samples kept: the input rebuilt from the
#: kept samples is then the record's own at every dropped sample (a creep test's load steps,
#: rebuilt from every 2nd sample, missed it by 36 x the noise). A smooth or noisy input has corners
#: everywhere and keeps only every k-th sample.
CORNER_SHARE = 0.1

#: ... a corner: a second difference of the input above this share of its largest magnitude (the
#: digits a CSV file keeps make the rest)
CORNER_TOLERANCE = 1e-6


def _input_corners(trace: Trace, k: int) -> np.ndarray:
    """The samples at and beside every corner of the input of a record that is not periodic
    (CORNER_SHARE, CORNER_TOLERANCE); none where they would add more than CORNER_SHARE to every
    k-th sample, or for a periodic record or one without input."""
    if trace.input is None or trace.periodic_samples or k <= 1:
        return np.zeros(0, int)
    u = np.asarray(trace.input, float)
    scale = float(np.max(np.abs(u))) if len(u) else 0.0
    if len(u) < 3 or not scale > 0:
        return np.zeros(0, int)
    j = np.flatnonzero(np.abs(np.diff(u, 2)) > CORNER_TOLERANCE * scale)
    near = np.unique(np.concatenate([j, j + 1, j + 2]))
    return near if len(near) <= CORNER_SHARE * len(u) / k else np.zeros(0, int)


def _kept_samples(n: int, k: int, periodic: bool, corners=()) -> np.ndarray:
    """Every k-th of n samples and the samples ``corners`` (_input_corners); a record that is not
    periodic keeps its last sample as well."""
    keep = np.arange(0, n, k)
    if not periodic:
        keep = np.union1d(np.union1d(keep, np.asarray(corners, int)), [n - 1])
    return keep


def thinned_input_miss(trace: Trace, k: int, kind: str | None = None) -> float:
    """How far the input rebuilt from every k-th sample (with the interpolation ``kind``; by default
    the one thinned() picks, the least of _rebuild_kinds' misses) misses the samples dropped (RMS),
    carried to the measured column by the ratio of the columns' standard deviations [unit of the
    measured column]; 0 for a record without input."""
    from ..run import input_pieces, record_period

    if trace.input is None:
        return 0.0
    if kind is None:
        return min(thinned_input_miss(trace, k, kd) for kd in _rebuild_kinds(trace, k))
    t = np.asarray(trace.time, float)
    u = np.asarray(trace.input, float)
    P = int(trace.periodic_samples or 0)
    period = None
    if P:
        period = record_period(t, P)
        t, u = t[:P], u[:P]
    keep = _kept_samples(len(t), k, bool(P), _input_corners(trace, k))
    vals, ders = input_pieces(t[keep], u[keep], period, kind)
    drop = np.setdiff1d(np.arange(len(t)), keep)
    i = np.searchsorted(t[keep], t[drop], side="right") - 1
    s = t[drop] - t[keep][i]
    rebuilt = vals[i] + s * (ders[i, 0] + s * (ders[i, 1] / 2.0 + s * ders[i, 2] / 6.0))
    spread_u = float(np.std(u))
    if not spread_u > 0:
        return 0.0
    return float(np.sqrt(np.mean((rebuilt - u[drop]) ** 2))) * float(np.std(trace.measured)) / spread_u


def thinned_interpolation(trace: Trace, k: int) -> str:
    """How the thinned record rebuilds its input between the kept samples: the record's own
    interpolation, or a cubic spline where that misses the dropped samples less (straight lines
    through every k-th sample of a smooth input miss it by (kh)^2 |u''| / 8, a spline by a power of
    kh four; a step in the input makes a spline ring, and the record's own kind is kept)."""
    kinds = _rebuild_kinds(trace, k)
    return kinds[0] if len(kinds) == 1 else min(kinds, key=lambda kind: thinned_input_miss(trace, k, kind))


def _rebuild_kinds(trace: Trace, k: int) -> tuple:
    """The interpolations the thinned record may rebuild its input with: the record's own, and a
    cubic spline beside it (thinned_interpolation)."""
    from ..run import input_interpolation

    own = input_interpolation(trace)
    return (own,) if trace.input is None or own == "spline" or k <= 1 else (own, "spline")


def search_thinning(trace: Trace, sigma: float, samples: int = SEARCH_SAMPLES) -> int:
    """k: the search runs on every k-th sample (1: on the whole record). The largest k up to what
    brings the simulated samples (one period of a periodic record) to ``samples`` (SEARCH_SAMPLES;
    a campaign shares them between its records) whose input is rebuilt (thinned_interpolation)
    within THINNED_INPUT_SHARE of the noise (a periodic record: k divides its period)."""
    P = int(trace.periodic_samples or 0)
    k_max = math.ceil((P or len(trace.time)) / samples)
    for k in range(k_max, 1, -1):
        if P and P % k:
            continue
        if thinned_input_miss(trace, k) <= THINNED_INPUT_SHARE * sigma:
            return k
    return 1


def thinned(trace: Trace, k: int) -> Trace:
    """The record on every k-th sample (search_thinning's k; a periodic record keeps whole periods),
    its input rebuilt between them as thinned_interpolation says."""
    P = int(trace.periodic_samples or 0)
    out = _samples_of(trace, _kept_samples(len(trace.time), k, bool(P), _input_corners(trace, k)))
    if P:
        out.periodic_samples = P // k
    if trace.input is not None:
        out.meta = {**(trace.meta if isinstance(trace.meta, dict) else {}),
                    "input_interpolation": thinned_interpolation(trace, k)}
    return out
