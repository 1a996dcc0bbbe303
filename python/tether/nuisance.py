"""Nuisance parameters: what a record knows imperfectly about its own experiment (docs/nuisance.md).

- ``m``: the effective payload mass (payload rig). The trace's ``payload_mass_kg`` is where it
  starts; a fit keeps it in the band ``payload_mass_kg * (1 +- rel)`` (:func:`mass_bounds`).
- ``x0``, ``v0``: the initial state of a payload record that does not start where its JSON says
  (a forced record cut out of a longer run starts in motion).
- ``last_reversal_beyond``: the rest of that state where the model has an Iwan bank, whose elements
  remember the motion before the record: where it last reversed, as the distance beyond the span
  [-|x0|, |x0|] (Masing's rule gives each element's state from it; a reversal inside the span
  leaves the same state as none; 0 is a payload displaced monotonically from the balance to x0).
- ``offset_measured``, ``offset_input``, ``input_gain``: the measurement (the engine's
  KT_PAR_MEASUREMENT parameters, identify_native.MEASUREMENT_DEFAULTS): the model is driven by
  ``input_gain * recorded input + offset_input`` and the measured column is the model's output
  ``+ offset_measured``. The engine applies them (fit, discover, predict); :func:`drive_input` and
  :func:`measured_output` are the same rule for the FMU's path (tether.run).

Which of them a record can determine, and why the others are refused (:func:`refusal`), rests on
the scaling facts in docs/nuisance.md: on a free vibration every force on the payload scales with
the mass, so the mass is not identifiable beside the law's force parameters; on a forced record
``m x'' = m g + G f - T``, so the mass and the force gain G are one nuisance in two forms.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from .identify_native import MEASUREMENT_DEFAULTS
from .traces import Trace

__all__ = ["NUISANCE", "MEASUREMENT", "STATE", "DEFAULT_MASS_BAND", "INPUT_GAIN_BOUNDS", "mass_band_rel",
           "check_mass_band", "mass_bounds", "mass_form", "refusal", "check_free", "freeable", "stated_values",
           "nuisance_box", "preload_age_box", "preload_age_grid", "relaxed_load_grid", "last_reversal_estimate",
           "last_reversal_grid",
           "drive_input", "measured_output", "moved_statement", "of_params_file"]

#: the measurement parameters and their defaults (the engine's own list)
MEASUREMENT = tuple(MEASUREMENT_DEFAULTS)
#: the initial state of a payload record (the last reversal: the Iwan bank's memory of it)
STATE = ("x0", "v0", "last_reversal_beyond")
#: the initial state of a load-rig record: how long its first load had hung on the tether before it
#: (the creep that preload left, tether.c: preload_creep), and the load the Iwan bank was last
#: unloaded at before it (tether.c: iwan_rig_start)
LOAD_STATE = ("creep_preload_age", "iwan_relaxed_load")
#: the nuisance parameters that belong to one law of the model: name -> (what it is, which law,
#: whether a model has that law)
LAW_STATE = {"last_reversal_beyond": ("the memory of the iwan hysteresis law", "hysteresis",
                                      lambda spec: spec.hysteresis == "iwan"),
             "creep_preload_age": ("the creep a preload left", "creep", lambda spec: bool(spec.creep)),
             "iwan_relaxed_load": ("the load the iwan hysteresis law was last unloaded at", "hysteresis",
                                   lambda spec: spec.hysteresis == "iwan")}
#: every nuisance parameter a fit may free, in report order
NUISANCE = ("m", *STATE, *LOAD_STATE, *MEASUREMENT)
#: half-width of the mass band, relative, where a trace states no mass_uncertainty_rel
DEFAULT_MASS_BAND = 0.3
#: the range a fitted input gain keeps to
INPUT_GAIN_BOUNDS = (0.2, 5.0)


def check_mass_band(rel, where: str = "--mass-band") -> float:
    """``rel`` as a float if it is a number in [0, 1); ValueError naming ``where`` otherwise."""
    try:
        v = float(rel)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: value {rel!r} is not a number; expected a relative half-width in [0, 1), "
                         "e.g. 0.3 for +-30 %") from None
    if not (math.isfinite(v) and 0.0 <= v < 1.0):
        raise ValueError(f"{where}: value {rel!r}; expected a relative half-width in [0, 1), e.g. 0.3 for +-30 % "
                         "(the mass must stay positive)")
    return v


def mass_band_rel(trace: Trace, rel: float | None = None) -> float:
    """The band's half-width relative to payload_mass_kg: ``rel`` if given, else the trace's
    ``mass_uncertainty_rel``, else DEFAULT_MASS_BAND."""
    if rel is not None:
        return check_mass_band(rel)
    if trace.mass_uncertainty_rel is not None:
        return check_mass_band(trace.mass_uncertainty_rel, f"{trace.json_path}: key 'mass_uncertainty_rel'")
    return DEFAULT_MASS_BAND


def mass_bounds(trace: Trace, rel: float | None = None) -> tuple[float, float]:
    """(low, high) of the effective mass: payload_mass_kg * (1 -+ band)."""
    m = float(trace.payload_mass_kg)
    b = mass_band_rel(trace, rel)
    return m * (1.0 - b), m * (1.0 + b)


def law_refusal(name: str, spec) -> str | None:
    """Why ``name`` cannot be freed in a model ``spec`` (a models.ModelSpec) that lacks the law it
    belongs to (LAW_STATE); None if it can."""
    entry = LAW_STATE.get(name)
    if entry is None or entry[2](spec):
        return None
    what, field, _ = entry
    value = getattr(spec, field)
    return f"it is {what}, and the model's {field} is {value if not isinstance(value, bool) else 'off'}"


def refusal(trace: Trace, name: str, free: Sequence[str] = ()) -> str | None:
    """Why ``name`` cannot be freed on ``trace`` (with the other ``free`` names), in a few words;
    None if it can. Only nuisance names are judged."""
    exp = trace.experiment
    periodic = bool(trace.periodic_samples)
    if name == "m":
        if trace.rig == "load":
            return f"the {exp} record runs on the load rig, where the payload mass plays no part"
        if exp == "free_vibration":
            return ("a free vibration cannot determine the mass: every force on the payload scales with it, so "
                    "(s m, s x the law's force parameters) gives the same record")
        if trace.mass_uncertainty_rel == 0:
            return "the trace states mass_uncertainty_rel = 0 (the mass is exact)"
        if "input_gain" in free:
            return ("m and input_gain cannot both be free: (s m, s G, s x the law's force parameters) gives the "
                    "same forced record; free one of them")
    if name in STATE:
        if trace.rig == "load":
            return f"the {exp} record runs on the load rig, which has no payload state"
        if periodic:
            return "a periodic record is fitted in its periodic steady state, which forgets the initial state"
    if name in LOAD_STATE:
        if trace.rig != "load":
            return (f"the {exp} record runs on the payload rig, whose initial state is its payload's (a preload's "
                    "creep and the load the Iwan bank was last unloaded at are a load-rig record's)")
        if not float(trace.input[0]) > 0.0:
            return f"the record's first load is {float(trace.input[0]):g} N: no preload hung before it"
    if name in ("offset_input", "input_gain") and trace.input_column is None:
        return f"a {exp} record has no input"
    if name == "input_gain" and trace.rig == "load":
        return ("on the load rig (s G, s x the law's force parameters) gives the same elongation; the gain of "
                "the load is not identifiable")
    return None


def check_free(traces: Sequence[Trace], free: Sequence[str]) -> None:
    """ValueError, one line naming the trace file, the parameter and why, for the first nuisance
    name in ``free`` that one of ``traces`` cannot determine."""
    names = [n for n in free if n in NUISANCE]
    if not names:
        return
    if len(traces) > 1:
        masses = {float(t.payload_mass_kg or 0.0) for t in traces}
        for n in names:
            if n != "m" or len(masses) > 1:
                raise ValueError(f"{traces[1].json_path}: parameter '{n}': a nuisance parameter belongs to one "
                                 f"record{' (or records of one payload mass)' if n == 'm' else ''}; fit the "
                                 f"{len(traces)} traces one at a time")
    for tr in traces:
        for n in names:
            why = refusal(tr, n, free)
            if why:
                raise ValueError(f"{tr.json_path}: parameter '{n}' cannot be freed: {why}")


def freeable(trace: Trace) -> list[str]:
    """The nuisance names that :func:`refusal` lets a fit free on ``trace`` (m and input_gain are
    both listed where each alone may be free)."""
    return [n for n in NUISANCE if refusal(trace, n) is None]


def mass_form(trace: Trace) -> str | None:
    """Which form of the mass nuisance a fit of ``trace`` should free: on a forced record
    ``input_gain`` where the trace says the force carries an unknown gain (force_gain_known false),
    else ``m`` unless its mass is stated exact (mass_uncertainty_rel 0); None on records where
    neither can be freed (free vibration, load rig) or nothing is uncertain."""
    if trace.experiment != "forced":
        return None
    if not trace.force_gain_known:
        return "input_gain"
    return None if trace.mass_uncertainty_rel == 0 else "m"


#: an initial velocity this many standard errors from zero is motion, not noise (starts_in_motion)
MOTION_STANDARD_ERRORS = 5.0
#: a record started at rest begins at its balance, within this share of its half-swing of its mean
#: (docs/nuisance-discovery.md: how it was chosen)
AWAY_FROM_REST = 0.05
#: the least distance beyond the span at which last_reversal_beyond starts, relative to the
#: record's half-swing, and the backlash that marks the record's first turning point
REVERSAL_START_MIN = 0.1
#: the grid of last_reversal_beyond a fit scans (last_reversal_grid): its finest value relative to
#: the record's span, and the ratio of neighbours
REVERSAL_GRID_FINEST = 1.0 / 64.0
REVERSAL_GRID_RATIO = 0.7


def _initial_slope(trace: Trace) -> tuple[float, float]:
    """The slope of the measured column at its start and its standard error: a quadratic through
    the samples of the first twentieth of the record's dominant period (at least 5 samples)."""
    from .fit.kinematics import dominant_frequency

    t = np.asarray(trace.time, float)
    y = np.asarray(trace.measured, float)
    dt = float(np.median(np.diff(t)))
    f = dominant_frequency(t, y)
    n = min(len(t), max(5, int(round(1.0 / (20.0 * f * dt)))))
    c, cov = np.polyfit(t[:n] - t[0], y[:n], 2, cov="unscaled" if n <= 3 else True)
    return float(c[1]), float(math.sqrt(max(cov[1, 1], 0.0)))


