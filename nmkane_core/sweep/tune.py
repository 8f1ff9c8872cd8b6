"""Baumgarte gains chosen for a step size and integrator (``nmkane tune``).

The constraint error obeys φ̇ = Γφ (nonholonomic) and ψ̈ = Γ1ψ̇ + Γ2ψ (holonomic); a
fixed-step explicit Runge–Kutta method integrates those modes stably only when every
eigenvalue λ of the error dynamics has λ·Δt inside the method's stability region
|R(z)| ≤ 1, R the stability polynomial of the tableau (R(z) = Σ_k z^k bᵀA^{k−1}𝟙).  On the
real axis that region is an interval [x*, 0]: −2.785 for RK4, about −3.5 for Kutta–Merson
(`real_stability_interval` computes it from the tableau).

`tune` runs candidate gains (log-spaced, inside that region) and picks the one with
the smallest max constraint violation over the horizon, among runs that end ``ok`` and whose
max energy drift stays within ``energy_factor`` × that of the unstabilized run (Γ = Γ1 =
Γ2 = 0).  Γ first (the nonholonomic constraints, Γ1 = Γ2 as given), then Γ1, Γ2 together
(the holonomic ones, with the chosen Γ).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..integrate.methods import Tableau

__all__ = ["Candidate", "TuneResult", "real_stability_interval", "stability_polynomial", "stable_gains", "tune"]


def stability_polynomial(tab: Tableau) -> np.ndarray:
    """Coefficients c_0..c_s (increasing powers) of R(z) = 1 + Σ_k z^k bᵀA^{k−1}𝟙 of an explicit method."""
    A, b = np.asarray(tab.A, float), np.asarray(tab.b, float)
    coef, v = [1.0], np.ones(len(b))
    for _ in range(len(b)):
        coef.append(float(b @ v))
        v = A @ v
    return np.array(coef)


def _R(coef: np.ndarray, z):
    return np.polynomial.polynomial.polyval(z, coef)


def real_stability_interval(tab: Tableau) -> float:
    """x* < 0 with |R(x)| ≤ 1 for every x in [x*, 0] (and not beyond): from the real roots of R ∓ 1."""
    coef = stability_polynomial(tab)
    roots = []
    for shift in (1.0, -1.0):
        c = coef.copy()
        c[0] -= shift
        r = np.polynomial.polynomial.polyroots(c)
        roots += [x.real for x in r if abs(x.imag) < 1e-9 and x.real < -1e-12]
    for x in sorted(roots, reverse=True):
        if abs(_R(coef, x * (1 + 1e-9))) > 1:
            return float(x)
    return -math.inf


def error_eigenvalues(G: float | None, G1: float | None, G2: float | None) -> np.ndarray:
    """Eigenvalues of the scalar error dynamics: Γ, and the roots of s² − Γ1 s − Γ2."""
    out = []
    if G is not None:
        out.append(complex(G))
    if G1 is not None or G2 is not None:
        out += list(np.roots([1.0, -(G1 or 0.0), -(G2 or 0.0)]).astype(complex))
    return np.array(out)


def stable_gains(tab: Tableau, dt: float, G=None, G1=None, G2=None) -> bool:
    """Whether every error eigenvalue λ has Re λ ≤ 0 and λ·dt inside |R| ≤ 1 (with 1e-12 slack)."""
    coef = stability_polynomial(tab)
    lam = error_eigenvalues(G, G1, G2)
    return bool(np.all(lam.real <= 0) and np.all(np.abs(_R(coef, lam * dt)) <= 1 + 1e-12))


@dataclass
class Candidate:
    """One tried gain set and what its run gave."""

    gains: dict
    status: str
    violation: float | None  # max over the stage's constraints of max |violation|
    energy: float | None  # max |ΔE|
    stable: bool
    feasible: bool = False


@dataclass
class TuneResult:
    """The choice (``gains``), the unstabilized reference and every candidate per stage."""

    integrator: str
    dt: float
    interval: float
    reference: dict
    gains: dict = field(default_factory=dict)
    stages: dict[str, list[Candidate]] = field(default_factory=dict)
    chosen: dict[str, Candidate | None] = field(default_factory=dict)
    given: dict[str, Candidate] = field(default_factory=dict)
    final: dict = field(default_factory=dict)
    outside: dict[str, int] = field(default_factory=dict)  # grid points outside the stability region
    energy_factor: float = 10.0


def _metric(row: dict, constraints) -> float | None:
    raw = [row.get(f"max_abs_violation.{c}") for c in constraints]
    vals: list[float] = [v for v in raw if isinstance(v, (int, float)) and math.isfinite(v)]
    return max(vals) if vals and len(vals) == len(constraints) else None


def _candidates(row_list, names, constraints, tab, dt, stage, e_limit):
    out = []
    for r in row_list:
        gains = {n: r[n] for n in names}
        st = (
            stable_gains(tab, dt, G=gains.get("gamma"), G1=gains.get("gamma1"), G2=gains.get("gamma2"))
            if stage == "holonomic" or "gamma" in gains
            else True
        )
        c = Candidate(gains, r["status"], _metric(r, constraints), r.get("max_abs_energy_drift"), st)
        c.feasible = (
            c.status == "ok"
            and c.stable
            and c.violation is not None
            and (e_limit is None or (c.energy is not None and c.energy <= e_limit))
        )
        out.append(c)
    return out


def _pick(cands: list[Candidate]) -> Candidate | None:
    ok = [c for c in cands if c.feasible]
    return min(ok, key=lambda c: (c.violation, sum(abs(v) for v in c.gains.values()))) if ok else None


def tune(base: dict, *, points: int = 10, energy_factor: float = 10.0, executor=None) -> TuneResult:
    """Choose Γ (and Γ1, Γ2) for ``base`` run settings; see the module docstring.

    ``points``: candidates per gain axis (Γ1 × Γ2 is a ``points`` × ``points`` grid, unstable
    pairs skipped); ``energy_factor``: the allowed energy drift as a multiple of the
    unstabilized run's; ``executor``: a sweep executor (default: this process)."""
    from ..run.simulate import simulate

    if not 2 <= points <= 50:
        raise InputError("--points", points, "an integer in [2, 50]")
    if not (energy_factor >= 1 and math.isfinite(energy_factor)):
        raise InputError("--energy-factor", energy_factor, "a finite number ≥ 1")
    search = _Search(base, energy_factor, executor)
    if search.nh:
        search.nonholonomic(points)
    if search.h:
        search.holonomic(points)
    res, current = search.res, search.current
    res.gains = {k: v for k, v in current.items() if (k == "gamma" and search.nh) or (k != "gamma" and search.h)}
    res.final = simulate({**base, **current}, progress=False).summary
    return res


