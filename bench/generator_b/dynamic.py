"""Payload on the tether: classical RK4 with fixed substeps, located slack switches and located
velocity reversals.

Elongation u [m], velocity v [m/s], displacement from balance x = u - u_b. The tether pulls the
payload up with T = elastic(eps) + damping(x, v) + hysteresis; gravity and the external force push
it down: m v' = m g + f(t) - T. With slack on, a tether whose T would fall below zero carries
nothing and the payload flies free; the switch is located inside the substep (Brent's method on
the substep's length) and the integration restarts from there in the other mode.

Both hysteresis laws are rate-independent, so they are carried as a memory of the strain path,
not as ODE states: within a substep the strain moves one way (the substep is cut where the
velocity changes sign), and the hysteresis force is then the law's exact function of the strain
reached (Dahl's branch, the stops' clip). This is exact along monotone pieces and has no
stiffness limit, however sharp the friction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import brentq

from .laws import DahlHysteresis, StopBankHysteresis

MAX_SUBSTEP_S = 1e-3   # RK4 error at 1 Hz and this step is ~(2 pi 1e-3)^4 per unit time: negligible
THETA_TOL = 1e-14      # where in a substep a switch or a reversal is located, as a fraction of it


@dataclass
class PayloadModel:
    length_m: float
    mass_kg: float
    gravity: float
    elastic: object
    damping: object
    hysteresis: object | None = None
    slack: bool = False
    u_balance: float = 0.0          # elongation where elastic(u/L) = m g


@dataclass
class DynamicResult:
    t: np.ndarray
    x: np.ndarray                   # displacement from balance at the samples
    v: np.ndarray
    events: list = field(default_factory=list)   # (time, "slack_entry" | "slack_exit")
    slack_time_s: float = 0.0
    starts_slack: bool = False
    min_tension_candidate: float = math.inf


class _System:
    """Right-hand side, tension and hysteresis memory of one model and one input.

    The memory `p` is, for Dahl, [z, strain] at the last cut; for the stop bank, the plays."""

    def __init__(self, model: PayloadModel, force: Callable):
        self.m = model
        self.f = force
        self.L = model.length_m
        self.dahl = model.hysteresis if isinstance(model.hysteresis, DahlHysteresis) else None
        self.stops = model.hysteresis if isinstance(model.hysteresis, StopBankHysteresis) else None
        self.has_memory = model.hysteresis is not None
        self.eps_ref = 0.0

    def initial_memory(self, u: float) -> list:
        self.eps_ref = u / self.L
        if self.dahl is not None:
            return [0.0, self.eps_ref]
        return [0.0] * (len(self.stops.radii) if self.stops is not None else 0)

    def hysteresis_force(self, eps: float, p: list) -> float:
        if self.dahl is not None:
            return self.dahl.branch(p[0], eps - p[1])
        if self.stops is not None:
            return self.stops.force(p, eps - self.eps_ref)
        return 0.0

    def advance_memory(self, p: list, u: float) -> list:
        eps = u / self.L
        if self.dahl is not None:
            return [self.dahl.branch(p[0], eps - p[1]), eps]
        if self.stops is not None:
            return self.stops.outputs(p, eps - self.eps_ref)
        return p

    def tension(self, u: float, v: float, p: list) -> float:
        """Tension the tether would carry (before the slack clamp)."""
        eps = u / self.L
        return (self.m.elastic.tension(eps) + self.m.damping.force(u - self.m.u_balance, v)
                + self.hysteresis_force(eps, p))

    def accel(self, f: float, u: float, v: float, slack: bool, p: list) -> float:
        T = 0.0 if slack else self.tension(u, v, p)
        return self.m.gravity + (f - T) / self.m.mass_kg

    def rk4(self, t: float, y: tuple, h: float, slack: bool, p: list, forces: tuple | None = None) -> tuple:
        """One classical RK4 step; `forces` = f at the start, middle and end (else computed)."""
        if forces is None:
            forces = (float(self.f(t)), float(self.f(t + 0.5 * h)), float(self.f(t + h)))
        fa, fm, fb = forces
        u, v = y
        a = self.accel(fa, u, v, slack, p)
        vb = v + 0.5 * h * a
        b = self.accel(fm, u + 0.5 * h * v, vb, slack, p)
        vc = v + 0.5 * h * b
        c = self.accel(fm, u + 0.5 * h * vb, vc, slack, p)
        vd = v + h * c
        d = self.accel(fb, u + h * vc, vd, slack, p)
        return (u + h / 6.0 * (v + 2 * vb + 2 * vc + vd), v + h / 6.0 * (a + 2 * b + 2 * c + d))


def simulate(model: PayloadModel, t_out: np.ndarray, x0: float, v0: float,
             force: Callable | None = None) -> DynamicResult:
    """Integrate from (x0, v0) at t_out[0] and sample at t_out. Hysteresis starts relaxed there.
    `force(t)` [N] takes a float or an array of times."""
    sys = _System(model, force or (lambda t: 0.0 * np.asarray(t)))
    u = model.u_balance + x0
    y, p = (u, v0), sys.initial_memory(u)
    slack = starts_slack = model.slack and sys.tension(u, v0, p) < 0.0
    res = DynamicResult(t=np.asarray(t_out, float), x=np.empty(len(t_out)), v=np.empty(len(t_out)))
    res.x[0], res.v[0] = x0, v0
    res.min_tension_candidate = sys.tension(u, v0, p)
    n_subs, f = _force_grid(sys.f, res.t)
    base = 0
    for k in range(1, len(t_out)):
        t0, n_sub = float(t_out[k - 1]), int(n_subs[k - 1])
        h = (float(t_out[k]) - t0) / n_sub
        for j in range(n_sub):
            i = base + 2 * j
            y, p, slack = _substep(sys, res, t0 + j * h, y, h, slack, p, (f[i], f[i + 1], f[i + 2]))
            res.min_tension_candidate = min(res.min_tension_candidate, sys.tension(y[0], y[1], p))
        base += 2 * n_sub
        res.x[k], res.v[k] = y[0] - model.u_balance, y[1]
    res.starts_slack = starts_slack
    res.slack_time_s = _slack_time(res.events, starts_slack, t_out[0], t_out[-1])
    return res


def _force_grid(force, t: np.ndarray) -> tuple[np.ndarray, list]:
    """Substeps per sample interval, and the force at every half substep (one vectorized call)."""
    dt = np.diff(t)
    n_subs = np.maximum(1, np.ceil(dt / MAX_SUBSTEP_S - 1e-9)).astype(int)
    counts = 2 * n_subs
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    local = np.arange(counts.sum()) - np.repeat(starts, counts)
    knots = np.append(np.repeat(t[:-1], counts) + np.repeat(0.5 * dt / n_subs, counts) * local, t[-1])
    values = np.asarray(force(knots), float) * np.ones(len(knots))
    return n_subs, values.tolist()


def _slack_time(events: list, starts_slack: bool, t0: float, t_end: float) -> float:
    total, since = 0.0, (t0 if starts_slack else None)
    for t, kind in events:
        if kind == "slack_entry":
            since = t
        elif since is not None:
            total, since = total + t - since, None
    return total + (t_end - since if since is not None else 0.0)


def _wants_switch(slack_mode: bool, tension: float) -> bool:
    return tension > 0.0 if slack_mode else tension < 0.0


def _substep(sys: _System, res: DynamicResult, t: float, y: tuple, h: float, slack: bool, p: list,
             forces: tuple):
    """One substep, cut at every slack switch and velocity reversal inside it."""
    remaining = h
    while remaining > 0.0:
        y1 = sys.rk4(t, y, remaining, slack, p, forces if remaining == h else None)
        switch = sys.m.slack and _wants_switch(slack, sys.tension(y1[0], y1[1], p))
        reversal = sys.has_memory and y[1] * y1[1] < 0.0
        if not (switch or reversal):
            return y1, sys.advance_memory(p, y1[0]), slack
        theta_switch = _switch_fraction(sys, t, y, remaining, slack, p) if switch else math.inf
        theta_rev = _reversal_fraction(sys, t, y, remaining, slack, p) if reversal else math.inf
        theta = min(theta_switch, theta_rev)
        y = sys.rk4(t, y, theta * remaining, slack, p) if theta > 0.0 else y
        if theta_rev <= theta_switch:
            y = (y[0], 0.0)                  # exactly at rest: the next piece starts one way
        p = sys.advance_memory(p, y[0])
        t += theta * remaining
        remaining -= theta * remaining
        if theta_switch < theta_rev:
            slack = not slack
            res.events.append((t, "slack_entry" if slack else "slack_exit"))
    return y, p, slack


def _switch_fraction(sys: _System, t: float, y: tuple, h: float, slack: bool, p: list) -> float:
    """Fraction of the substep where the tension candidate crosses zero (0 if it starts beyond)."""
    def g(theta: float) -> float:
        yy = sys.rk4(t, y, theta * h, slack, p) if theta > 0.0 else y
        return sys.tension(yy[0], yy[1], p)

    g0 = g(0.0)
    if _wants_switch(slack, g0) or g0 == 0.0:
        return 0.0
    return brentq(g, 0.0, 1.0, xtol=THETA_TOL, rtol=4 * np.finfo(float).eps, maxiter=200)


def _reversal_fraction(sys: _System, t: float, y: tuple, h: float, slack: bool, p: list) -> float:
    """Fraction of the substep where the velocity changes sign."""
    return brentq(lambda theta: sys.rk4(t, y, theta * h, slack, p)[1] if theta > 0.0 else y[1],
                  0.0, 1.0, xtol=THETA_TOL, rtol=4 * np.finfo(float).eps, maxiter=200)
