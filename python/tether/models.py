"""Model strings and parameter files.

Model strings
=============
A model is a preset, optionally followed by effects or laws joined with ``+``::

    linear                    linear spring EA + viscous damper c0 (the trace-format baseline)
    cubic                     cubic tension-strain law a1 a2 a3 (power term pow_F pow_eps pow_n, off
                              unless pow_F > 0) + viscous damper
    simplified                cubic + displacement-dependent damping c(x) (the paper's simplified model)
    kawabata                  Kawabata loading/unloading branches + viscous damper
    full                      cubic + Bouc-Wen + displacement-dependent damping (the paper's full model)

    linear+boucwen, linear+iwan, simplified+slack, cubic+creep+slack, ...

Terms after the preset are effect names of the trace format (``nonlinear_stiffness`` = cubic,
``hysteresis`` = boucwen, ``nonlinear_damping`` = displacement-dependent damping, ``creep``,
``slack``) or specific laws (``cubic``, ``exponential``: T = exp_F (exp(eps/exp_eps) - 1), ``bilinear``:
a toe of stiffness toe_EA up to the strain toe_eps, then EA, the corner rounded over toe_width, ``boucwen``,
``kawabata``, ``iwan``: inter-fibre friction, a bank of Jenkins elements beside the elastic law;
``primary_creep``: creep with primary creep, a power or the logarithm of time, in the slip's place;
``coulomb``: a damping of viscous and dry friction, c0 v + c_coulomb tanh(v / coulomb_v), in the
place of c(x): it damps small amplitudes more than large ones; ``amplitude_damping``: c(.) of the
payload's swing amplitude sqrt(x^2 + (v / omega)^2) in the place of c(|x|)).
A string that starts with an effect or a law builds on ``linear``. Names are case-insensitive. Adding something the model
already has, or two hysteresis laws, or the Kawabata law (which replaces the elastic law) together
with another elastic law than the linear one, is an error.

Every model switches slack and creep off unless they are added: the baseline of the trace format
is a linear spring that also carries compression.

Effects of a model (for reports) use the trace-format names; the Kawabata law counts as both
``nonlinear_stiffness`` (its power-law loading branch) and ``hysteresis``.

Parameter files
===============
``--params FILE.json`` holds either the canonical form written by :func:`write_params`::

    {"format": "tether-params/1", "model": "linear+boucwen", "parameters": {"EA": 5e4, "c0": 10}, ...}

(schema: docs/schemas/tether-params-1.schema.json; ``format`` is written, not required on reading;
the intervals of a fit are ``intervals``, and an older file's ``ci95`` is read as ``intervals``)
or a flat object ``{"EA": 5e4, "c0": 10}``. Names must be parameters of the FMU (causality
``parameter``); values must be numbers inside the FMU's min/max. The structural switches (rig,
stiffness, damping, hysteresis, creep, slack) come from the model string and may not be set in the
file. ``L0``, ``m``, ``g``, ``x0`` and ``v0`` are accepted, but a trace sets them from its metadata
(``tether.length_m``, ``payload_mass_kg``, ``gravity_m_s2``, initial state) and the trace wins.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Mapping

#: the ``format`` key of a parameter file written by :func:`write_params`
PARAMS_FORMAT = "tether-params/1"

# ---------------------------------------------------------------------------------------------
# values of the FMU's Integer switches (each listed in its description in modelDescription.xml)
RIG = {"element": 1, "payload": 2, "load": 3}
STIFFNESS = {"linear": 1, "cubic": 2, "exponential": 3, "bilinear": 4}
DAMPING = {"viscous": 1, "displacement": 2, "coulomb": 3, "amplitude": 4}
HYSTERESIS = {"none": 1, "kawabata": 2, "boucwen": 3, "iwan": 4}
CREEP_LAW = {"kelvin_slip": 1, "primary": 2}

#: trace-format effect names, in report order
EFFECTS = ("nonlinear_stiffness", "hysteresis", "nonlinear_damping", "creep", "slack")
#: law names that may be added with '+'
LAWS = ("cubic", "exponential", "bilinear", "boucwen", "kawabata", "iwan", "primary_creep", "coulomb", "amplitude_damping")

#: the structural switches: set by the model string, never by a parameter file
SWITCHES = ("rig", "stiffness", "damping", "hysteresis", "creep", "slack", "creep_law")
#: names a trace sets from its metadata (they win over a parameter file)
TRACE_PARAMETERS = ("L0", "m", "g", "x0", "v0", "line_density")

EXPERIMENT_RIG = {"free_vibration": "payload", "forced": "payload", "load_unload": "load", "creep": "load"}

_PARAMS_LINEAR = ("EA",)
_PARAMS_CUBIC = ("a1", "a2", "a3", "pow_F", "pow_eps", "pow_n")
_PARAMS_EXPONENTIAL = ("exp_F", "exp_eps")
_PARAMS_BILINEAR = ("EA", "toe_EA", "toe_eps", "toe_width")
#: each elastic law's parameters
STIFFNESS_PARAMETERS = {"linear": _PARAMS_LINEAR, "cubic": _PARAMS_CUBIC, "exponential": _PARAMS_EXPONENTIAL,
                        "bilinear": _PARAMS_BILINEAR}
_PARAMS_VISCOUS = ("c0",)
_PARAMS_DISPLACEMENT = ("c0", "c1", "c2", "c_table_dx", "c_table_1", "c_table_2", "c_table_3", "c_table_4",
                        "c_table_5", "c_table_6", "c_drag", "c_coulomb", "coulomb_v")
_PARAMS_COULOMB = ("c0", "c_coulomb", "coulomb_v")
#: the damping laws whose coefficient is c0 + c1 a + c2 a^2 (+ a table, drag, friction) of a magnitude
#: a: the displacement |x|, or the payload's swing amplitude (physics/damping.c)
C_OF_MAGNITUDE = ("displacement", "amplitude")
#: each damping law's parameters
DAMPING_PARAMETERS = {"viscous": _PARAMS_VISCOUS, "displacement": _PARAMS_DISPLACEMENT, "coulomb": _PARAMS_COULOMB,
                      "amplitude": _PARAMS_DISPLACEMENT}
_PARAMS_BOUCWEN = ("bw_A", "bw_beta", "bw_gamma", "bw_n", "bw_b2", "bw_b3", "bw_b4", "bw_b5", "bw_b6", "z0")
#: the Iwan bank: element stiffnesses, then their slip strains (IWAN_ELEMENTS of each)
IWAN_ELEMENTS = 16
IWAN_K = tuple(f"iw_k{i}" for i in range(1, IWAN_ELEMENTS + 1))
IWAN_EPS = tuple(f"iw_eps{i}" for i in range(1, IWAN_ELEMENTS + 1))
#: the elements a fit of the Iwan law frees by default, on the estimate's grid of slip strains; the
#: others stay absent (stiffness 0) unless a finer bank is asked for (tether.discover's last stage)
IWAN_FIT_ELEMENTS = 8
IWAN_K_FIT = IWAN_K[:IWAN_FIT_ELEMENTS]
IWAN_EPS_FIT = IWAN_EPS[:IWAN_FIT_ELEMENTS]
_PARAMS_IWAN = IWAN_K + IWAN_EPS
_PARAMS_KAWABATA = ("kaw_LT", "kaw_RT", "kaw_eps_ref", "kaw_F_ref", "kaw_residual")
#: the elastic law's terms (linear, cubic, exponential or bilinear), and each hysteresis law's
ELASTIC_PARAMETERS = _PARAMS_LINEAR + _PARAMS_CUBIC + _PARAMS_EXPONENTIAL + _PARAMS_BILINEAR[1:]
#: the elastic law's terms that are forces (N): a stiffer or softer law scales these, not the power
#: term's reference strain and exponent nor the exponential's strain scale nor the toe's strains
ELASTIC_FORCES = ("EA", "a1", "a2", "a3", "pow_F", "exp_F", "toe_EA")
HYSTERESIS_PARAMETERS = {"kawabata": _PARAMS_KAWABATA, "boucwen": _PARAMS_BOUCWEN, "iwan": _PARAMS_IWAN}
_PARAMS_KELVIN = ("creep_J1", "creep_tau1", "creep_J2", "creep_tau2", "creep_J3", "creep_tau3")
_PARAMS_SLIP = ("slip_capacity0", "slip_rate", "slip_knee", "slip_load_half", "slip_load_exponent",
                "slip_regen_tau", "slip_limit")
_PARAMS_PRIMARY = ("primary_J", "primary_tau", "primary_n")
#: each creep law's parameters: the Kelvin cells, and the slip or the primary creep beside them
CREEP_PARAMETERS = {"kelvin_slip": _PARAMS_KELVIN + _PARAMS_SLIP, "primary": _PARAMS_KELVIN + _PARAMS_PRIMARY}


class ModelError(ValueError):
    """Unknown or inconsistent model string; ``str(e)`` is one line."""


class ParamsError(ValueError):
    """Bad parameter file; ``str(e)`` is one line naming the file, key and value."""


@dataclass(frozen=True)
class ModelSpec:
    """The structural switches of one model (values named as in the FMU switches' descriptions)."""

    stiffness: str = "linear"      # linear | cubic | exponential | bilinear
    damping: str = "viscous"       # viscous | displacement | coulomb | amplitude
    hysteresis: str = "none"       # none | kawabata | boucwen | iwan
    creep: bool = False
    slack: bool = False
    creep_law: str = "kelvin_slip"  # kelvin_slip (Kelvin cells + slip) | primary (Kelvin cells + primary creep)
    rig: str = "payload"           # element | payload | load (follows the experiment)

    # -- derived views ----------------------------------------------------------------------
    @property
    def switches(self) -> dict[str, int | bool]:
        """FMU values of the structural switches: {'rig': 2, 'stiffness': 1, ..., 'slack': False}, and
        the creep law's (creep_law) where it is not the FMU's default, the Kelvin cells and slip."""
        return {"rig": RIG[self.rig], "stiffness": STIFFNESS[self.stiffness], "damping": DAMPING[self.damping],
                "hysteresis": HYSTERESIS[self.hysteresis], "creep": bool(self.creep), "slack": bool(self.slack),
                **({"creep_law": CREEP_LAW[self.creep_law]} if self.creep_law != "kelvin_slip" else {})}

    @property
    def effects(self) -> list[str]:
        """The trace-format effects this model contains, in the order of :data:`EFFECTS`."""
        have = set()
        if self.stiffness != "linear" or self.hysteresis == "kawabata":
            have.add("nonlinear_stiffness")
        if self.hysteresis != "none":
            have.add("hysteresis")
        if self.damping != "viscous":
            have.add("nonlinear_damping")
        if self.creep:
            have.add("creep")
        if self.slack:
            have.add("slack")
        return [e for e in EFFECTS if e in have]

    @property
    def parameters(self) -> list[str]:
        """Names of the FMU parameters that matter for this model (not the trace's L0/m/g/x0/v0)."""
        names: list[str] = []
        if self.hysteresis == "kawabata":
            names += _PARAMS_KAWABATA
        else:
            names += STIFFNESS_PARAMETERS[self.stiffness]
        names += DAMPING_PARAMETERS[self.damping]
        if self.hysteresis == "boucwen":
            names += _PARAMS_BOUCWEN
        if self.hysteresis == "iwan":
            names += _PARAMS_IWAN
        if self.creep:
            names += CREEP_PARAMETERS[self.creep_law]
        return names

    @property
    def canonical(self) -> str:
        """A canonical model string: the largest preset contained, then the rest in fixed order."""
        base = None
        for name in ("full", "simplified", "kawabata", "cubic", "linear"):
            p = PRESETS[name]
            if _contains(self, p):
                base = name
                break
        assert base is not None
        p = PRESETS[base]
        terms = [base]
        if self.stiffness != p.stiffness:
            terms.append(self.stiffness)
        if self.hysteresis != p.hysteresis:
            terms.append(self.hysteresis)
        if self.damping != p.damping:
            terms.append(DAMPING_TERM[self.damping])
        if self.creep and not p.creep:
            terms.append("primary_creep" if self.creep_law == "primary" else "creep")
        if self.slack and not p.slack:
            terms.append("slack")
        return "+".join(terms)

    def __str__(self) -> str:
        return self.canonical

    def for_experiment(self, experiment: str) -> "ModelSpec":
        """The same model on the rig of ``experiment`` (payload: free_vibration/forced; load: load tests)."""
        return replace(self, rig=EXPERIMENT_RIG[experiment])


def _contains(spec: ModelSpec, preset: ModelSpec) -> bool:
    """True if every non-baseline switch of ``preset`` is also set in ``spec``."""
    base = PRESETS["linear"]
    for f in ("stiffness", "damping", "hysteresis", "creep", "slack"):
        pv = getattr(preset, f)
        if pv != getattr(base, f) and getattr(spec, f) != pv:
            return False
    return True


PRESETS: dict[str, ModelSpec] = {
    "linear": ModelSpec(),
    "cubic": ModelSpec(stiffness="cubic"),
    "simplified": ModelSpec(stiffness="cubic", damping="displacement"),
    "kawabata": ModelSpec(hysteresis="kawabata"),
    "full": ModelSpec(stiffness="cubic", damping="displacement", hysteresis="boucwen"),
}

#: the model-string term of each damping law beyond the viscous one
DAMPING_TERM = {"displacement": "nonlinear_damping", "coulomb": "coulomb", "amplitude": "amplitude_damping"}

# term -> (switch field, value)
_TERMS: dict[str, tuple[str, Any]] = {
    "nonlinear_stiffness": ("stiffness", "cubic"),
    "cubic": ("stiffness", "cubic"),
    "exponential": ("stiffness", "exponential"),
    "bilinear": ("stiffness", "bilinear"),
    "hysteresis": ("hysteresis", "boucwen"),
    "boucwen": ("hysteresis", "boucwen"),
    "kawabata": ("hysteresis", "kawabata"),
    "iwan": ("hysteresis", "iwan"),
    "nonlinear_damping": ("damping", "displacement"),
    "coulomb": ("damping", "coulomb"),
    "amplitude_damping": ("damping", "amplitude"),
    "creep": ("creep", True),
    "primary_creep": ("creep", True),
    "slack": ("slack", True),
}


def valid_names() -> str:
    return (f"presets {', '.join(PRESETS)}; effects {', '.join(EFFECTS)}; laws {', '.join(LAWS)}")


def parse_model(text: str, experiment: str | None = None) -> ModelSpec:
    """Parse a model string (see the module docstring). ``experiment`` selects the rig."""
    if not isinstance(text, str) or not text.strip():
        raise ModelError(f"model {text!r}: empty; expected a preset and optional '+effect' terms ({valid_names()})")
    terms = [t.strip().lower() for t in text.split("+")]
    for t in terms:
        if not t:
            raise ModelError(f"model '{text}': empty term between '+'; expected e.g. 'linear+boucwen' ({valid_names()})")
        if t not in PRESETS and t not in _TERMS:
            raise ModelError(f"model '{text}': unknown name '{t}'; valid names: {valid_names()}")
    first = terms[0]
    if first in PRESETS:
        spec = PRESETS[first]
        origin = {f: first for f in ("stiffness", "damping", "hysteresis", "creep", "slack")
                  if getattr(spec, f) != getattr(PRESETS["linear"], f)}
        rest = terms[1:]
    else:
        spec, origin, rest = PRESETS["linear"], {}, terms
    for t in rest:
        if t in PRESETS and t not in _TERMS:
            raise ModelError(f"model '{text}': preset '{t}' may only come first; after it add effects or laws "
                             f"({', '.join(EFFECTS)}; {', '.join(LAWS)})")
        fld, value = _TERMS[t]
        current = getattr(spec, fld)
        if fld in origin:
            if current == value:
                raise ModelError(f"model '{text}': '{t}' is already in the model (from '{origin[fld]}'); "
                                 "name each effect once")
            raise ModelError(f"model '{text}': '{t}' conflicts with '{origin[fld]}' (both set the {fld} law; "
                             "a model has one)")
        spec = replace(spec, **{fld: value})
        if t == "primary_creep":
            spec = replace(spec, creep_law="primary")
        origin[fld] = t
    if spec.hysteresis == "kawabata" and spec.stiffness != "linear":
        a = origin.get("hysteresis", "kawabata")
        b = origin.get("stiffness", spec.stiffness)
        raise ModelError(f"model '{text}': '{a}' conflicts with '{b}': the Kawabata branches replace the elastic "
                         "law (and already give nonlinear stiffness)")
    if experiment is not None:
        if experiment not in EXPERIMENT_RIG:
            raise ModelError(f"experiment '{experiment}' is not known; expected one of {', '.join(EXPERIMENT_RIG)}")
        spec = spec.for_experiment(experiment)
    return spec


# ---------------------------------------------------------------------------------------------
# parameter files
@dataclass
class ParamsFile:
    path: Path
    model: str | None             # the file's model string, if any
    parameters: dict[str, float]
    extra: dict[str, Any]          # other top-level keys of the canonical form


def _show(value: Any) -> str:
    try:
        return json.dumps(value)
    except (TypeError, ValueError):
        return repr(value)


def check_parameters(params: Mapping[str, Any], where: str, description=None) -> dict[str, float]:
    """Check names and values against the FMU's parameters; return {name: float}.

    ``where`` prefixes messages (usually the file name). ``description`` defaults to the FMU's.
    """
    if description is None:
        from .fmu import model_description
        description = model_description()
    fmu_params = description.parameters
    out: dict[str, float] = {}
    for name, value in params.items():
        if name in SWITCHES:
            raise ParamsError(f"{where}: key '{name}': value {_show(value)}; '{name}' is a structural switch, "
                              f"chosen by the model string (--model), not by a parameter file")
        if name == "L0":
            var = description.variables.get("L0")
        else:
            var = fmu_params.get(name)
        if var is None:
            known = sorted(n for n in fmu_params if n not in SWITCHES) + ["L0"]
            raise ParamsError(f"{where}: key '{name}' is not a parameter of the FMU; known parameters: "
                              f"{', '.join(known)}")
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise ParamsError(f"{where}: key '{name}': value {_show(value)} is not a number; expected a number")
        v = float(value)
        if not math.isfinite(v):
            raise ParamsError(f"{where}: key '{name}': value {_show(value)} is not finite; expected a finite number")
        if var.min is not None and v < var.min:
            raise ParamsError(f"{where}: key '{name}': value {_show(value)} is below the minimum {var.min:g} of the "
                              "FMU's parameter")
        if var.max is not None and v > var.max:
            raise ParamsError(f"{where}: key '{name}': value {_show(value)} is above the maximum {var.max:g} of the "
                              "FMU's parameter")
        if var.type in ("Integer", "Enumeration") and not v.is_integer():
            raise ParamsError(f"{where}: key '{name}': value {_show(value)} is not a whole number; '{name}' is an "
                              f"{var.type.lower()}")
        out[name] = v
    return out


def read_params(path: str | os.PathLike, description=None) -> ParamsFile:
    """Read and check a parameter file (canonical or flat form; see the module docstring)."""
    from .filecheck import JSONInputError, input_problem, load_json

    path = Path(path)
    problem = input_problem(path)
    if problem == "not found":
        raise ParamsError(f"{path}: parameter file not found")
    if problem is not None:
        raise ParamsError(f"{path}: {problem}; expected a parameter file (JSON)")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise ParamsError(f"{path}: parameter file not found") from None
    except UnicodeDecodeError as e:
        raise ParamsError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start}); expected a JSON object") from None
    except OSError as e:
        raise ParamsError(f"{path}: cannot be read ({e.strerror})") from None
    if not text.strip():
        raise ParamsError(f"{path}: empty file; expected a JSON object "
                          "{\"model\": ..., \"parameters\": {name: number}} or {name: number}")
    try:
        raw = load_json(text)
    except JSONInputError as e:
        raise ParamsError(f"{path}: {e}") from None
    if not isinstance(raw, dict):
        raise ParamsError(f"{path}: the top level is {type(raw).__name__}; expected a JSON object "
                          "{\"model\": ..., \"parameters\": {name: number}} or {name: number}")
    model = None
    extra: dict[str, Any] = {}
    if "parameters" in raw or "model" in raw:
        params = raw.get("parameters", {})
        if not isinstance(params, dict):
            raise ParamsError(f"{path}: key 'parameters': value {_show(params)[:60]} is not an object; "
                              "expected {name: number}")
        if "model" in raw:
            model = raw["model"]
            if not isinstance(model, str):
                raise ParamsError(f"{path}: key 'model': value {_show(model)} is not a string; expected a model "
                                  f"string such as 'linear+boucwen'")
            try:
                parse_model(model)
            except ModelError as e:
                raise ParamsError(f"{path}: key 'model': {e}") from None
        extra = {k: v for k, v in raw.items() if k not in ("model", "parameters")}
        if "ci95" in extra and "intervals" not in extra:       # the intervals' older name
            extra["intervals"] = extra.pop("ci95")
        prefix = "parameters."
    else:
        params = raw
        prefix = ""
    checked = {}
    for k, v in params.items():
        checked.update(check_parameters({k: v}, f"{path}", description) if not prefix else
                       _check_prefixed(k, v, path, prefix, description))
    return ParamsFile(path=path, model=model, parameters=checked, extra=extra)


