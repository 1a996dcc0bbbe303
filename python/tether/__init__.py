"""KevlarTether: simulate, validate, fit and discover models of a braided Kevlar tether.

The Python API (docs/api.md)::

    import tether
    trace = tether.read_trace("reference_results/freevib_full_0p1669")
    result = tether.fit(trace, "linear+boucwen")
    prediction = tether.simulate(trace, "linear+boucwen", result.parameters)

``read_trace``, ``Trace``, ``TraceError``, ``simulate``, ``fit`` and ``discover`` are loaded on first
use: ``import tether`` itself imports neither scipy nor matplotlib nor the FMU.
``tether.fit`` and ``tether.discover`` are also the modules of those names (``tether.fit.fit_traces``,
``tether.discover.discovery_document``); calling them calls the API function.
"""

from __future__ import annotations

import importlib
import types

__version__ = "0.1.0"
__all__ = ["read_trace", "Trace", "TraceError", "simulate", "fit", "discover", "__version__"]

#: API name -> (module, attribute), imported on first use
_LAZY = {
    "read_trace": ("traces", "read_trace"),
    "Trace": ("traces", "Trace"),
    "TraceError": ("traces", "TraceError"),
    "simulate": ("api", "simulate"),
}


class _CallableModule(types.ModuleType):
    """A submodule that is also the API function of its name: ``tether.fit(...)`` calls
    :func:`tether.api.fit`, while ``tether.fit.fit_traces`` stays the module's function."""

    def __call__(self, *args, **kwargs):
        from . import api

        return getattr(api, self.__name__.rpartition(".")[2])(*args, **kwargs)


def __getattr__(name: str):
    if name in _LAZY:
        module, attr = _LAZY[name]
        value = getattr(importlib.import_module(f"{__name__}.{module}"), attr)
        globals()[name] = value
        return value
    if name in ("fit", "discover"):
        return importlib.import_module(f"{__name__}.{name}")     # made callable at its own import
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