def _initial_velocity(trace: Trace) -> float:
    """The slope of the measured column at its start (_initial_slope)."""
    return _initial_slope(trace)[0]


def starts_in_motion(trace: Trace) -> bool:
    """Whether the record was cut out of a longer run rather than started at rest: its initial
    velocity differs from zero by MOTION_STANDARD_ERRORS of its standard errors or more, or its
    first sample lies AWAY_FROM_REST of its half-swing or more from its mean (a cut near a
    reversal, where the velocity is small)."""
    v, se = _initial_slope(trace)
    y = np.asarray(trace.measured, float)
    half_swing = 0.5 * float(np.ptp(y))
    return abs(v) >= MOTION_STANDARD_ERRORS * se or abs(y[0] - float(np.mean(y))) >= AWAY_FROM_REST * half_swing


def last_reversal_estimate(trace: Trace) -> float:
    """A start for last_reversal_beyond: where a steady oscillation would have last reversed, the
    mirror of the record's first turning point (about its mean), on the side the payload comes
    from; its distance beyond the span [-|x0|, |x0|] at least REVERSAL_START_MIN of the half-swing.
    Not 0: there a reversal on the far side of x0 moves no element, so a fit cannot leave it."""
    y = np.asarray(trace.measured, float)
    x = y - float(np.mean(y))
    half_swing = 0.5 * float(np.ptp(x))
    if half_swing <= 0.0:
        return 0.0
    direction = 1.0 if _initial_velocity(trace) >= 0.0 else -1.0
    turning = first_turning_point(direction * x, REVERSAL_START_MIN * half_swing)
    beyond = max(abs(turning) - abs(x[0]), REVERSAL_START_MIN * half_swing)
    return -direction * beyond


