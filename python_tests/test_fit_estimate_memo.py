"""initial_estimate is computed once per (data, model, fixed values): a discovery asks for the
same starts many times (docs/speed.md). The remembered answer must be the one a fresh computation
gives, for the data and not for the file name, and must not be changed by a caller."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from tether.fit import start as S
from tether.models import parse_model
from tether.traces import read_trace

REF = Path(__file__).resolve().parents[1] / "reference_results"


@pytest.fixture
def counted(monkeypatch):
    """Counts the payload estimates actually computed."""
    calls = []
    real = S.payload_estimate

    def counting(trace, spec):
        calls.append(trace.name)
        return real(trace, spec)
    monkeypatch.setattr(S, "payload_estimate", counting)
    monkeypatch.setattr(S, "_ESTIMATES", {})
    return calls


def test_the_same_data_read_twice_is_estimated_once_and_as_a_fresh_computation(counted):
    a = read_trace(REF / "freevib_full_0p1669")
    b = read_trace(REF / "freevib_full_0p1669")        # another object, the same data
    first = S.initial_estimate([a], "linear+boucwen")
    second = S.initial_estimate([b], "linear+boucwen")
    assert len(counted) == 1
    fresh = S.initial_estimate.__wrapped__([a], parse_model("linear+boucwen"))
    assert first == second == fresh


def test_other_data_another_model_or_other_fixed_values_are_estimated_anew(counted):
    a = read_trace(REF / "freevib_full_0p1669")
    S.initial_estimate([a], "linear")
    S.initial_estimate([a], "cubic")
    S.initial_estimate([a], "linear", {"c0": 1.0})
    moved = dataclasses.replace(a, measured=a.measured + np.r_[1e-9, np.zeros(len(a.measured) - 1)])
    got = S.initial_estimate([moved], "linear")
    assert len(counted) == 4
    assert got == S.initial_estimate.__wrapped__([moved], parse_model("linear"))


def test_a_caller_changing_its_answer_does_not_change_the_next(counted):
    a = read_trace(REF / "freevib_simplified_0p1669")
    first = S.initial_estimate([a], "linear")
    first["EA"] = -1.0
    assert S.initial_estimate([a], "linear")["EA"] > 0
    assert len(counted) == 1


def test_every_field_of_the_data_counts_and_the_file_name_does_not(counted):
    """Fields a trace gains later are in the key without a change here: each one is tried."""
    a = read_trace(REF / "freevib_full_0p1669")
    S.initial_estimate([a], "linear")
    S.initial_estimate([dataclasses.replace(a, stem=a.stem.with_name("other"), description="another")], "linear")
    assert len(counted) == 1
    changed = {"length_m": a.length_m * 1.01, "payload_mass_kg": a.payload_mass_kg * 1.01,
               "gravity_m_s2": 9.8, "initial_displacement_m": a.initial_displacement_m * 0.99}
    for name, value in changed.items():
        S.initial_estimate([dataclasses.replace(a, **{name: value})], "linear")
    assert len(counted) == 1 + len(changed)