def _check_prefixed(k, v, path, prefix, description):
    try:
        return check_parameters({k: v}, str(path), description)
    except ParamsError as e:
        # name the key as it appears in the file: parameters.EA
        msg = str(e).replace(f"key '{k}'", f"key '{prefix}{k}'", 1)
        raise ParamsError(msg) from None


def write_params(path: str | os.PathLike, model: str | ModelSpec | None, params: Mapping[str, float],
                 extra: Mapping[str, Any] | None = None) -> Path:
    """Write the canonical form ``{"format": "tether-params/1", "model": ..., "parameters": {...},
    **extra}`` atomically."""
    path = Path(path)
    doc: dict[str, Any] = {"format": PARAMS_FORMAT}
    if model is not None:
        doc["model"] = model.canonical if isinstance(model, ModelSpec) else str(model)
    doc["parameters"] = {k: float(v) for k, v in params.items()}
    for k, v in (extra or {}).items():
        if k in ("format", "model", "parameters"):
            raise ValueError(f"write_params: extra key '{k}' would overwrite the canonical form")
        doc[k] = v
    text = json.dumps(doc, indent=2, allow_nan=False) + "\n"
    atomic_write_text(path, text)
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically (see :mod:`tether.atomic`)."""
    from .atomic import write_text

    write_text(path, text)
