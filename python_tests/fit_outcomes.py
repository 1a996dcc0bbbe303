"""Fits as a table of outcomes, for tests of a discovery stage's own logic: a ModelFit of a model
string at a given error over the noise with a given number of free terms, and the BIC of such a
fit worked by hand (judge._bic's formula written out)."""

from __future__ import annotations

import math

import numpy as np

from tether.discover.fitting import ModelFit
from tether.models import parse_model


def outcome(model: str, effects: tuple, rms_over_noise: float, n_free: int, *, experiment: str,
            sigma: float) -> ModelFit:
    """A fit of ``model`` that ended at ``rms_over_noise`` times ``sigma`` with ``n_free`` terms."""
    return ModelFit(spec=parse_model(model, experiment), effects=effects, params={},
                    free=[f"p{i}" for i in range(n_free)], rms=rms_over_noise * sigma, predicted=np.zeros(3))


def bic_by_hand(rms_over_noise: float, k: int, *, n: int, sigma: float) -> float:
    """n ln(rms^2) + k ln(n)."""
    return n * math.log((rms_over_noise * sigma) ** 2) + k * math.log(n)
