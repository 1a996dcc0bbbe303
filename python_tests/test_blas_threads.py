"""One BLAS thread for the package's numerical work (tether.blas, docs/speed.md): the command line
limits its own process through the environment; the library limits numpy's and scipy's BLAS only
for the duration of a fit or a discovery and gives the caller's setting back."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg  # noqa: F401 - both BLAS libraries loaded, numpy's and scipy's, as a fit loads them
from threadpoolctl import threadpool_info, threadpool_limits

from tether import blas

REF = Path(__file__).resolve().parents[1] / "reference_results"


def _blas_threads() -> dict:
    """BLAS library file -> its thread count, as threadpoolctl reads it from the libraries."""
    return {d["filepath"]: d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"}


def test_a_fit_runs_on_one_blas_thread_and_gives_the_callers_setting_back():
    from tether.fit import fit_traces

    seen = []
    with threadpool_limits(limits=2, user_api="blas"):      # the caller's setting
        before = _blas_threads()
        fit_traces([REF / "freevib_simplified_0p1669"], "linear", progress=lambda p: seen.append(_blas_threads()))
        after = _blas_threads()
    assert len(before) >= 2 and set(before.values()) == {2}
    assert seen and all(set(s.values()) == {1} for s in seen)
    assert after == before


def test_the_context_restores_the_setting_when_the_block_raises():
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        with pytest.raises(RuntimeError):
            with blas.one_blas_thread():
                assert set(_blas_threads().values()) == {1}
                raise RuntimeError("inside")
        assert _blas_threads() == before


def _child_threads(env: dict, code: str) -> dict:
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


CHILD = ("import json, sys; from tether.blas import limit_process; done = limit_process(); "
         "import numpy, threadpoolctl; "
         "print(json.dumps({'done': done, 'threads': sorted({d['num_threads'] for d in threadpoolctl.threadpool_info() "
         "if d['user_api'] == 'blas'}), 'env': __import__('os').environ.get('OPENBLAS_NUM_THREADS')}))")


def test_the_command_lines_process_limit_is_one_thread_and_a_users_count_stays():
    env = {k: v for k, v in os.environ.items() if k not in blas.THREAD_VARIABLES}
    assert _child_threads(env, CHILD) == {"done": True, "threads": [1], "env": "1"}
    assert _child_threads({**env, "OPENBLAS_NUM_THREADS": "2"}, CHILD) == {"done": True, "threads": [2], "env": "2"}


def test_the_process_limit_changes_nothing_once_numpy_is_loaded():
    env = {k: v for k, v in os.environ.items() if k not in blas.THREAD_VARIABLES}
    code = "import numpy; " + CHILD
    got = _child_threads(env, code)
    assert got["done"] is False and got["env"] is None


def test_the_results_do_not_depend_on_the_number_of_threads():
    """The same fit with the caller's BLAS at 2 threads and at 1: the same numbers, bit for bit
    (the library's limit is a speed-up, never a change of result)."""
    from tether.fit import initial_estimate

    tr = REF / "freevib_full_0p1669"
    with threadpool_limits(limits=2, user_api="blas"):
        a = initial_estimate([tr], "full")
    with threadpool_limits(limits=1, user_api="blas"):
        b = initial_estimate([tr], "full")
    assert a.keys() == b.keys()
    assert all(np.array_equal(a[k], b[k]) for k in a)


def test_threads_started_inside_share_the_limit_and_a_fit_in_another_thread_leaves_the_setting_alone():
    """The limit is the process's: a discovery's fits, in threads it starts, run on one BLAS
    thread; a fit a caller runs in a thread of its own changes nothing (OpenBLAS ignores counts
    set from other threads once the main thread set one)."""
    import threading

    from tether.fit import fit_traces

    seen = {}
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        with blas.one_blas_thread():
            t = threading.Thread(target=lambda: seen.setdefault("inside", set(_blas_threads().values())))
            t.start()
            t.join(60)

        def worker():
            fit_traces([REF / "freevib_simplified_0p1669"], "linear",
                       progress=lambda p: seen.setdefault("worker", set(_blas_threads().values())))
        t = threading.Thread(target=worker)
        t.start()
        t.join(300)
        after = _blas_threads()
    assert seen["inside"] == {1}
    assert seen["worker"] == {2}
    assert after == before