def last_reversal_grid(trace: Trace) -> list[float]:
    """The values of last_reversal_beyond a fit tries before it frees it with the rest: on either
    side, from REVERSAL_GRID_FINEST of the record's span to the span, each REVERSAL_GRID_RATIO of
    the next. The record tells the memory only through the elements its motion slips, so the
    error is flat between values where an element's slip begins or ends: a search by gradients
    stays where it starts, and the grid finds the right stretch first."""
    span = float(np.ptp(np.asarray(trace.measured, float)))
    steps = int(math.ceil(math.log(REVERSAL_GRID_FINEST) / math.log(REVERSAL_GRID_RATIO)))
    sizes = [span * REVERSAL_GRID_RATIO ** i for i in range(steps + 1)]
    return sorted([-d for d in sizes] + sizes)


def first_turning_point(x: np.ndarray, backlash: float) -> float:
    """The running maximum of x where x first falls ``backlash`` below it (x's maximum if never)."""
    peak = np.maximum.accumulate(np.asarray(x, float))
    back = np.nonzero(peak - x >= backlash)[0]
    return float(peak[back[0]] if len(back) else peak[-1])


def stated_values(trace: Trace) -> dict:
    """What the record states (or the tool assumes) for each nuisance parameter of its rig: the
    value a fitted one's change is measured from (the JSON's mass and initial state, no offsets,
    a unit gain)."""
    out = dict(MEASUREMENT_DEFAULTS)
    if trace.rig == "load":
        out.update(creep_preload_age=0.0, iwan_relaxed_load=0.0)
    if trace.rig == "payload":
        out.update(m=float(trace.payload_mass_kg), x0=float(trace.initial_displacement_m),
                   v0=float(trace.initial_velocity_m_s), last_reversal_beyond=0.0)
    return out


