"""The bench scripts measure the checkout they are run from.

``use()`` puts this checkout's python/, python_tests/ and bench/ first on sys.path and checks that
``tether`` is then imported from this checkout's python/. A virtual environment's editable install
of another checkout puts its finder ahead of sys.path, and a script run from a copy of the tree
(a snapshot taken to measure one commit while the work goes on) would silently measure that other
checkout's code; ``use()`` stops the script there, naming both places.
"""
from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def use() -> Path:
    """This checkout's root, once its packages come first (SystemExit naming both places if
    ``tether`` is imported from elsewhere)."""
    for sub in ("python", "python_tests", "bench"):
        path = str(REPO / sub)
        if path in sys.path:
            sys.path.remove(path)
        sys.path.insert(0, path)
    import tether

    got = Path(tether.__file__).resolve().parent
    want = (REPO / "python" / "tether").resolve()
    if got != want:
        raise SystemExit(f"{Path(sys.argv[0]).name}: the package tether is imported from {got}, not from this "
                         f"checkout's {want} (an editable install of another checkout in this Python's "
                         f"environment?): the figures would be that checkout's code. Run it with this "
                         f"checkout's own environment ({REPO / '.venv'}).")
    return REPO
