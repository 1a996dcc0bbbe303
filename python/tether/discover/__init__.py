"""Discovery: which physical effects does a measured trace show that the linear baseline lacks?

Starting from the baseline of the trace format (linear spring, viscous damper, no slack), the
workflow repeats

1. fit the current model to the trace;
2. locate the disagreement: the time windows where the residual stands above the noise, and the
   regimes they fall in (loading or unloading, large or small amplitude, slack, long holds); the
   noise level comes from the data alone (high-order divided differences of the measured column,
   or the difference between periods of a periodic record), never from a fit;
3. rank the candidate effects of the shared vocabulary that the current model lacks and that the
   experiment can reveal: by their signature in the residual (the share of the residual the
   candidate's own extra terms can explain to first order) and by refitting the model with each
   candidate added, judged on the whole record with a penalty per extra parameter and on the last
   part of the record that a fit on the first part did not see;
4. add the winner, with its evidence, and measure the gap again

until the model reproduces the record to within the noise or no candidate earns its parameters.
Then, with the effects named, the shape terms of their laws (SHAPE_TERMS: Bouc-Wen's exponent and
generalized terms, the Iwan slip strains, the tabulated part of c(x)) are freed where the model
still misses the record, kept only when they lower the BIC and do not worsen the held-out
prediction; and a hysteresis named before another effect is fitted once more with its rival law in
its place (rival_law), kept on the same terms. This changes no effect's name.

A long record (more than SEARCH_SAMPLES simulated samples) whose input every k-th sample rebuilds
to within the noise is searched on every k-th sample (search_thinning), and the model found is
fitted once more to the whole record; every error the account reports is the whole record's.

Effects map to model terms as in :mod:`tether.models`: ``nonlinear_stiffness`` -> the cubic law,
``hysteresis`` -> a Bouc-Wen force (in load tests also the Kawabata branches, the better of the two),
``nonlinear_damping`` -> c(x) = c0 + c1|x| + c2 x^2 (and a drag term where the record has one), or
beside it a viscous damping with dry (Coulomb) friction, the better of the two; where the
polynomial closes only part of the gap, the candidate is fitted again with the tabulated c(x)
(Criteria.damping_table_trigger) and competes with the better of the two,
``creep`` -> Kelvin cells and slip, ``slack`` -> no compression (no parameter of its own).

The package, one job per module: ``laws`` (what an effect and a law are), ``scales``,
``samples`` (the held-out part, the thinning), ``fitting``, ``starts``, ``evidence`` (regimes,
windows, signatures), ``judge`` (every threshold of acceptance), ``records``, ``refine`` (shapes),
``rival`` (rival laws, the Iwan stages), ``nuisance`` (the record's nuisance parameters), ``search`` (discover() itself),
``verdicts`` (the verdict on every effect, what remains unexplained) and ``document`` (OUT.json
and the account). docs/discovery.md tells the story. Settings for a run beside others (bench/):
``tether.discover.fitting.ENGINE_OPTIONS`` and ``tether.discover.fitting.PARALLEL_FITS``.
"""

from __future__ import annotations

from .document import account, discovery_document, ordinal
from .evidence import Window, disagreement, regime_table, regimes, signatures
from .fitting import DEFAULT_BUDGET, ENGINE_OPTIONS, ModelFit, fit_model, predict
from .laws import CANDIDATES, candidates, free_parameters
from ..noise import NoiseEstimate, estimate_noise
from .nuisance import nuisance_not_freed, nuisance_parameters, nuisance_section
from .records import CandidateResult, Discovery, DiscoveryError, Refinement, Removal, Step
from .samples import search_thinning, thinned, thinned_input_miss
from .search import discover
from .verdicts import bic_weight, effect_verdicts, unexplained

__all__ = ["CANDIDATES", "DEFAULT_BUDGET", "ENGINE_OPTIONS", "CandidateResult", "Discovery", "DiscoveryError",
           "ModelFit", "NoiseEstimate", "Refinement", "Removal", "Step", "Window", "account", "candidates",
           "disagreement", "discover", "discovery_document", "estimate_noise", "fit_model", "free_parameters",
           "nuisance_not_freed", "nuisance_parameters", "nuisance_section", "ordinal", "predict", "regime_table", "regimes", "search_thinning", "signatures", "thinned",
           "thinned_input_miss",
           "bic_weight", "effect_verdicts", "unexplained"]

# `tether.discover(...)` calls tether.api.discover (docs/api.md); the package stays a package
import sys as _sys  # noqa: E402

from .. import _CallableModule  # noqa: E402

_sys.modules[__name__].__class__ = _CallableModule