def nuisance_box(trace: Trace, name: str, mass_band: float | None = None) -> tuple[float, float, float, str]:
    """(lower, upper, start, scaling) of a free nuisance parameter on ``trace``: the mass in its
    band (start: the trace's), the initial state from the record's start (x0 its first sample, v0
    the slope there), offsets from 0 and the gain from 1 (INPUT_GAIN_BOUNDS)."""
    if name == "m":
        lo, hi = mass_bounds(trace, mass_band)
        return lo, hi, float(trace.payload_mass_kg), "log"
    if name == "x0":
        return -math.inf, math.inf, float(trace.measured[0]), "linear"
    if name == "v0":
        return -math.inf, math.inf, _initial_velocity(trace), "linear"
    if name == "last_reversal_beyond":
        # a reversal more than the record's span beyond it has slipped every element the record's
        # motion moves: the record cannot tell it from a nearer one, and a fit would drift there
        span = float(np.ptp(np.asarray(trace.measured, float)))
        return -span, span, last_reversal_estimate(trace), "linear"
    if name == "creep_preload_age":
        return preload_age_box(trace)
    if name == "iwan_relaxed_load":
        return 0.0, float(np.max(np.asarray(trace.input, float))), 0.0, "linear"
    if name == "input_gain":
        return INPUT_GAIN_BOUNDS[0], INPUT_GAIN_BOUNDS[1], 1.0, "log"
    if name in MEASUREMENT:
        return -math.inf, math.inf, MEASUREMENT_DEFAULTS[name], "linear"
    raise KeyError(f"'{name}' is not a nuisance parameter ({', '.join(NUISANCE)})")


#: the preload's age a fit may reach, relative to the record's duration (beyond: every creep time
#: scale a record can show has run its course); where it starts, relative to the duration
PRELOAD_AGE_LONGEST = 1e2
PRELOAD_AGE_START = 0.0
#: the ratio of neighbours on the grid of preload ages a fit scans (preload_age_grid)
PRELOAD_AGE_GRID_RATIO = 2.0


def preload_age_box(trace: Trace) -> tuple[float, float, float, str]:
    """(lower, upper, start, scaling) of creep_preload_age on a load-rig record: from 0 to
    PRELOAD_AGE_LONGEST times its duration, from PRELOAD_AGE_START of its duration (0: what the
    record states; a fit holds it there while it fits the law, then scans the grid,
    tether.fit.memory.SCANNED_AFTER_LAW), scaled linearly: at a small age the record sees the age
    itself (the cells' creep under the preload grows as the age does), which a log scale would
    hide (python_tests/test_creep_preload.py)."""
    t = np.asarray(trace.time, float)
    span = float(t[-1] - t[0])
    return 0.0, PRELOAD_AGE_LONGEST * span, PRELOAD_AGE_START * span, "linear"


