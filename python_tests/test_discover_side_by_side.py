"""Independent fits side by side (tether.discover.fitting._side_by_side): every item fitted once, the
results in the order of the items whatever the order they ran in, and with a cost estimate the
costliest started first, so that a long fit does not start last and run alone at the end."""
from __future__ import annotations

import threading
import time

from tether.discover import fitting


def _recorder(durations: dict):
    started, lock = [], threading.Lock()

    def fit_one(item, own_thread):
        with lock:
            started.append(item)
        time.sleep(durations[item])
        return (item, own_thread)
    return fit_one, started


def test_the_costliest_starts_first_and_the_results_keep_the_items_order(monkeypatch):
    monkeypatch.setattr(fitting, "PARALLEL_FITS", 2)
    durations = {"cubic": 0.01, "boucwen": 0.02, "iwan": 0.05, "slack": 0.0}
    cost = {"cubic": 4, "boucwen": 5, "iwan": 10, "slack": 2}
    fit_one, started = _recorder(durations)
    out = fitting._side_by_side(fit_one, list(durations), cost=cost.get)
    assert out == [(k, True) for k in durations]
    # two at a time: the two costliest first (in either order), then the others as threads come free
    assert set(started[:2]) == {"iwan", "boucwen"} and started[2:] == ["cubic", "slack"]


def test_without_a_cost_the_items_start_in_their_order_and_alone_they_run_on_the_callers_thread(monkeypatch):
    monkeypatch.setattr(fitting, "PARALLEL_FITS", 2)
    fit_one, started = _recorder({"a": 0.02, "b": 0.02, "c": 0.0})
    assert fitting._side_by_side(fit_one, ["a", "b", "c"]) == [("a", True), ("b", True), ("c", True)]
    assert started[2] == "c"
    fit_one, started = _recorder({"a": 0.0})
    assert fitting._side_by_side(fit_one, ["a"], cost=lambda x: 1) == [("a", False)]
    monkeypatch.setattr(fitting, "PARALLEL_FITS", 1)
    fit_one, started = _recorder({"a": 0.0, "b": 0.0})
    assert fitting._side_by_side(fit_one, ["b", "a"], cost={"a": 9, "b": 1}.get) == [("b", False), ("a", False)]
