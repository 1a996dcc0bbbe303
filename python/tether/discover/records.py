"""What a discovery run records: the candidates of each step, the steps, the removals, the
refinements, and the run itself."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..traces import Trace
from .fitting import ModelFit, model_label
from ..noise import NoiseEstimate


class DiscoveryError(RuntimeError):
    """A discovery run that cannot go on (e.g. the baseline fit fails); one line."""


@dataclass
class CandidateResult:
    effect: str
    model: str
    added_parameters: int
    rms: float
    heldout_rms: float
    bic_change: float
    signature: float
    signature_text: str
    fit: ModelFit = field(repr=False, default=None)
    part_fit: ModelFit = field(repr=False, default=None)
    verdict: str = ""
    accepted: bool = False
    seconds_spent: float | None = None      # kept by forget_curves
    outranked_by: str = ""                  # passed (or was set aside untested), but this effect won the step
    tied_with: str = ""                     # passed, but this other effect did as well: neither was named
    values: dict = field(repr=False, default_factory=dict)   # the fit's parameters, kept by forget_curves
    shape: tuple = ()                       # shape terms freed beyond the law's (ModelFit.shape)

    @property
    def label(self) -> str:
        """The model as OUT.json names it: with the shape terms freed beyond its law's."""
        return model_label(self.model, self.shape)

    def seconds(self) -> float:
        """The time of this candidate's fits (the whole record's and the held-out part's)."""
        if self.seconds_spent is not None:
            return self.seconds_spent
        return (self.fit.seconds if self.fit else 0.0) + (self.part_fit.seconds if self.part_fit else 0.0)

    def forget_curves(self) -> None:
        """Drop the fits (their fitted curves are what weighs), keeping what they cost and their values."""
        self.seconds_spent = self.seconds()
        self.values = dict(self.fit.params) if self.fit is not None and self.fit.ok else {}
        self.fit = self.part_fit = None

    def as_dict(self, sigma: float) -> dict:
        return {"effect": self.effect, "model": self.label, "added_parameters": self.added_parameters,
                "rmse": self.rms, "rmse_over_noise": self.rms / sigma, "heldout_rmse": self.heldout_rms,
                "heldout_rmse_over_noise": self.heldout_rms / sigma, "bic_change": self.bic_change,
                "signature": self.signature, "signature_text": self.signature_text,
                "seconds": self.seconds(),
                "verdict": self.verdict, "accepted": self.accepted}


@dataclass
class Step:
    model_before: str
    rms_before: float
    heldout_before: float
    windows: list
    regimes: dict
    candidates: list                # CandidateResult, best first
    effect: str | None = None       # the effect added (None: the search stopped here)
    evidence: str = ""
    rms_after: float | None = None
    model_after: str | None = None
    retests: list = field(default_factory=list)   # Retest of each effect named before this step's
    cut_short: bool = False         # the time budget ran out while the candidates were fitted


@dataclass
class Retest:
    """An effect named in an earlier step, tested again once a later one is in (the model without
    it refitted): kept, or removed (then a Removal too)."""

    effect: str
    bic_change: float               # BIC with the effect less BIC without it, on the searched samples
    kept: bool
    verdict: str
    beside: str | None = None       # what it was tested beside: None for the step's new effect


@dataclass
class Discovery:
    trace: Trace
    noise: NoiseEstimate
    start_model: str
    fits: list                      # ModelFit of the start model and after each added effect
    steps: list                     # Step per round (the last one may add nothing)
    stop_reason: str
    seconds: float
    heldout_start: float            # time where the held-out part begins [s]
    heldout_spans: list = field(default_factory=list)   # (first, last) time [s] of each held-out stretch
    removals: list = field(default_factory=list)   # effects dropped again (Removal)
    refinements: list = field(default_factory=list)  # shape terms tried at the end (Refinement)
    searched_every: int = 1         # the search ran on every k-th sample (search_thinning)
    nuisance_freed: bool = True     # every fit freed the record's nuisance parameters
    stages: list = field(default_factory=list)  # the search plan's stages that ran, in order (plan.PLAN)

    @property
    def final(self) -> ModelFit:
        return self.fits[-1]

    @property
    def added_effects(self) -> list[str]:
        return effects_added(self.steps, self.final.effects)


def effects_added(steps, final_effects) -> list[str]:
    """The effects of the final model that the steps added, each once, in the order of the addition
    that stands: an effect added, removed by a re-test and added again counts at its last step."""
    out: list[str] = []
    for s in steps:
        if s.effect and s.effect in final_effects:
            if s.effect in out:
                out.remove(s.effect)
            out.append(s.effect)
    return out


@dataclass
class Removal:
    effect: str
    model_before: str
    model_after: str
    rms_before: float
    rms_after: float
    reason: str


@dataclass
class Refinement:
    """One group of shape terms tried on the final model (refine_shapes)."""

    effect: str
    parameters: tuple
    rms_before: float
    rms_after: float
    heldout_before: float
    heldout_after: float
    bic_change: float
    accepted: bool
    verdict: str
    values: dict = field(default_factory=dict)
    law: str = ""                   # "boucwen -> iwan": the effect's law replaced by its rival (rival_law)
    restart: bool = False           # the Iwan bank's idle elements restarted (restart_idle_elements)
    finer: bool = False             # the Iwan bank made finer (finer_bank)

    def as_dict(self, sigma: float) -> dict:
        return {"effect": self.effect, "law": self.law, "restart": self.restart, "finer": self.finer,
                "parameters": list(self.parameters), "rmse_before": self.rms_before, "rmse_after": self.rms_after,
                "rmse_before_over_noise": self.rms_before / sigma, "rmse_after_over_noise": self.rms_after / sigma,
                "heldout_rmse_before": self.heldout_before,
                "heldout_rmse_after": self.heldout_after, "bic_change": self.bic_change,
                "accepted": self.accepted, "verdict": self.verdict, "values": self.values}
