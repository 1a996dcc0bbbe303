"""Fit model parameters to measured traces: data-based starts, staged Levenberg-Marquardt through
the identification engine (the FMU's own physics), intervals and an identifiability report.

    from tether.fit import fit_traces, write_fit_params
    r = fit_traces([read_trace("train_multisine")], "linear+boucwen", progress=print)
    write_fit_params("P.json", r)          # tether simulate/validate --params P.json read it

How a fit runs
==============
1. **Experiments.** Each trace becomes one engine experiment exactly as :func:`tether.run.simulate`
   drives the FMU: the rig of its experiment, ``L0``, ``m``, ``g``, ``x0``, ``v0`` from its metadata
   (fixed, never fitted; a periodic record starts from rest), its input reconstructed by run.py's
   own helpers (``force`` a cubic spline, periodic for a periodic record; ``load`` PCHIP; the trace's
   ``input_interpolation`` key wins), one solver step sequence per sample like the FMU's.
   A periodic record of K periods is fitted as the mean of its periods with weight sqrt(K): the
   model's output repeats every period, so sum_k |y - m_k|^2 = K |y - mean(m)|^2 + const and the
   optimum, the covariance and the intervals are those of the whole record, at 1/K of the cost.
   Several traces share one parameter set; each trace's residuals are weighted by the inverse of
   its noise level estimated from the data (equal noise: weight 1).
2. **Starts from the data** (:func:`initial_estimate`, no hand-picked values):
   payload traces: equation error ``m x'' + c(x) x' + R(x) + z = f`` with derivatives from a
   Savitzky-Golay filter (periodic records: exact spectral derivatives below the highest excited
   frequency), linear in the stiffness and damping coefficients; with Bouc-Wen, ``z`` is integrated
   along the measured path for (A, beta, gamma) found by a small nonlinear least-squares (several
   data-scaled starts: A a fraction of the stiffness, beta and gamma from the amplitude). The
   cubic's a1, a2, a3 follow from the Taylor coefficients about the balance. Load tests: the static
   law inverted (linear or cubic fit of load against strain); Kawabata's LT, RT and residual strain
   from the cycle's energies; creep compliances by linear least squares on the Kelvin responses.
3. **Stages**: the elastic law and viscous damping first (other effects held at their starts),
   then every free parameter. Free-vibration records use the engine's horizon stages (first part
   of the record, then all of it) against the multimodality of an oscillation in its frequency.
4. **Statistics** at the optimum: standard errors, 95 % intervals (linearized, Student t),
   correlations, and the directions the data do not determine (SVD of the Jacobian), named.

The modules, one job each: :mod:`.parameters` (which parameters are free, their bounds and
scales), :mod:`.kinematics` (noise and motion from the data), :mod:`.equation_error`,
:mod:`.elastic`, :mod:`.iwan_bank`, :mod:`.payload_start`, :mod:`.load_start`, :mod:`.creep_start`
and :mod:`.start` (the starts from the data), :mod:`.experiments` (a trace as an engine
experiment), :mod:`.engine` (the stages and the statistics), :mod:`.result` (what a fit hands
back). This package is the public face: the names below; the rest is imported from its module.
"""

from __future__ import annotations

import sys as _sys

from .. import _CallableModule
from .engine import fit_traces
from ..noise import noise_level
from .parameters import default_free_parameters
from .result import FitError, FitProgress, FitResult, write_fit_params
from .start import initial_estimate

__all__ = ["FitResult", "FitProgress", "FitError", "default_free_parameters", "initial_estimate", "fit_traces",
           "write_fit_params", "noise_level"]

# `tether.fit(...)` calls tether.api.fit (docs/api.md); the package stays a module
_sys.modules[__name__].__class__ = _CallableModule
