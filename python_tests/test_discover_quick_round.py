"""fit_model from several starts: a quick round of a few iterations from each, then one carried to
convergence. A start whose quick fit converged within those iterations has shown its optimum (carried
on, it ends where it is); one stopped at the iteration limit has not. Where the quick round's winner
converged there, the best start still descending races it for as many iterations again, and where it
then leads it is carried to convergence where it gains on the model it extends (whether or not the
winner did; fitting._best_still_descending). Measured on the forced record of Iwan friction with slack
(test_discover's rival law): the estimate's start converged at 6.50 x noise in the quick round, ahead
of three starts still descending at 6.8-11 x that end at 2.7-2.8 x (docs/discovery.md, "The quick
round")."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from tether.discover import fitting

QUICK = 12


def _result(rms: float, status: int, stages=()):
    """What _fit_once returns of a fit (the parts fit_model reads); ``stages``: the engine statuses
    of the stages before the last (tether.fit's stage log)."""
    return SimpleNamespace(rms=rms, status=status, evaluations=10, parameters={"EA": rms}, values={"EA": rms},
                           free=["EA"], std_error={}, unidentifiable=[], predictions=[np.zeros(3)], message="",
                           ci95={}, stages=[{"status": st} for st in (*stages, status)])


def _run(monkeypatch, quick: list, race: dict, full: dict, baseline: float):
    """fit_model with _fit_once stubbed: the quick round returns ``quick`` (per start), a race of twice
    the quick iterations from start i race[i], a fit to convergence from start i full[i]; returns the
    model and the fits beyond the quick round, as (start, 'race' or 'full')."""
    calls = []

    def fake(trace, spec, names, start, sc, max_iterations=None, **kw):
        i = start["i"]
        if max_iterations == QUICK:
            return quick[i], ""
        kind = "race" if max_iterations == 2 * QUICK else "full"
        calls.append((i, kind))
        return (race if kind == "race" else full)[i], ""

    monkeypatch.setattr(fitting, "_fit_once", fake)
    monkeypatch.setattr(fitting, "free_parameters", lambda spec, experiment: ["EA"])
    trace = SimpleNamespace(experiment="forced", time=np.zeros(3))
    spec = SimpleNamespace(for_experiment=lambda e: spec)
    m = fitting.fit_model(trace, spec, (), [{"i": i} for i in range(len(quick))], None, quick_iterations=QUICK,
                          baseline_rms=baseline)
    return m, calls


def test_a_converged_winner_gives_way_to_the_best_start_still_descending(monkeypatch):
    quick = [_result(6.8, 1), _result(11.0, 1), _result(6.5, 0), _result(7.0, 1)]
    m, calls = _run(monkeypatch, quick, race={0: _result(4.0, 1)}, full={0: _result(2.77, 0)},
                    baseline=6.12)                                    # the winner gains nothing
    assert calls == [(0, "race"), (0, "full")]                      # the best still descending
    assert m.rms == 2.77 and m.best_start == 0


def test_a_descending_start_that_converges_in_the_race_is_taken_as_it_is(monkeypatch):
    quick = [_result(6.8, 1), _result(6.5, 0)]
    m, calls = _run(monkeypatch, quick, race={0: _result(3.1, 0)}, full={}, baseline=9.0)
    assert calls == [(0, "race")] and m.rms == 3.1 and m.best_start == 0


def test_a_descending_start_that_leads_without_a_gain_is_not_carried_on(monkeypatch):
    quick = [_result(6.8, 1), _result(6.5, 0)]
    m, calls = _run(monkeypatch, quick, race={0: _result(6.2, 1)}, full={0: _result(1.0, 0)}, baseline=6.2)
    assert calls == [(0, "race")] and m.rms == 6.2 and m.best_start == 0


def test_the_converged_winner_stays_where_the_descending_start_does_not_lead_after_the_race(monkeypatch):
    quick = [_result(6.8, 1), _result(6.5, 0)]
    m, calls = _run(monkeypatch, quick, race={0: _result(6.6, 1)}, full={0: _result(1.0, 0)}, baseline=9.0)
    assert calls == [(0, "race")] and m.rms == 6.5 and m.best_start == 1


def test_a_winner_still_descending_is_carried_on_itself(monkeypatch):
    quick = [_result(6.8, 1), _result(6.5, 1)]
    m, calls = _run(monkeypatch, quick, race={}, full={1: _result(3.0, 0), 0: _result(1.0, 0)}, baseline=9.0)
    assert calls == [(1, "full")] and m.rms == 3.0 and m.best_start == 1


def test_a_winner_cut_at_the_limit_in_an_earlier_stage_is_still_descending(monkeypatch):
    # its last stage converged, but from where the cut stage left it: run longer, it goes elsewhere
    quick = [_result(6.8, 1), _result(6.5, 0, stages=(1,))]
    m, calls = _run(monkeypatch, quick, race={}, full={1: _result(3.0, 0), 0: _result(1.0, 0)}, baseline=9.0)
    assert calls == [(1, "full")] and m.rms == 3.0 and m.best_start == 1
    # and a start cut in an earlier stage races a winner that converged in every stage
    quick = [_result(6.8, 0, stages=(1,)), _result(6.5, 0, stages=(0,))]
    m, calls = _run(monkeypatch, quick, race={0: _result(3.1, 0)}, full={}, baseline=9.0)
    assert calls == [(0, "race")] and m.rms == 3.1 and m.best_start == 0


def test_every_quick_fit_converged_returns_the_winner_as_it_is(monkeypatch):
    quick = [_result(6.8, 0), _result(6.5, 0)]
    m, calls = _run(monkeypatch, quick, race={}, full={}, baseline=6.0)
    assert calls == [] and m.rms == 6.5 and m.best_start == 1