class _Search:
    """One tuning: the plan, the unstabilized reference run, the gains found so far."""

    def __init__(self, base: dict, energy_factor: float, executor):
        from ..run.plan import resolve
        from ..run.simulate import simulate
        from .executors import SerialExecutor

        plan = resolve(base)
        tab = plan.integrator
        if not isinstance(tab, Tableau) or tab.adaptive:
            raise InputError(
                "integrator",
                getattr(tab, "name", tab),
                "a fixed-step method: rk4 | kutta-merson",
                "the gains are tuned for a fixed step size",
            )
        info = plan.info
        self.nh, self.h = list(info.nonholonomic), list(info.holonomic)
        if not self.nh and not self.h:
            raise InputError("system", base["system"], "a system with constraints", "nothing to stabilize")
        self.base, self.tab, self.dt = base, tab, plan.dt
        x = real_stability_interval(tab)
        ref = simulate({**base, "gamma": 0.0, "gamma1": 0.0, "gamma2": 0.0}, progress=False).summary
        e_ref = ref["max_abs_energy_drift"]
        self.e_limit = energy_factor * e_ref if e_ref is not None and e_ref > 0 else None
        self.res = TuneResult(tab.name, self.dt, x, ref, energy_factor=energy_factor)
        self.ex = executor or SerialExecutor()
        self.top = abs(x) / self.dt  # |Γ| at the edge of the real stability interval
        self.given = {k: plan.settings.get(k) for k in ("gamma", "gamma1", "gamma2")}
        self.current = {k: self.given[k] or 0.0 for k in ("gamma", "gamma1", "gamma2")}

    def _run(self, points_list, names, constraints, stage):
        from .executors import batch_size

        rows = []
        start = {**self.base, **self.current}
        for batch in self.ex.rows(start, iter(points_list), batch_size(len(points_list), self.ex.workers)):
            rows += batch
        return _candidates(rows, names, constraints, self.tab, self.dt, stage, self.e_limit)

    def nonholonomic(self, points: int) -> None:
        vals = -np.logspace(-1, math.log10(self.top), points)
        pts = [{"gamma": float(v)} for v in vals]
        mine = {"gamma": float(self.given["gamma"])} if self.given["gamma"] else None
        cands = self._run(pts + ([mine] if mine and mine not in pts else []), ["gamma"], self.nh, "nonholonomic")
        _take_given(self.res, "nonholonomic", cands, mine, mine in pts)
        self.res.chosen["nonholonomic"] = best = _pick(cands)
        if best is not None:
            self.current["gamma"] = best.gains["gamma"]

    def holonomic(self, points: int) -> None:
        g1 = -np.logspace(-1, math.log10(self.top), points)
        g2 = -np.logspace(-1, math.log10(self.top * self.top), points)
        grid = [{"gamma1": float(a), "gamma2": float(b)} for a in g1 for b in g2]
        pts = [p for p in grid if stable_gains(self.tab, self.dt, G1=p["gamma1"], G2=p["gamma2"])]
        self.res.outside["holonomic"] = len(grid) - len(pts)
        given = self.given
        mine = (
            {"gamma1": float(given["gamma1"] or 0.0), "gamma2": float(given["gamma2"] or 0.0)}
            if given["gamma1"] or given["gamma2"]
            else None
        )
        cands = self._run(pts + ([mine] if mine and mine not in pts else []), ["gamma1", "gamma2"], self.h, "holonomic")
        _take_given(self.res, "holonomic", cands, mine, mine in pts)
        self.res.chosen["holonomic"] = best = _pick(cands)
        if best is not None:
            self.current.update(best.gains)


def _take_given(res: TuneResult, stage: str, cands: list[Candidate], mine: dict | None, on_grid: bool) -> None:
    """The stage's candidates, without the user's gains (kept apart) unless they are a grid point."""
    if mine is not None:
        i = next(i for i, c in enumerate(cands) if c.gains == mine)
        res.given[stage] = cands[i] if on_grid else cands.pop(i)
    res.stages[stage] = cands


def rank(result: TuneResult, stage: str) -> tuple[int, int] | None:
    """Where the given gains of a stage stand: (place among feasible candidates, how many)."""
    g = result.given.get(stage)
    if g is None or not g.feasible:
        return None
    better = sum(1 for c in result.stages[stage] if c.feasible and (c.violation or 0.0) < (g.violation or 0.0))
    return better + 1, sum(1 for c in result.stages[stage] if c.feasible) + 1
