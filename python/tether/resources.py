"""Where the package finds its FMU, its identification engine and its bundled data.

One place for it. Installed from a wheel, everything is inside the package, in ``tether/_data/``
(``KevlarTether.fmu``, ``libtether_identify.so``, ``reference_results/``, ``datasets/``). In a
checkout (an editable install, ``scripts/setup.sh``), ``tether/_data/`` does not exist and the
files are the repository's: ``build/`` (or ``$KT_BUILD_DIR``), ``reference_results/`` and
``datasets/``. Environment variables ``KT_FMU`` and ``KT_IDENTIFY_LIB`` name a file to use instead.
"""

from __future__ import annotations

import os
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
#: the wheel's payload (absent in a checkout)
INSTALLED_DATA = PACKAGE_DIR / "_data"
#: the checkout this package sits in (python/tether -> the repository root), when it is one
REPO_ROOT = PACKAGE_DIR.parents[1]

SETUP_HINT = ("reinstall the package (pip install .), or in the repository run scripts/setup.sh "
              "(or cmake -S . -B build && cmake --build build)")


def build_dir() -> Path:
    """The repository's CMake build directory ($KT_BUILD_DIR, relative to the repository, or build/)."""
    b = Path(os.environ.get("KT_BUILD_DIR", "build"))
    return b if b.is_absolute() else REPO_ROOT / b


def fmu_candidates() -> list[Path]:
    """Where the FMU is looked for, in order."""
    env = os.environ.get("KT_FMU")
    if env:
        return [Path(env)]
    return [INSTALLED_DATA / "KevlarTether.fmu", build_dir() / "KevlarTether.fmu"]


def identify_library_candidates() -> list[Path]:
    """Where libtether_identify.so is looked for, in order."""
    env = os.environ.get("KT_IDENTIFY_LIB")
    if env:
        return [Path(env)]
    b = build_dir()
    return [INSTALLED_DATA / "libtether_identify.so", b / "fmu_src" / "identify" / "libtether_identify.so",
            b / "libtether_identify.so", b / "identify" / "libtether_identify.so"]


def _data_dir(*parts: str) -> Path:
    installed = INSTALLED_DATA.joinpath(*parts)
    return installed if installed.is_dir() else REPO_ROOT.joinpath(*parts)


def reference_results_dir() -> Path:
    """The bundled synthetic traces of the paper's experiments (reference_results/)."""
    return _data_dir("reference_results")


def dataset_dir(name: str) -> Path:
    """A bundled third-party data set, e.g. dataset_dir("boucwen") (datasets/NAME/)."""
    return _data_dir("datasets", name)
