"""tether.discover.evidence.running_max, the regimes' amplitude envelope, is the plain windowed
maximum (a loop) and scipy.ndimage's maximum_filter1d, which it replaced, exactly."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import maximum_filter1d

from tether.discover.evidence import running_max


def _loop(v, w):
    """The maximum of v over [i - w//2, i - w//2 + w), clipped to the record, one sample at a time."""
    n = len(v)
    return np.array([max(v[j] for j in range(max(0, i - w // 2), min(n, i - w // 2 + w))) for i in range(n)])


@pytest.mark.parametrize("n", [1, 2, 3, 7, 40, 101])
@pytest.mark.parametrize("w", [1, 2, 3, 4, 5, 8, 39, 40, 41, 250])
def test_the_windowed_maximum_of_a_loop(n, w):
    rng = np.random.default_rng(7 * n + w)
    for v in (rng.standard_normal(n), np.arange(n, dtype=float), -np.arange(n, dtype=float), np.zeros(n)):
        assert np.array_equal(running_max(v, w), _loop(v, w)), (n, w)


@pytest.mark.parametrize("n, w", [(2001, 3), (2001, 40), (2001, 500), (10001, 2500), (4681, 1171), (16, 4)])
def test_scipy_maximum_filter1d_bit_for_bit(n, w):
    rng = np.random.default_rng(n + w)
    t = np.arange(n) * 5e-3
    for v in (np.abs(np.exp(-0.3 * t) * np.sin(9 * t) + 1e-4 * rng.standard_normal(n)), rng.random(n)):
        assert np.array_equal(running_max(v, w), maximum_filter1d(v, size=w)), (n, w)


def test_regimes_no_longer_import_scipy_ndimage():
    """The point of the change: a discovery's evidence does not load scipy.ndimage."""
    import subprocess
    import sys

    code = ("import sys, numpy as np\n"
            "from tether.discover.evidence import regimes\n"
            "from tether.traces import read_trace\n"
            "from pathlib import Path\n"
            "import tether\n"
            "tr = read_trace(Path(tether.__file__).resolve().parents[2] / 'reference_results' / 'discovery' "
            "/ 'freevib_hidden')\n"
            "m = regimes(tr)\n"
            "assert m['large amplitude'].any() and m['small amplitude'].any()\n"
            "print('scipy.ndimage' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