def preload_age_grid(trace: Trace) -> list[float]:
    """The preload ages a fit tries before it frees the age with the rest: 0, then from the
    record's shortest sample interval each PRELOAD_AGE_GRID_RATIO times the last up to the box's
    upper end. Once the preload's age passes a Kelvin cell's time, the cell starts saturated
    whatever the age: the error is flat there, and a search by gradients started on that plateau
    stays on it."""
    hi = preload_age_box(trace)[1]
    lo = float(np.min(np.diff(np.asarray(trace.time, float))))
    n = int(math.ceil(math.log(hi / lo) / math.log(PRELOAD_AGE_GRID_RATIO)))
    return [0.0] + [min(lo * PRELOAD_AGE_GRID_RATIO ** i, hi) for i in range(n + 1)]


#: the steps of the grid of iwan_relaxed_load a fit scans (relaxed_load_grid) below the first load
#: and above it
RELAXED_LOAD_GRID_STEPS = 4


def relaxed_load_grid(trace: Trace) -> list[float]:
    """The loads the Iwan bank may have been last unloaded at that a fit tries before it frees the
    load with the rest: from 0 (a virgin tether) to the first load (a tether shaken down under it)
    and on to the upper end of its box (nuisance_box: the record's largest load),
    RELAXED_LOAD_GRID_STEPS even steps each way."""
    first, n = max(float(trace.input[0]), 0.0), RELAXED_LOAD_GRID_STEPS
    top = nuisance_box(trace, "iwan_relaxed_load")[1]
    grid = [first * k / n for k in range(n + 1)] + [first + (top - first) * k / n for k in range(1, n + 1)]
    return sorted(set(grid))


def drive_input(recorded: np.ndarray, derivatives: np.ndarray | None, params: Mapping[str, float]):
    """The input and its derivatives that drive the model for a recorded input: input_gain *
    recorded + offset_input, derivatives times input_gain (the engine's set_input)."""
    g = float(params.get("input_gain", MEASUREMENT_DEFAULTS["input_gain"]))
    o = float(params.get("offset_input", MEASUREMENT_DEFAULTS["offset_input"]))
    u = g * np.asarray(recorded, float) + o
    return u, (None if derivatives is None else g * np.asarray(derivatives, float))


def measured_output(model_output: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
    """What the measured column reads for the model's output: + offset_measured."""
    return np.asarray(model_output, float) + float(params.get("offset_measured",
                                                              MEASUREMENT_DEFAULTS["offset_measured"]))


def moved_statement(values: Mapping[str, float], start: Mapping[str, float],
                    intervals: Mapping[str, tuple]) -> list[str]:
    """One line per nuisance parameter in ``values``: where it started, where it ended, the change
    in units of its 95 % interval's width, and whether the interval excludes the start (moved)."""
    lines = []
    for n in NUISANCE:
        if n not in values:
            continue
        v, s = float(values[n]), float(start.get(n, values[n]))
        lo, hi = (float(x) for x in intervals.get(n, (math.nan, math.nan)))
        width = hi - lo
        d = v - s
        widths = d / width if width > 0 else math.inf if d else 0.0
        rel = f" ({d / s:+.1%})" if s else ""
        verdict = "moved" if not (lo <= s <= hi) else "did not move beyond its interval"
        lines.append(f"{n}: {s:.6g} -> {v:.6g}, change {d:+.4g}{rel} = {widths:+.2f} interval widths "
                     f"[{lo:.6g}, {hi:.6g}]: {verdict}")
    return lines


def of_params_file(extra: Mapping, trace: Trace) -> dict | None:
    """The nuisance values a parameter file holds for ``trace`` (its ``extra`` keys, models.ParamsFile),
    None where it holds none for it: they belong to the records they were fitted on. A fit's file
    lists its traces (``traces``) beside the values (``nuisance``: name -> value); a discovery's
    OUT.json names its one record (``trace``) and holds ``nuisance.parameters``: name -> {"value": ...}."""
    section = extra.get("nuisance")
    if not isinstance(section, Mapping) or not section:
        return None
    if isinstance(section.get("parameters"), Mapping):         # a discovery document
        from pathlib import Path

        if Path(str(extra.get("trace", ""))).name != trace.stem.name:
            return None
        return {k: float(v["value"]) for k, v in section["parameters"].items()
                if k in NUISANCE and isinstance(v, Mapping) and "value" in v}
    if trace.stem.name not in set(extra.get("traces") or []):  # a fit's parameter file
        return None
    return {k: float(v) for k, v in section.items() if k in NUISANCE}
