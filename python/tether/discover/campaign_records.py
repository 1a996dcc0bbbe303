"""The records of a campaign discovery (discover.campaign): each record with its noise and split,
a joint fit, a candidate, a step and the run; the records' checks and their nuisance values baked
into copies of them. The one-record search's are discover.records."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .. import nuisance as NZ
from ..models import ModelSpec
from ..noise import NoiseEstimate
from ..traces import Trace
from .records import DiscoveryError, Refinement, Removal, Retest, effects_added
from .scales import _Scales


@dataclass
class Record:
    """One record of the campaign: the trace, its noise, its held-out split, its scales and the
    current values of its nuisance parameters."""

    trace: Trace
    nuisance: tuple
    noise: NoiseEstimate
    part: Trace                    # the record as the held-out test's fit sees it (samples.heldout_split)
    held: np.ndarray               # the held-out samples (True per sample)
    sc: _Scales
    nz: dict = field(default_factory=dict)
    alone: dict = field(default_factory=dict)   # the start model fitted to this record alone: law and nuisance
    whole: Trace | None = None     # the whole record where the search runs on every k-th sample
    every: int = 1                 # k (samples.search_thinning)

    @property
    def name(self) -> str:
        return self.trace.name

    @property
    def sigma(self) -> float:
        return float(self.noise.sigma)

    @property
    def n(self) -> int:
        return len(self.trace.time)

    @property
    def first(self) -> int:
        """The first held-out sample."""
        return int(np.argmax(self.held))


@dataclass
class CampaignFit:
    """One model fitted to every record of the campaign. ``rms`` is the campaign's error in noise
    units (sqrt of the mean over all samples of (residual / its record's noise)^2), the scale the
    judge reads with sigma = 1; ``rms_records`` each record's own error [its unit]."""

    spec: ModelSpec
    effects: tuple
    params: dict                   # the shared law: every parameter of the model
    free: list                     # the shared law's free names
    rms: float
    rms_records: list
    predicted: list = field(repr=False)
    nz: list = field(default_factory=list)   # per record: its nuisance values in this fit
    n_nuisance: int = 0
    ok: bool = True
    message: str = ""
    seconds: float = 0.0
    shape: tuple = ()              # shape terms freed beyond the law's (Campaign.finer_bank), as ModelFit.shape
    lead: int | None = None        # a candidate's fit: the record it was fitted to alone first (Campaign.lead_fit)

    @property
    def model(self) -> str:
        return self.spec.canonical

    @property
    def n_free(self) -> int:
        return len(self.free) + self.n_nuisance


@dataclass
class CampaignCandidate:
    effect: str
    fit: CampaignFit
    added_parameters: int
    bic_change: float              # on the campaign's error in noise units: the judge's
    records_bic_change: float = float("nan")   # each record's error against its own: the rank (ranked_bic_change)
    verdict: str = ""
    accepted: bool = False
    heldout_rms: float = float("nan")
    tied_with: str = ""            # passed, but this other effect did as well: neither was named (judge)


@dataclass
class CampaignStep:
    effect: str | None
    model_before: str
    model_after: str | None
    rms_before: float              # noise units
    rms_after: float | None
    records_before: list           # per record [its unit]
    records_after: list | None
    revealed_by: list = field(default_factory=list)
    revealed_how: str = ""
    candidates: list = field(default_factory=list)
    fit_before: CampaignFit | None = field(default=None, repr=False)
    fit_after: CampaignFit | None = field(default=None, repr=False)
    retests: list = field(default_factory=list)    # Retest: the effects named before, tested again beside this one
    refit: dict | None = None      # the current model fitted as the candidates are, before they were judged


@dataclass
class CampaignDiscovery:
    records: list
    fits: list
    steps: list
    start_model: str
    stop_reason: str
    seconds: float
    contradicting: list
    alone: dict                    # record name -> its own fit of the final model (the contradiction test)

    @property
    def final(self) -> CampaignFit:
        return self.fits[-1]

    removals: list = field(default_factory=list)   # Removal: an effect a later one made redundant
    refinements: list = field(default_factory=list)  # Refinement: a named effect's wider law tried at the end

    @property
    def added_effects(self) -> list:
        return effects_added(self.steps, self.final.effects)


def _law_only(params: dict, spec: ModelSpec) -> dict:
    return {k: float(v) for k, v in params.items() if k in spec.parameters and k not in NZ.NUISANCE}


class CampaignInputError(DiscoveryError):
    """A campaign that cannot be run as given (the input's fault); ``str(e)`` names the file."""


def check_campaign(traces: Sequence[Trace]) -> None:
    """CampaignInputError naming the file for a campaign it cannot run: fewer than two records,
    one record given twice."""
    if len(traces) < 2:
        raise CampaignInputError("a campaign needs two records or more")
    seen = {}
    for tr in traces:
        key = tr.csv_path.resolve()
        if key in seen:
            raise CampaignInputError(f"{tr.csv_path}: the record is given twice in the campaign (as {seen[key]} "
                                 f"and {tr.stem}); give each record once")
        seen[key] = tr.stem


def in_noise_units(errors: Sequence[float], records: Sequence, counts: Sequence[int] | None = None) -> float:
    """The campaign's error in noise units over ``records``: the RMS over all their samples of each
    residual divided by its record's noise, from each record's RMS error ``errors`` [its unit] on
    ``counts`` samples (default: the whole record's)."""
    counts = [r.n for r in records] if counts is None else counts
    return math.sqrt(sum(k * (e / r.sigma) ** 2 for k, e, r in zip(counts, errors, records)) / sum(counts))


def ranked_bic_change(records: Sequence, before, after, added: int, n: int) -> float:
    """The BIC change that ranks the candidates that pass: each record's error read against its
    own (the sum over records of n ln(rms_after^2 / rms_before^2), the likelihood where each
    record's error variance is its own, estimated, not its noise: Box and Draper's rule for
    responses of unknown error levels), the ``added`` parameters counted once over all ``n`` samples.
    The campaign's error in noise units, which judges, weighs a record by its noise alone: where
    one record is missed far above its noise (a quiet free vibration the shared hysteresis law
    cannot follow), its misfit outweighs the rest and a step would name whatever takes the most
    of it."""
    if not after.ok:
        return float("inf")
    return (sum(r.n * math.log((a / b) ** 2) for r, b, a in zip(records, before.rms_records, after.rms_records))
            + added * math.log(n))
