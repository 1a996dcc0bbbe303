"""A trace as one experiment of the identification engine, exactly as tether.run.simulate drives
the FMU (its rig, metadata, reconstructed input; a periodic record as its mean period), and the
model's prediction on the trace's own time grid."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Mapping

import numpy as np

from .. import identify_native as idn
from .. import nuisance as NZ
from ..models import ModelSpec
from ..run import input_pieces, input_interpolation, record_period
from ..traces import Trace
from ..noise import noise_level


@dataclass
class TraceExperiment:
    """A trace and the engine experiment built from it."""

    trace: Trace
    exp: idn.Experiment
    periods: int          # K (periodic records are fitted as their mean period)

    @cached_property
    def noise(self) -> float:
        """The trace's noise level (tether.noise), computed where a fit weighs or reports it: a
        prediction needs none (estimating it costs more than a simulation of a long record)."""
        return noise_level(self.trace)


def trace_experiment(trace: Trace, spec: ModelSpec, settings_extra: Mapping[str, float]) -> TraceExperiment:
    """The engine experiment of ``trace`` under ``spec``: the rig of its experiment, L0 (and m, g,
    x0, v0, line density) from its metadata, the FMU's switches, ``settings_extra`` (held or fixed
    values; nuisance values among them win over the metadata)."""
    sp = spec.for_experiment(trace.experiment)
    settings = {k: float(v) for k, v in sp.switches.items()}
    settings.update({k: float(v) for k, v in settings_extra.items()})
    settings["L0"] = float(trace.length_m)
    P = int(trace.periodic_samples or 0)
    if P and trace.fitted_samples is not None:
        raise ValueError(f"{trace.name}: a periodic record is fitted as its mean period, not on some of its samples")
    if sp.rig == "payload":
        settings.update(m=float(trace.payload_mass_kg), g=float(trace.gravity_m_s2),
                        x0=0.0 if P else float(trace.initial_displacement_m),
                        v0=0.0 if P else float(trace.initial_velocity_m_s),
                        line_density=float(trace.line_density_kg_m))
        # nuisance values given (fixed, or held between stages) win over the trace's metadata
        settings.update({k: float(v) for k, v in settings_extra.items() if k in NZ.NUISANCE})
    t = np.asarray(trace.time, float)
    y = np.asarray(trace.measured, float)
    kind = {None: idn.INPUT_NONE, "force": idn.INPUT_FORCE, "load": idn.INPUT_LOAD}[trace.input_column]
    inp = der = None
    if P:
        K = len(t) // P
        Tp = record_period(t, P)
        tt = t[:P]
        meas = y.reshape(K, P).mean(axis=0)
        if kind != idn.INPUT_NONE:
            inp, der = input_pieces(tt, np.asarray(trace.input, float)[:P], Tp, input_interpolation(trace))
        # the engine closes a period with (t[P-1] - t[0]) P / (P - 1): exact for uniform sampling
        uniform = abs(float(t[P - 1] - t[0]) * P / (P - 1) - Tp) <= 1e-9 * Tp
        if not uniform:
            tt = np.concatenate([tt, tt + Tp])
            meas = np.tile(meas, 2)
            if inp is not None:
                inp, der = np.tile(inp, 2), np.tile(der, (2, 1))
            e = idn.Experiment(tt, settings=settings, input_kind=kind, input=inp, input_der=der,
                               output=trace.measured_column, measured=meas, periodic_samples=P)
            return TraceExperiment(trace, e, K / 2.0)
        e = idn.Experiment(tt, settings=settings, input_kind=kind, input=inp, input_der=der,
                           output=trace.measured_column, measured=meas, periodic_samples=P)
        return TraceExperiment(trace, e, K)
    if kind != idn.INPUT_NONE:
        vals, ders = input_pieces(t, np.asarray(trace.input, float), None, input_interpolation(trace))
        inp = np.append(vals, float(trace.input[-1]))
        der = np.vstack([ders, np.zeros((1, 3))])
    e = idn.Experiment(t, settings=settings, input_kind=kind, input=inp, input_der=der,
                       output=trace.measured_column, measured=y, sample_weight=fitted_weights(trace))
    return TraceExperiment(trace, e, 1)


def fitted_weights(trace: Trace) -> np.ndarray | None:
    """The factor of each sample's residual in a fit: 1 where the fit sees it, 0 in a held-out part
    inside the record (Trace.fitted_samples); None where the fit sees every sample."""
    if trace.fitted_samples is None:
        return None
    w = np.asarray(trace.fitted_samples, bool)
    if w.shape != np.shape(trace.time):
        raise ValueError(f"{trace.name}: fitted_samples has {w.size} entries for {len(trace.time)} samples")
    return w.astype(float)


def fitted_count(trace: Trace) -> int:
    """The samples a fit of ``trace`` sees (Trace.fitted_samples)."""
    return len(trace.time) if trace.fitted_samples is None else int(np.count_nonzero(trace.fitted_samples))


def predict(x: TraceExperiment, params: Mapping[str, float]) -> np.ndarray:
    """The model's measured column with ``params`` on the trace's own time grid (every period of a
    periodic record)."""
    y = idn.simulate(x.exp, params)
    P = int(x.trace.periodic_samples or 0)
    if P:
        return np.tile(y[:P], len(x.trace.time) // P)
    return y
