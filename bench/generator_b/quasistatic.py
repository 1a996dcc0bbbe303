"""Load-controlled tests: the tether carries the applied load at every sample (no inertia).

The elastic law and the hysteresis act in parallel on the elastic strain; the creep strain is in
series, driven by the load alone: elongation = L (eps_el + eps_creep), with
elastic(eps_el) + hysteresis(eps_el) = load. Between two samples the load, and so the elastic
strain, moves one way, which makes the hysteresis force an explicit function of the end strain
(Dahl's exact branch, the plays' clip); each sample is one monotone scalar root.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from .laws import DahlHysteresis, StopBankHysteresis, elastic_strain_for


def elastic_strains(elastic, hysteresis, load: np.ndarray) -> np.ndarray:
    """Elastic strain at every sample; hysteresis starts relaxed at the first load."""
    eps = np.empty(len(load))
    eps[0] = elastic_strain_for(elastic, float(load[0]))
    z, p = 0.0, [0.0] * (len(hysteresis.radii) if isinstance(hysteresis, StopBankHysteresis) else 0)
    for k in range(1, len(load)):
        e0 = eps[k - 1]

        def total(e: float) -> float:
            return elastic.tension(e) + _hysteresis_force(hysteresis, z, p, e0, e - eps[0], e)

        eps[k] = _monotone_root(total, float(load[k]), e0)
        if isinstance(hysteresis, DahlHysteresis):
            z = hysteresis.branch(z, eps[k] - e0)
        elif isinstance(hysteresis, StopBankHysteresis):
            p = hysteresis.outputs(p, eps[k] - eps[0])
    return eps


def _hysteresis_force(hysteresis, z: float, p: list, e0: float, q: float, e: float) -> float:
    if isinstance(hysteresis, DahlHysteresis):
        return hysteresis.branch(z, e - e0)
    if isinstance(hysteresis, StopBankHysteresis):
        return hysteresis.force(p, q)
    return 0.0


def _monotone_root(total, target: float, start: float) -> float:
    """Root of total(e) = target for an increasing total, searched outward from `start`."""
    gap = total(start) - target
    if gap == 0.0:
        return start
    direction = -1.0 if gap > 0.0 else 1.0
    step = 1e-4
    far = start + direction * step
    while (total(far) - target) * gap > 0.0:
        step *= 2.0
        far = start + direction * step
        if step > 1.0:
            raise ValueError(f"no strain carries the load {target} N from strain {start}")
    lo, hi = sorted((start, far))
    return brentq(lambda e: total(e) - target, lo, hi, xtol=1e-15, rtol=1e-14, maxiter=200)


def elongation(length_m: float, elastic, hysteresis, creep, t: np.ndarray, load: np.ndarray) -> dict:
    """Elongation [m] at the samples, with its elastic and creep parts."""
    eps_el = elastic_strains(elastic, hysteresis, load)
    eps_creep = creep.strain(t, load) if creep is not None else np.zeros(len(t))
    return {"elongation": length_m * (eps_el + eps_creep), "elastic_strain": eps_el, "creep_strain": eps_creep}
