"""The paper's Figures 2–9 and 11–18, regenerated, and a report of its claims.

``nmkane figures [--out DIR]`` (or :func:`make_figures`) runs every simulation the
figures of Bajodah, Hodges & Chen (2005) need, draws each figure as a PNG with the
paper's caption, axis labels and units, checks the paper's claims against the numbers
measured now, and writes ``report.md``, ``report.html`` and ``report.json``: each figure
beside a table (claim, paper value, measured now, PASS/FAIL), a short "what this shows"
paragraph, and the settings of every run as a CLI command and a REST body.

Choices the paper leaves open (stated again in the report):

* Example 1 (Appell–Hamel): the paper states neither the horizon nor the step of
  Figs. 2–9.  We use 20 s (by then θ has settled and the load has fallen ≈ 50 m) and the
  Kutta–Merson scheme with Δt = 0.01 s, the project's defaults.
* Example 2: every run uses fixed-step Kutta–Merson, as the paper does; 500 s for
  Figs. 11–15 and 17 (the paper's), 1 h for Fig. 16 (the paper's), and 500 s for Fig. 18
  (not stated).  The fine-step reference of Fig. 16 is the minimal equation (137) at
  Δt = 0.001 s.

``quick=True`` shortens what a claim allows: Fig. 18 over 100 s and Fig. 16's reference at
Δt = 0.005 s.  Figs. 11–15 and 17 always run the paper's full 500 s: Fig. 15's bound needs
it, and at Δt = 0.001 s the undamped drift only starts to grow after ≈ 120 s.

The claims are computed by :func:`evaluate_claims` from the runs of :func:`collect_runs`;
the test suite (tests/test_paper_claims.py) asserts them.
"""

from __future__ import annotations

import argparse
import html
import json
import math
import os
import sys
import re
import time
from dataclasses import asdict, dataclass, field
from typing import Callable

import numpy as np

from .errors import NmkaneError

__all__ = ["Claim", "FigureResult", "Report", "Runs", "collect_runs", "evaluate_claims",
           "make_figures", "run_plan", "main", "cli_command", "rest_body"]

#: Horizons and steps (s).  See the module docstring for the reasons.
T_AH = 20.0          # Example 1, Figs. 2–9 (not stated in the paper)
DT_AH = 0.01
T_EX2 = 500.0        # Figs. 11–15, 17 (paper)
T_FIG18_QUICK = 100.0  # Fig. 18 in quick mode
T_FIG16 = 3600.0     # Fig. 16 (paper: 1 h)
T_FIG18 = 500.0      # Fig. 18 (not stated in the paper)
GAINS = {"gamma1": -20.0, "gamma2": -100.0}     # the paper's Γ1 (s⁻¹), Γ2 (s⁻²)
KM = "kutta-merson"
PRECORRECTION_SAMPLES = 500  # states of a projection run re-stepped without correction (Fig. 18)

PASS, FAIL, INFO, NOT_RUN = "PASS", "FAIL", "INFO", "NOT RUN"

#: the REST service's default limits, quoted so the report can say which runs need them raised
from .schema import REST_DEFAULT_LIMITS  # noqa: E402


# --------------------------------------------------------------------------- runs
def run_plan(quick: bool = False) -> dict[str, dict]:
    """Every simulation the figures need, by key: the settings as sent to ``simulate``,
    the CLI or the REST service (omitted fields take the system's defaults, the paper's)."""
    t_short = T_EX2
    t18 = T_FIG18_QUICK if quick else T_FIG18
    ah = {"system": "appell-hamel", "integrator": KM, "dt": DT_AH, "t_final": T_AH, "every": 1}
    sp = {"system": "sliding-particle", "integrator": KM}
    return {
        "ah-nonlinear": {**ah, "model": "nonlinear"},
        "ah-linear": {**ah, "model": "linear"},
        "sp-undamped-dt0.01": {**sp, "formulation": "nonminimal", "dt": 0.01, "t_final": t_short, "every": 2},
        "sp-undamped-dt0.001": {**sp, "formulation": "nonminimal", "dt": 0.001, "t_final": t_short, "every": 20},
        "sp-damped-dt0.001": {**sp, "formulation": "nonminimal", **GAINS, "dt": 0.001, "t_final": T_EX2,
                              "every": 20},
        "sp-1h-minimal": {**sp, "formulation": "minimal", "dt": 0.1, "t_final": T_FIG16, "every": 1},
        "sp-1h-nonminimal": {**sp, "formulation": "nonminimal", "dt": 0.1, "t_final": T_FIG16, "every": 1},
        "sp-1h-damped": {**sp, "formulation": "nonminimal", **GAINS, "dt": 0.1, "t_final": T_FIG16, "every": 1},
        "sp-1h-reference": {**sp, "formulation": "minimal", "dt": 0.005 if quick else 0.001,
                            "t_final": T_FIG16, "every": 20 if quick else 100},
        "sp-fig18-baumgarte": {**sp, "formulation": "nonminimal", **GAINS, "dt": 0.01, "t_final": t18, "every": 1},
        "sp-fig18-blajer": {**sp, "formulation": "nonminimal", "projection": "blajer", "dt": 0.01,
                            "t_final": t18, "every": 1},
        "sp-fig18-yoon": {**sp, "formulation": "nonminimal", "projection": "yoon", "dt": 0.01,
                          "t_final": t18, "every": 1},
        # the weakest member of the projection family: one Newton step with the Jacobian at the
        # uncorrected point, no energy correction (does the conclusion depend on the switches?)
        "sp-fig18-oneshot": {**sp, "formulation": "nonminimal", "projection": "yoon", "projection_iterations": 1,
                             "projection_jacobian": "frozen", "projection_energy": False, "dt": 0.01,
                             "t_final": t18, "every": 1},
    }


#: what each run is, in the report's words
RUN_LABELS = {
    "ah-nonlinear": "Appell–Hamel, nonlinear constraint model NC (57)–(59)",
    "ah-linear": "Appell–Hamel, linear constraint model LC (101), (102), (59)",
    "sp-undamped-dt0.01": "particle, nonminimal, Γ1 = Γ2 = 0, Δt = 0.01 s",
    "sp-undamped-dt0.001": "particle, nonminimal, Γ1 = Γ2 = 0, Δt = 0.001 s",
    "sp-damped-dt0.001": "particle, nonminimal, Γ1 = −20, Γ2 = −100, Δt = 0.001 s",
    "sp-1h-minimal": "particle, minimal (137), Δt = 0.1 s, 1 h (M)",
    "sp-1h-nonminimal": "particle, nonminimal, Γ1 = Γ2 = 0, Δt = 0.1 s, 1 h (N)",
    "sp-1h-damped": "particle, nonminimal, Γ1 = −20, Γ2 = −100, Δt = 0.1 s, 1 h (DN)",
    "sp-1h-reference": "particle, minimal (137), fine step, 1 h (reference)",
    "sp-fig18-baumgarte": "particle, Baumgarte Γ1 = −20, Γ2 = −100, Δt = 0.01 s (1)",
    "sp-fig18-blajer": "particle, post-step projection 'blajer', Δt = 0.01 s (2)",
    "sp-fig18-yoon": "particle, post-step projection 'yoon', Δt = 0.01 s (3)",
    "sp-fig18-oneshot": "particle, projection one-shot (1 Newton step, frozen Jacobian, no energy fix)",
}


@dataclass
class Runs:
    """The runs of :func:`run_plan`, their results, and the runs that could not be made."""

    settings: dict[str, dict]
    results: dict = field(default_factory=dict)          # key -> simulate.Run
    errors: dict[str, str] = field(default_factory=dict)  # key -> why it was not run
    extra: dict = field(default_factory=dict)             # derived measurements (oracle, pre-correction)
    quick: bool = False
    wall_s: float = 0.0

    def __getitem__(self, key):
        if key in self.errors:
            raise KeyError(f"run {key!r} was not made: {self.errors[key]}")
        return self.results[key]

    def ok(self, key) -> bool:
        return key in self.results and self.results[key].status == "ok"


def collect_runs(quick: bool = False, progress: bool | None = None, keys=None) -> Runs:
    """Make the runs (on all cores), then the derived measurements.

    A run whose settings the library refuses (for example a projection it does not offer
    yet) is recorded in ``errors`` instead of stopping the report.
    """
    from .simulate import resolve, simulate_many

    plan = run_plan(quick)
    if keys is not None:
        plan = {k: plan[k] for k in keys}
    runs = Runs(settings=plan, quick=quick)
    t0 = time.perf_counter()
    plans = {}
    for key, settings in plan.items():
        try:
            plans[key] = resolve(settings)
        except NmkaneError as e:
            runs.errors[key] = f"{type(e).__name__}: {e}"
    done = simulate_many(list(plans.values()), workers=min(2, os.cpu_count() or 1), progress=progress)
    runs.results = dict(zip(plans, done))
    for key, run in runs.results.items():
        if run.status != "ok":
            runs.errors.setdefault(key, f"status {run.status}: {run.summary['message']}")
    if "ah-nonlinear" in plan:
        runs.extra["oracle"] = _oracle(runs)
    for key in ("sp-fig18-blajer", "sp-fig18-yoon", "sp-fig18-oneshot"):
        if runs.ok(key):
            runs.extra[f"precorrection:{key}"] = _precorrection(runs[key], runs.settings[key])
    runs.wall_s = time.perf_counter() - t0
    return runs


def _oracle(runs: Runs) -> dict:
    """Kane's minimal equations of Appell–Hamel from sympy's KanesMethod (nmkane_core.oracle,
    an independent derivation), integrated with DOP853 at rtol 1e-11 on the output times."""
    if not runs.ok("ah-nonlinear"):
        return {"error": runs.errors.get("ah-nonlinear", "no nonlinear run")}
    try:
        from scipy.integrate import solve_ivp

        from .oracle import appell_hamel_minimal_rhs

        t_start = time.perf_counter()
        run = runs["ah-nonlinear"]
        names = ("theta", "phi", "x", "y", "z", "u1", "u2", "u3", "u4", "u5")
        s0 = np.array([run.state[n][0] for n in names])
        rhs = appell_hamel_minimal_rhs(**run.settings["params"])
        sol = solve_ivp(rhs, (0.0, float(run.t[-1])), s0, method="DOP853", rtol=1e-11, atol=1e-11,
                        t_eval=run.t)
        if not sol.success:
            return {"error": f"solve_ivp: {sol.message}"}
        state = {n: sol.y[i] for i, n in enumerate(names)}
        diff = {n: float(np.abs(state[n] - run.state[n]).max()) for n in names}
        return {"t": sol.t, "state": state, "max_abs_diff": diff, "wall_s": time.perf_counter() - t_start}
    except Exception as e:  # the oracle is a cross-check; its failure must not hide the figures
        return {"error": f"{type(e).__name__}: {e}"}


def _precorrection(run, settings: dict) -> dict:
    """|φ| one step after corrected states, taken without correction: the violation each
    post-step correction removes.  Sampled every k-th step so that about
    PRECORRECTION_SAMPLES states spread over the whole run (and over the motion's phase)."""
    from .simulate import simulate

    dt = settings["dt"]
    stride = max(1, (len(run.t) - 1) // PRECORRECTION_SAMPLES)
    idx = np.arange(0, len(run.t) - 1, stride)
    names = ("x", "y", "u1", "u2")
    vals = np.empty(idx.size)
    for j, i in enumerate(idx):
        one = simulate({"system": settings["system"], "formulation": settings["formulation"],
                        "integrator": settings["integrator"], "dt": dt, "t_final": dt,
                        "initial": {n: float(run.state[n][i]) for n in names}}, progress=False)
        vals[j] = one.summary["max_abs_violation"]["surface"]
    return {"max": float(vals.max()), "median": float(np.median(vals)), "samples": int(idx.size),
            "stride": stride * int(settings.get("every", 1)), "t": run.t[idx] + dt, "values": vals}


# --------------------------------------------------------------------------- claims
@dataclass
class Claim:
    """One row of the claims table."""

    key: str
    figures: tuple[int, ...]
    claim: str
    paper: str
    measured: str
    status: str                     # PASS | FAIL | INFO | NOT RUN
    values: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        return _fig_label(self.figures)


def _fig_label(figs) -> str:
    figs = list(figs)
    if len(figs) > 2 and figs == list(range(figs[0], figs[-1] + 1)):
        return f"{figs[0]}–{figs[-1]}"
    return ", ".join(str(f) for f in figs)


def _e(v: float) -> str:
    return f"{v:.3g}" if 1e-3 <= abs(v) < 1e4 or v == 0 else f"{v:.2e}"


def _ok(b) -> str:
    return PASS if b else FAIL


def _absmax(v) -> float:
    return float(np.max(np.abs(v))) if len(v) else float("nan")


def _fifths(v):
    """max|v| over the first and the last fifth of the output."""
    n = max(len(v) // 5, 1)
    return _absmax(v[:n]), _absmax(v[-n:])


def _halves(v):
    n = max(len(v) // 2, 1)
    return _absmax(v[:n]), _absmax(v[n:])


def _bounded(v, rel=1.5, floor=1e-14) -> tuple[bool, float, float]:
    """No growth: the second half's max|v| within ``rel`` × the first half's (plus round-off)."""
    a, b = _halves(v)
    return b <= rel * a + floor, a, b


def _drift(run):
    return run.energy - run.energy[0]


def _needs(runs: Runs, *keys) -> str | None:
    missing = [f"{k}: {runs.errors.get(k, 'not in this report')}" for k in keys if not runs.ok(k)]
    return "; ".join(missing) if missing else None


def _claim(runs, key, figures, claim, paper, needs, fn: Callable[[], tuple[str, str, dict]]) -> Claim:
    why = _needs(runs, *needs)
    if why:
        return Claim(key, figures, claim, paper, f"not run — {why}", NOT_RUN)
    measured, status, values = fn()
    return Claim(key, figures, claim, paper, measured, status, values)


def evaluate_claims(runs: Runs) -> list[Claim]:
    """The claims table (the order of the report)."""
    out: list[Claim] = []
    add = out.append

    # ---- Example 1 -------------------------------------------------------------------
    def models_agree():
        nc, lc = runs["ah-nonlinear"], runs["ah-linear"]
        d = {n: _absmax(nc.state[n] - lc.state[n]) for n in nc.state}
        worst = max(d, key=d.get)
        return (f"max difference over {T_AH:g} s: {_e(d[worst])} ({worst}); θ {_e(d['theta'])} rad, "
                f"z {_e(d['z'])} m", _ok(d[worst] < 1e-6), {"max_abs_diff": d})

    add(_claim(runs, "models_same_motion", (2, 3, 4, 5, 6, 7, 8),
               "The nonlinear (NC) and linear (LC) constraint models give the same motion",
               "\"the solutions … should not be different, irrespective of the way the constraint "
               "equations are manipulated\" (§2.5)", ("ah-nonlinear", "ah-linear"), models_agree))

    def oracle():
        o = runs.extra.get("oracle", {"error": "not computed"})
        if "error" in o:
            return f"not run — {o['error']}", NOT_RUN, {}
        worst = max(o["max_abs_diff"], key=o["max_abs_diff"].get)
        v = o["max_abs_diff"][worst]
        return (f"max |NC − KanesMethod| over all 10 states: {_e(v)} ({worst})", _ok(v < 1e-6),
                {"max_abs_diff": o["max_abs_diff"]})

    add(_claim(runs, "matches_kanes_method_oracle", (2, 3, 4, 5, 6, 7, 8),
               "The nonminimal solution agrees with Kane's minimal equations derived independently "
               "(sympy KanesMethod, DOP853, rtol 1e-11)", "— (cross-check, REFERENCE.md)",
               ("ah-nonlinear",), oracle))

    def theta_settles():
        r = runs["ah-nonlinear"]
        th, thd = r.state["theta"], r.state["u1"]
        late = r.t >= r.t[-1] / 2
        change = float(th[late].max() - th[late].min())
        return (f"θ({r.t[-1]:g} s) = {th[-1]:.4f} rad; |θ̇| at the end {_e(abs(thd[-1]))} rad/s; "
                f"θ moves {_e(change)} rad over the second half", _ok(abs(thd[-1]) < 1e-3 and change < 1e-2),
                {"theta_end": float(th[-1]), "theta_dot_end": float(thd[-1]), "theta_change_late": change})

    add(_claim(runs, "theta_reaches_steady_state", (2, 4, 6),
               "θ tends to a constant steady-state value (θ̇ → 0) as the wheel keeps rolling",
               "\"The angle θ tends to reach a constant steady state value\" (text by Fig. 6)",
               ("ah-nonlinear",), theta_settles))

    def load_falls():
        r = runs["ah-nonlinear"]
        phd, z = r.state["u2"], r.state["z"]
        mono = bool(np.all(np.diff(phd) > 0) and np.all(np.diff(z) < 0))
        return (f"φ̇: {phd[0]:.3g} → {phd[-1]:.3g} rad/s, z: {z[0]:.3g} → {z[-1]:.3g} m, "
                f"{'both monotonic' if mono else 'NOT monotonic'}", _ok(mono),
                {"phi_dot": (float(phd[0]), float(phd[-1])), "z": (float(z[0]), float(z[-1]))})

    add(_claim(runs, "load_falls_wheel_speeds_up", (3, 5, 8),
               "The load falls (z decreases) and spins the wheel up (φ̇ increases)",
               "qualitative (Figs. 5, 8; REFERENCE.md)", ("ah-nonlinear",), load_falls))

    def fig9():
        nc = runs["ah-nonlinear"].summary["max_abs_energy_drift"]
        lc = runs["ah-linear"].summary["max_abs_energy_drift"]
        return (f"max|ΔE|: NC {_e(nc)} J, LC {_e(lc)} J (NC/LC = {nc / lc:.2f}); Kutta–Merson, "
                f"Δt = {DT_AH:g} s, {T_AH:g} s", _ok(nc < lc), {"nonlinear": nc, "linear": lc})

    add(_claim(runs, "fig9_nonlinear_energy_drift_below_linear", (9,),
               "Nonlinear constraint model: smaller max|ΔE| than the linear model (same integrator, same Δt)",
               "\"the nonlinearity in the constraint equations subdues the growing deviation in the total "
               "energy\"", ("ah-nonlinear", "ah-linear"), fig9))

    # ---- Example 2: undamped drift -----------------------------------------------------
    def grows(kind):
        def fn():
            vals, parts, ok = {}, [], True
            for dt in (0.01, 0.001):
                r = runs[f"sp-undamped-dt{dt:g}"]
                v = r.violation["surface"] if kind == "phi" else _drift(r)
                first, last = _fifths(v)
                vals[dt] = {"first_fifth": first, "last_fifth": last}
                ok &= last > 3 * first
                parts.append(f"Δt = {dt:g}: {_e(first)} → {_e(last)} (×{last / first:.3g})")
            tf = runs["sp-undamped-dt0.01"].t[-1]
            return (f"max{'|φ|' if kind == 'phi' else '|ΔE|'} first vs last fifth of {tf:g} s: "
                    + "; ".join(parts), _ok(ok), vals)
        return fn

    def smaller(kind):
        def fn():
            key = "surface"
            big = runs["sp-undamped-dt0.01"]
            small = runs["sp-undamped-dt0.001"]
            if kind == "phi":
                b, s = big.summary["max_abs_violation"][key], small.summary["max_abs_violation"][key]
                unit = "m"
            else:
                b, s = big.summary["max_abs_energy_drift"], small.summary["max_abs_energy_drift"]
                unit = "J"
            return (f"Δt = 0.01: {_e(b)} {unit}; Δt = 0.001: {_e(s)} {unit} ({b / s:.3g} times smaller)",
                    _ok(s < b), {"dt0.01": b, "dt0.001": s})
        return fn

    need_u = ("sp-undamped-dt0.01", "sp-undamped-dt0.001")
    add(_claim(runs, "fig11_12_undamped_violation_grows", (11, 12),
               "Without stabilization the constraint violation φ grows with time",
               "\"It is clearly seen that φ grows with time\"", need_u, grows("phi")))
    add(_claim(runs, "fig11_12_smaller_step_smaller_violation", (11, 12),
               "max|φ| is smaller at Δt = 0.001 s than at Δt = 0.01 s",
               "\"Reducing Δt reduces the growth of φ\"", need_u, smaller("phi")))
    add(_claim(runs, "fig13_14_undamped_energy_drift_grows", (13, 14),
               "Without stabilization |ΔE| grows with time",
               "\"The same is concluded for … the energy integral E\"", need_u, grows("energy")))
    add(_claim(runs, "fig13_14_smaller_step_smaller_energy_drift", (13, 14),
               "max|ΔE| is smaller at Δt = 0.001 s than at Δt = 0.01 s",
               "\"The same is concluded for … E\"", need_u, smaller("energy")))

    # ---- Fig. 15 -------------------------------------------------------------------------
    def fig15():
        r = runs["sp-damped-dt0.001"]
        m = r.summary["max_abs_violation"]["surface"]
        ok_b, a, b = _bounded(r.violation["surface"])
        return (f"max|φ| = {m:.3e} m over {r.t[-1]:g} s (every step); max over first/second half "
                f"{a:.3e} / {b:.3e} ({'bounded' if ok_b else 'GROWING'})", _ok(m < 2.0e-11 and ok_b),
                {"max_abs_phi": m, "first_half": a, "second_half": b})

    add(_claim(runs, "fig15_damped_bound", (15,),
               "Γ1 = −20, Γ2 = −100, Δt = 0.001 s, 500 s: φ stays bounded, |φ| < 2.0e−11 m",
               "|φ| < 2.0 × 10⁻¹¹ m (independent Kutta–Merson: ≈ 1.8 × 10⁻¹¹ m)",
               ("sp-damped-dt0.001",), fig15))

    # ---- Fig. 16 -------------------------------------------------------------------------
    need16 = ("sp-1h-minimal", "sp-1h-nonminimal", "sp-1h-damped", "sp-1h-reference")

    def y_range(key):
        y = runs[key].state["y"]
        return float(y.min()), float(y.max())

    def fig16_bowl():
        l0 = runs["sp-1h-damped"].settings["params"]["l0"]
        lo, hi = -0.1 * l0, 1.1 * l0
        dn, m = y_range("sp-1h-damped"), y_range("sp-1h-minimal")
        ok = lo <= dn[0] and dn[1] <= hi and lo <= m[0] and m[1] <= hi
        return (f"y over 1 h: DN [{dn[0]:.3f}, {dn[1]:.3f}] m, M [{m[0]:.3f}, {m[1]:.3f}] m "
                f"(bowl: [0, {l0:g}] m, allowed ±10 %)", _ok(ok), {"damped": dn, "minimal": m})

    add(_claim(runs, "fig16_damped_stays_in_bowl", (16,),
               "Δt = 0.1 s, 1 h: the damped nonminimal (DN) y stays within the bowl's range, "
               "as the minimal (M) one does",
               "DN stays near the surface, M on it (Fig. 16)", need16, fig16_bowl))

    def fig16_drift():
        l0 = runs["sp-1h-nonminimal"].settings["params"]["l0"]
        n = _absmax(runs["sp-1h-nonminimal"].state["y"])
        orders = math.log10(n / l0)
        return (f"N: max|y| = {_e(n)} m = {orders:.1f} orders of magnitude above l0 = {l0:g} m; "
                f"max|φ| {_e(runs['sp-1h-nonminimal'].summary['max_abs_violation']['surface'])} m",
                _ok(orders >= 2), {"max_abs_y": n, "orders": orders})

    add(_claim(runs, "fig16_undamped_drifts_off", (16,),
               "Δt = 0.1 s, 1 h: the undamped nonminimal (N) y drifts off by orders of magnitude",
               "\"the damping of constraint violations is crucial for accurate fast long-term simulations\"",
               need16, fig16_drift))

    def fig16_ref():
        ref = runs["sp-1h-reference"]
        vals, parts = {}, []
        for name, key in (("M", "sp-1h-minimal"), ("N", "sp-1h-nonminimal"), ("DN", "sp-1h-damped")):
            r = runs[key]
            y_ref = np.interp(r.t, ref.t, ref.state["y"])
            last = r.t >= r.t[-1] - 600
            rms = float(np.sqrt(np.mean((r.state["y"][last] - y_ref[last]) ** 2)))
            dE = float(_drift(r)[-1])
            vals[name] = {"rms_last_10min": rms, "energy_drift_end": dE,
                          "y_range_last_10min": (float(r.state["y"][last].min()), float(r.state["y"][last].max()))}
            parts.append(f"{name} {_e(rms)} m (ΔE(1 h) {_e(dE)} J)")
        E0 = float(ref.energy[0])
        ok = vals["DN"]["rms_last_10min"] < vals["N"]["rms_last_10min"] / 100
        return ("RMS of y − y_ref over the last 10 min: " + "; ".join(parts)
                + f"; E0 = {E0:.3g} J. DN is far closer than N, but neither M nor DN tracks the reference's "
                f"phase at Δt = 0.1 s, and DN has lost {abs(vals['DN']['energy_drift_end']) / E0:.0%} of E0 "
                f"(its y swings only over [{vals['DN']['y_range_last_10min'][0]:.2f}, "
                f"{vals['DN']['y_range_last_10min'][1]:.2f}] m at the end)", _ok(ok), vals)

    add(_claim(runs, "fig16_compared_with_fine_reference", (16,),
               "Against a fine-step minimal reference, DN's y error is orders of magnitude below N's",
               "solutions compared with \"the most accurate one obtained from … (137)\"", need16, fig16_ref))

    # ---- Fig. 17 vs 14 -------------------------------------------------------------------
    def fig17():
        d = runs["sp-damped-dt0.001"].summary["max_abs_energy_drift"]
        u = runs["sp-undamped-dt0.001"]
        # same horizon for both: the undamped run may be shorter in quick mode
        dmp = runs["sp-damped-dt0.001"]
        within = dmp.t <= u.t[-1] + 1e-9
        d_same = _absmax(_drift(dmp)[within])
        u_m = u.summary["max_abs_energy_drift"]
        return (f"max|ΔE| at Δt = 0.001 s over {u.t[-1]:g} s: damped {_e(d_same)} J vs undamped {_e(u_m)} J "
                f"(×{d_same / u_m:.3g}); damped over {dmp.t[-1]:g} s: {_e(d)} J", _ok(d_same > u_m),
                {"damped": d_same, "undamped": u_m, "damped_full": d})

    add(_claim(runs, "fig17_damping_increases_energy_error", (14, 17),
               "With Baumgarte damping the energy deviation is larger than without (Fig. 17 vs 14)",
               "\"This deviation represents a deterioration in accuracy compared to the "
               "constraint-unstabilized system for the same Δt\"", ("sp-damped-dt0.001", "sp-undamped-dt0.001"),
               fig17))

    # ---- Fig. 18 -------------------------------------------------------------------------
    f18 = {"Baumgarte": "sp-fig18-baumgarte", "Blajer": "sp-fig18-blajer", "Yoon et al.": "sp-fig18-yoon"}

    def fig18_bounded():
        vals, parts, ok = {}, [], True
        for name, key in f18.items():
            b, a1, a2 = _bounded(runs[key].violation["surface"])
            vals[name] = {"first_half": a1, "second_half": a2, "bounded": b}
            ok &= b
            parts.append(f"{name} {a1:.2e} / {a2:.2e}")
        return "max|φ| first / second half (m): " + "; ".join(parts), _ok(ok), vals

    add(_claim(runs, "fig18_all_bounded", (18,),
               "Δt = 0.01 s: Baumgarte, Blajer and Yoon et al. all keep |φ| bounded",
               "all three bounded (Fig. 18)", tuple(f18.values()), fig18_bounded))

    def fig18_order():
        m = {name: runs[key].summary["max_abs_violation"]["surface"] for name, key in f18.items()}
        pre = {}
        for name, key in f18.items():
            p = runs.extra.get(f"precorrection:{key}")
            if name != "Baumgarte":
                pre[name] = p and {k: p[k] for k in ("max", "median", "samples", "stride")}
        smallest = min(m, key=m.get)
        ok = smallest == "Baumgarte"
        text = "max|φ| (m): " + ", ".join(f"{k} {v:.2e}" for k, v in m.items())
        if all(pre.values()):
            text += (f"; one step before a correction (max over {next(iter(pre.values()))['samples']} "
                     "steps sampled over the run): "
                     + ", ".join(f"{k} {p['max']:.2e}" for k, p in pre.items()))
        one = runs.results.get("sp-fig18-oneshot")
        if one is not None and one.status == "ok":
            m["one-shot"] = one.summary["max_abs_violation"]["surface"]
            text += f"; one-shot variant {m['one-shot']:.2e}"
        if not ok:
            text += (f". DISAGREES with the paper: the post-step corrections hold |φ| at round-off, "
                     f"{m['Baumgarte'] / max(m[smallest], 1e-300):.1e} times below Baumgarte's bound")
        return text, _ok(ok), {"max_abs_phi": m, "precorrection": pre}

    add(_claim(runs, "fig18_baumgarte_smallest_bound", (18,),
               "Baumgarte (Γ1 = −20, Γ2 = −100) gives the smallest |φ| bound of the three",
               "\"Clearly the augmentation of Baumgarte numerical stabilization terms yields better constraint "
               "violation dynamics\"", tuple(f18.values()), fig18_order))
    return out


# --------------------------------------------------------------------------- figures
@dataclass
class FigureSpec:
    number: int
    slug: str
    caption: str            # the paper's caption
    runs: tuple[str, ...]
    draw: Callable          # draw(fig, runs) -> list of notes shown under the plot in the report
    explain: str            # what this shows, in plain words (may use {name} fields from `facts`)
    note: str = ""


@dataclass
class FigureResult:
    number: int
    file: str
    caption: str
    explain: str
    runs: list[str]
    claims: list[Claim]
    note: str = ""
    error: str | None = None


C_NC, C_LC, C_REF = "#1f4e9c", "#e07b00", "#222222"
C_M, C_N, C_DN = "#2a7d2a", "#c0392b", "#1f4e9c"


def _ah_series(ax, runs, name, ylabel, scale=1.0):
    oracle = runs.extra.get("oracle", {})
    drawn = False
    if runs.ok("ah-nonlinear"):
        r = runs["ah-nonlinear"]
        ax.plot(r.t, r.state[name] * scale, color=C_NC, lw=2.2, label="NC (nonlinear constraints)")
        drawn = True
    if runs.ok("ah-linear"):
        r = runs["ah-linear"]
        ax.plot(r.t, r.state[name] * scale, color=C_LC, lw=1.2, ls="--", label="LC (linear constraints)")
        drawn = True
    if "state" in oracle:
        k = max(len(oracle["t"]) // 25, 1)
        ax.plot(oracle["t"][::k], oracle["state"][name][::k] * scale, "o", ms=3.5, mfc="none", color=C_REF,
                label="Kane's minimal eqs. (KanesMethod)")
    ax.set_xlabel("t (s)")
    ax.set_ylabel(ylabel)
    if drawn:
        ax.legend(loc="best", fontsize=8)


def _draw_ah(name, ylabel):
    def draw(fig, runs):
        _ah_series(fig.add_subplot(111), runs, name, ylabel)
    return draw


def _draw_fig6(fig, runs):
    ax = fig.add_subplot(111)
    for key, color, ls, lw, label in (("ah-nonlinear", C_NC, "-", 2.2, "NC"), ("ah-linear", C_LC, "--", 1.2, "LC")):
        if runs.ok(key):
            r = runs[key]
            ax.plot(r.state["phi"], r.state["u1"], color=color, ls=ls, lw=lw, label=label)
    ax.set_xlabel(r"$\phi$ (rad)")
    ax.set_ylabel(r"$\dot{\theta}$ (rad/s)")
    ax.legend(fontsize=8)


def _draw_fig7(fig, runs):
    ax = fig.add_subplot(111)
    for key, color, ls, lw, label in (("ah-nonlinear", C_NC, "-", 2.2, "NC"), ("ah-linear", C_LC, "--", 1.2, "LC")):
        if runs.ok(key):
            r = runs[key]
            ax.plot(r.state["x"], r.state["y"], color=color, ls=ls, lw=lw, label=label)
    if runs.ok("ah-nonlinear"):
        r = runs["ah-nonlinear"]
        marks = [i for i in range(0, len(r.t), max(len(r.t) // 4, 1))]
        for i in marks[1:]:
            ax.annotate(f"t = {r.t[i]:g} s", (r.state["x"][i], r.state["y"][i]), textcoords="offset points",
                        xytext=(8, -4), fontsize=8)
            ax.plot(r.state["x"][i], r.state["y"][i], "o", color=C_NC, ms=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=8, loc="lower left")
    _draw_fig7_inset(ax, runs)


def _draw_fig9(fig, runs):
    ax = fig.add_subplot(111)
    for key, color, ls, lw, label in (("ah-linear", C_LC, "-", 1.6, "LC (linear constraints)"),
                                      ("ah-nonlinear", C_NC, "-", 2.0, "NC (nonlinear constraints)")):
        if runs.ok(key):
            r = runs[key]
            ax.plot(r.t, _drift(r), color=color, ls=ls, lw=lw, label=label)
    ax.axhline(0, color="0.6", lw=0.6)
    ax.set_xlabel("t (s)")
    ax.set_ylabel(r"$\Delta E$ (J)")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
    ax.legend(fontsize=8)


def _draw_ex2(key, what, bound=None):
    """Figs. 11–15, 17: one run, φ or ΔE vs t (as the paper plots it), and below it the
    envelope of |·| on a log axis; ``bound`` = (value, label) draws the paper's bound."""
    def draw(fig, runs):
        gs = fig.add_gridspec(2, 1, height_ratios=(3, 2), hspace=0.08)
        ax = fig.add_subplot(gs[0])
        ax2 = fig.add_subplot(gs[1], sharex=ax)
        if not runs.ok(key):
            ax.text(0.5, 0.5, f"not run: {runs.errors.get(key)}", ha="center", transform=ax.transAxes, wrap=True)
            return
        r = runs[key]
        v = r.violation["surface"] if what == "phi" else _drift(r)
        ax.plot(r.t, v, color=C_NC, lw=0.5)
        ax.axhline(0, color="0.6", lw=0.6)
        ax.set_ylabel(r"$\phi$ (m)" if what == "phi" else r"$\Delta E$ (J)")
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
        ax.tick_params(labelbottom=False)
        a = np.abs(v)
        ax2.semilogy(r.t, np.maximum(a, 1e-300), color=C_NC, lw=0.4, alpha=0.35)
        env_t, env = _envelope(r.t, a, 100)
        ax2.semilogy(env_t, env, color=C_NC, lw=1.6, label="envelope (max per window)")
        hi = max(a.max(), bound[0] if bound else 0.0) * 3
        lo = max(env[env > 0].min() / 3, a.max() * 1e-8) if np.any(env > 0) else hi * 1e-8
        ax2.set_ylim(min(lo, hi / 100), hi)
        if bound:
            for y in (bound[0], -bound[0]):
                ax.axhline(y, color="#c0392b", ls="--", lw=1.0)
            ax2.axhline(bound[0], color="#c0392b", ls="--", lw=1.0, label=bound[1])
        ax2.set_ylabel(r"$|\phi|$ (m)" if what == "phi" else r"$|\Delta E|$ (J)")
        _log_ticks(ax2)
        ax2.set_xlabel("t (s)")
        ax2.legend(fontsize=8, loc="lower right")
    return draw


def _envelope(t, a, n):
    edges = np.linspace(0, len(a), n + 1).astype(int)
    tt, mm = [], []
    for i, j in zip(edges[:-1], edges[1:]):
        if j > i:
            tt.append(t[(i + j - 1) // 2])
            mm.append(a[i:j].max())
    return np.array(tt), np.array(mm)


def _window_range(t, v, n):
    edges = np.linspace(0, len(v), n + 1).astype(int)
    tt, lo, hi = [], [], []
    for i, j in zip(edges[:-1], edges[1:]):
        if j > i:
            tt.append(t[(i + j - 1) // 2])
            lo.append(v[i:j].min())
            hi.append(v[i:j].max())
    return np.array(tt), np.array(lo), np.array(hi)


def _draw_fig16(fig, runs):
    gs = fig.add_gridspec(1, 2, width_ratios=(1.1, 1), wspace=0.25)
    ax = fig.add_subplot(gs[0])
    ax2 = fig.add_subplot(gs[1])
    # left: the whole hour as the range of y per 30 s window (the swings are too fast to draw)
    for key, color, label in (("sp-1h-minimal", C_M, "M minimal"),
                              ("sp-1h-damped", C_DN, "DN damped nonminimal (Γ1 = −20, Γ2 = −100)"),
                              ("sp-1h-nonminimal", C_N, "N nonminimal (Γ1 = Γ2 = 0)")):
        if runs.ok(key):
            r = runs[key]
            tt, lo, hi = _window_range(r.t, r.state["y"], 120)
            if key == "sp-1h-damped":     # hatched, so that M's band shows through
                ax.fill_between(tt / 60, lo, hi, facecolor="none", edgecolor=color, hatch="////", lw=0,
                                label=label)
            else:
                ax.fill_between(tt / 60, lo, hi, color=color, alpha=0.3 if key == "sp-1h-minimal" else 0.8,
                                lw=0, label=label)
            ax.plot(tt / 60, hi, color=color, lw=1.0)
            ax.plot(tt / 60, lo, color=color, lw=1.0)
    ax.axhline(0, color="0.4", lw=0.6, ls=":")
    ax.axhline(1, color="0.4", lw=0.6, ls=":")
    ax.set_yscale("symlog", linthresh=1.0, linscale=1.5)
    ax.set_ylim(-0.3, None)
    ax.set_xlabel("t (min)")
    ax.set_ylabel("y (m): range per 30 s window\n(symlog: linear below 1 m)")
    ax.set_title("the whole hour (bowl: 0 ≤ y ≤ l0 = 1 m, dotted)", fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    # right: the last seconds, sample by sample
    t1 = T_FIG16
    if runs.ok("sp-1h-reference"):
        ref = runs["sp-1h-reference"]
        w = ref.t >= t1 - 8
        ax2.plot(ref.t[w], ref.state["y"][w], color=C_REF, lw=2.6, alpha=0.3,
                 label=f"reference: minimal, Δt = {ref.settings['dt']:g} s")
    for key, color, label in (("sp-1h-minimal", C_M, "M (Δt = 0.1 s)"), ("sp-1h-damped", C_DN, "DN (Δt = 0.1 s)")):
        if runs.ok(key):
            r = runs[key]
            w = r.t >= t1 - 8
            ax2.plot(r.t[w], r.state["y"][w], ".-", color=color, lw=1.0, ms=3.5, label=label)
    ax2.set_xlim(t1 - 8, t1)
    ax2.set_ylim(-0.1, 1.6)
    ax2.set_xlabel("t (s)")
    ax2.set_ylabel("y (m)  (y = 1: bottom of the bowl)")
    ax2.set_title("the last 8 s (N is off the scale)", fontsize=9)
    ax2.legend(fontsize=7, loc="upper center", ncol=2, columnspacing=1.0, handlelength=1.5)


def _draw_fig18(fig, runs):
    gs = fig.add_gridspec(2, 1, height_ratios=(3, 2), hspace=0.1)
    ax = fig.add_subplot(gs[0])
    ax2 = fig.add_subplot(gs[1], sharex=ax)
    series = (("sp-fig18-baumgarte", "#1f4e9c", '"1" Baumgarte (Γ1 = −20, Γ2 = −100)'),
              ("sp-fig18-blajer", "#c0392b", '"2" Blajer (projection preset)'),
              ("sp-fig18-yoon", "#2a7d2a", '"3" Yoon et al. (projection preset)'))
    floor = 1e-17
    missing = []
    window = float("nan")
    for key, color, label in series:
        if not runs.ok(key):
            missing.append(f"{label.split(' (')[0]}: not run ({runs.errors.get(key, '?')[:90]})")
            continue
        r = runs[key]
        a = np.maximum(np.abs(r.violation["surface"]), floor)
        env_t, env = _envelope(r.t, a, 250)
        window = r.t[-1] / 250
        ax.semilogy(env_t, env, color=color, lw=1.6, label=label)
        ax2.plot(r.t, _drift(r), color=color, lw=1.2 if "blajer" not in key else 2.2, label=label.split(" (")[0],
                 zorder=3 if "blajer" in key else 2)
    for key, color, marker in (("sp-fig18-blajer", "#c0392b", "x"), ("sp-fig18-yoon", "#2a7d2a", "+")):
        pre = runs.extra.get(f"precorrection:{key}")
        if pre:
            name = "Blajer" if "blajer" in key else "Yoon et al."
            ax.semilogy(pre["t"], np.maximum(pre["values"], floor), marker, color=color, ms=3, alpha=0.6,
                        label=f"{name}: |φ| one step before the correction (sampled)")
    ax.axhline(2.22e-16, color="0.5", lw=0.8, ls=":", label="machine ε = 2.2e−16")
    ax.set_ylabel(r"$|\phi|$ (m)" + f"\nmax per {window:.2g} s window")
    top = max([float(np.max(line.get_ydata())) for line in ax.get_lines() if len(line.get_ydata())] + [1e-12])
    ax.set_ylim(floor / 2, top * 3e4)          # room above the curves for the legend
    _log_ticks(ax)
    ax.tick_params(labelbottom=False)
    ax.legend(fontsize=6.5, loc="upper center", ncol=2, framealpha=0.95)
    if missing:
        ax.text(0.02, 0.04, "\n".join(missing), transform=ax.transAxes, fontsize=7, color="#c0392b")
    ax2.axhline(0, color="0.6", lw=0.6)
    ax2.set_ylabel(r"$\Delta E$ (J)" + "\n(not in the paper)", fontsize=9)
    ax2.set_xlabel("t (s)")
    ax2.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
    ax2.legend(fontsize=7, loc="lower left")


def _draw_fig4(fig, runs):
    ax = fig.add_subplot(111)
    _ah_series(ax, runs, "u1", r"$\dot{\theta}$ (rad/s)")
    ax.legend(loc="upper center", fontsize=8)
    if runs.ok("ah-nonlinear"):
        r = runs["ah-nonlinear"]
        ins = ax.inset_axes([0.52, 0.22, 0.45, 0.45])
        ins.semilogy(r.t, np.maximum(np.abs(r.state["u1"]), 1e-300), color=C_NC, lw=1.6)
        if runs.ok("ah-linear"):
            rl = runs["ah-linear"]
            ins.semilogy(rl.t, np.maximum(np.abs(rl.state["u1"]), 1e-300), color=C_LC, lw=1.0, ls="--")
        ins.set_title(r"$|\dot{\theta}|$ (rad/s), log scale", fontsize=8)
        ins.tick_params(labelsize=7)
        ins.grid(True, alpha=0.3)
        _log_ticks(ins)


def _draw_fig7_inset(ax, runs, t_zoom=3.0):
    ins = ax.inset_axes([0.6, 0.42, 0.37, 0.5])
    for key, color, ls, lw in (("ah-nonlinear", C_NC, "-", 2.0), ("ah-linear", C_LC, "--", 1.0)):
        if runs.ok(key):
            r = runs[key]
            w = r.t <= t_zoom
            ins.plot(r.state["x"][w], r.state["y"][w], color=color, ls=ls, lw=lw)
    ins.set_title(f"first {t_zoom:g} s", fontsize=8)
    ins.set_aspect("equal", adjustable="datalim")
    ins.tick_params(labelsize=7)
    ins.grid(True, alpha=0.3)


FIGURES: tuple[FigureSpec, ...] = (
    FigureSpec(2, "theta", r"Figure 2. Example 1: $\theta$ vs. t.", ("ah-nonlinear", "ah-linear"),
               _draw_ah("theta", r"$\theta$ (rad)"),
               "θ is the heading of the wheel's plane. It starts turning at 1 rad/s, the turning dies "
               "out within a few seconds, and the heading then stays fixed (≈ {theta_end:.3f} rad): from "
               "then on the wheel rolls straight ahead. The two ways of writing the rolling constraints "
               "(nonlinear NC, linear LC) give the same curve, and so does an independent derivation of "
               "Kane's minimal equations with sympy (circles)."),
    FigureSpec(3, "phi", r"Figure 3. Example 1: $\phi$ vs. t.", ("ah-nonlinear", "ah-linear"),
               _draw_ah("phi", r"$\phi$ (rad)"),
               "φ is the angle the wheel has rolled through. The curve bends upward: the load pulls the "
               "thread off the drum, so the wheel rolls faster and faster (here φ is the wheel's angle, "
               "not the constraint violation of Example 2)."),
    FigureSpec(4, "theta_dot", r"Figure 4. Example 1: $\dot{\theta}$ vs. t.", ("ah-nonlinear", "ah-linear"),
               _draw_fig4,
               "The turning rate θ̇ falls from 1 rad/s to zero (|θ̇| ≈ {theta_dot_end:.1e} rad/s at the end): "
               "the mechanism stops turning and only rolls."),
    FigureSpec(5, "phi_dot", r"Figure 5. Example 1: $\dot{\phi}$ vs. t.", ("ah-nonlinear", "ah-linear"),
               _draw_ah("u2", r"$\dot{\phi}$ (rad/s)"),
               "The rolling rate φ̇ grows steadily: the load's weight acts through the drum like a constant "
               "torque, so once the turning has died out the wheel speeds up at a constant rate, like a "
               "body sliding down a frictionless incline."),
    FigureSpec(6, "theta_dot_vs_phi", r"Figure 6. Example 1: $\dot{\theta}$ vs. $\phi$.",
               ("ah-nonlinear", "ah-linear"), _draw_fig6,
               "The same turning rate plotted against how far the wheel has rolled: θ̇ reaches zero within "
               "the first turns of the wheel and stays there while φ keeps growing — the steady state the "
               "paper describes."),
    FigureSpec(7, "y_vs_x", "Figure 7. Example 1: y vs. x.", ("ah-nonlinear", "ah-linear"), _draw_fig7,
               "The load's track on the x-y plane (it rides on the frame). It curves while the mechanism "
               "turns and then runs along a straight line, with the points spaced further and further "
               "apart as the mechanism speeds up."),
    FigureSpec(8, "z", "Figure 8. Example 1: z vs. t.", ("ah-nonlinear", "ah-linear"),
               _draw_ah("z", "z (m)"),
               "The load's height falls faster and faster, as the thread unwinds from the drum. The model "
               "has no floor: the load passes z = 0 and keeps falling (the web app shows it dropping "
               "into a shaft).",
               note="The paper's caption reads \"Example 3.1: z vs. t.\", a slip for Example 1."),
    FigureSpec(9, "energy_lc_nc",
               "Figure 9. Example 1: Energy integral, LC: linear constraints, NC: nonlinear constraints.",
               ("ah-nonlinear", "ah-linear"), _draw_fig9,
               "The mechanism is conservative, so its energy E should never change; ΔE is purely numerical "
               "error. Both models are integrated with the same method and step. The errors are tiny "
               "(nano-joules) but the nonlinear model's stays smaller (max|ΔE| NC/LC = {nc_lc:.2f}): "
               "writing the constraints nonlinearly in the speeds acts as a passive damper of numerical "
               "error, which is the paper's point."),
    FigureSpec(11, "phi_undamped_dt0.01",
               r"Figure 11. Example 2: Constraint violation, $\phi$: $\Gamma_1 = \Gamma_2 = 0$, $\Delta t = 0.01$ s.",
               ("sp-undamped-dt0.01",), _draw_ex2("sp-undamped-dt0.01", "phi"),
               "φ measures how far the computed particle is off the bowl's surface. The nonminimal "
               "equations hold the particle on the surface only through the surface's second time "
               "derivative (φ̈ = 0), so nothing pulls back the small error each step makes in φ and φ̇: "
               "it is integrated twice and piles up, and |φ| keeps growing (lower panel, log scale)."),
    FigureSpec(12, "phi_undamped_dt0.001",
               r"Figure 12. Example 2: Constraint violation, $\phi$: $\Gamma_1 = \Gamma_2 = 0$, $\Delta t = 0.001$ s.",
               ("sp-undamped-dt0.001",), _draw_ex2("sp-undamped-dt0.001", "phi"),
               "The same with a ten times smaller step: the drift still grows with time, but it is about "
               "{phi_ratio:.2g} times smaller — paid for with ten times more steps."),
    FigureSpec(13, "energy_undamped_dt0.01",
               r"Figure 13. Example 2: Energy integral: $\Gamma_1 = \Gamma_2 = 0$, $\Delta t = 0.01$ s.",
               ("sp-undamped-dt0.01",), _draw_ex2("sp-undamped-dt0.01", "energy"),
               "The particle's energy should stay at its initial value m g l0; the deviation ΔE grows "
               "along with the constraint drift: a particle that drifts off the surface no longer feels "
               "the right forces."),
    FigureSpec(14, "energy_undamped_dt0.001",
               r"Figure 14. Example 2: Energy integral: $\Gamma_1 = \Gamma_2 = 0$, $\Delta t = 0.001$ s.",
               ("sp-undamped-dt0.001",), _draw_ex2("sp-undamped-dt0.001", "energy"),
               "With the smaller step the energy error is far smaller but still grows. Compare its size "
               "with Fig. 17."),
    FigureSpec(15, "phi_damped_dt0.001",
               r"Figure 15. Example 2: Constraint violation, $\phi$: $\Gamma_1 = -20$, $\Gamma_2 = -100$, "
               r"$\Delta t = 0.001$ s.",
               ("sp-damped-dt0.001",),
               _draw_ex2("sp-damped-dt0.001", "phi", bound=(2.0e-11, "paper's bound |φ| < 2.0e−11 m")),
               "Baumgarte's terms replace \"the surface's acceleration error is zero\" by \"φ̈ + 20 φ̇ + 100 φ "
               "= 0\": any drift now dies out like a critically damped spring with a 0.1 s time constant, "
               "instead of accumulating. φ no longer grows; it stays at the level the step's local error "
               "feeds in, below 2·10⁻¹¹ m ({phi15:.2e} m measured)."),
    FigureSpec(16, "y_1h_dt0.1",
               r"Figure 16. Example 2: $y$ solution after 1 h, $\Delta t = 0.1$ s: M minimal, N nonminimal "
               r"($\Gamma_1 = \Gamma_2 = 0$), DN damped nonminimal ($\Gamma_1 = -20$, $\Gamma_2 = -100$).",
               ("sp-1h-minimal", "sp-1h-nonminimal", "sp-1h-damped", "sp-1h-reference"), _draw_fig16,
               "A coarse step (0.1 s) over an hour. Without stabilization (N) the particle drifts off the "
               "bowl to y ≈ {n_max:.0e} m — nonsense. With Baumgarte's terms (DN) it stays on the bowl, "
               "as the minimal equation (M, which cannot leave the surface) does. Staying on the surface "
               "is not the same as being accurate, as the paper warns: against a fine-step reference both "
               "M and DN are out of phase after an hour, and DN has bled away {dn_loss:.0%} of its energy, "
               "so its swing has shrunk to the bottom of the bowl (right panel)."),
    FigureSpec(17, "energy_damped_dt0.001",
               r"Figure 17. Example 2: Energy integral deviation $\Delta E$: $\Gamma_1 = -20$, $\Gamma_2 = -100$, "
               r"$\Delta t = 0.001$ s.",
               ("sp-damped-dt0.001",), _draw_ex2("sp-damped-dt0.001", "energy"),
               "The price of the stabilization: the Baumgarte terms are extra forces that do work, so the "
               "energy error is larger than without them at the same step (about {e17_ratio:.0f} times Fig. 14's), "
               "even though the constraint is now held (Fig. 15)."),
    FigureSpec(18, "phi_baumgarte_blajer_yoon",
               r'Figure 18. Example 2: Constraint violation $\phi$: $\Delta t = 0.01$ s; "1" Baumgarte, '
               r'"2" Blajer, "3" Yoon et al.',
               ("sp-fig18-baumgarte", "sp-fig18-blajer", "sp-fig18-yoon", "sp-fig18-oneshot"), _draw_fig18,
               "Two ways to stop the drift. Baumgarte changes the equations of motion so that drift decays "
               "on its own; the post-step corrections of Blajer and of Yoon et al. leave the equations alone "
               "and, after every step, move the state back onto the surface (positions, then speeds). "
               "{f18_verdict} The two papers' texts were not available, so the presets follow the family "
               "both belong to (see nmkane_core.projection and the claims table for the numbers).",
               note="Fig. 18's horizon is not stated in the paper; 500 s is used, as for Figs. 11–15 (100 s in quick mode). The "
                    "upper panel shows the maximum of |φ| per window on a log scale (a signed linear plot "
                    "would show the projections as a flat line at zero)."),
)


def _facts(runs: Runs, claims: dict[str, Claim]) -> dict:
    """Numbers quoted in the "what this shows" paragraphs (NaN when a run is missing)."""
    nan = float("nan")
    f = dict(theta_end=nan, theta_dot_end=nan, nc_lc=nan, phi_ratio=nan, phi15=nan, n_max=nan, dn_loss=nan,
             e17_ratio=nan, b18=nan, f18_verdict="")
    v = lambda k: claims[k].values if k in claims and claims[k].values else None  # noqa: E731
    if v("theta_reaches_steady_state"):
        f["theta_end"] = v("theta_reaches_steady_state")["theta_end"]
        f["theta_dot_end"] = abs(v("theta_reaches_steady_state")["theta_dot_end"])
    if v("fig9_nonlinear_energy_drift_below_linear"):
        d = v("fig9_nonlinear_energy_drift_below_linear")
        f["nc_lc"] = d["nonlinear"] / d["linear"]
    if v("fig11_12_smaller_step_smaller_violation"):
        d = v("fig11_12_smaller_step_smaller_violation")
        f["phi_ratio"] = d["dt0.01"] / d["dt0.001"]
    if v("fig15_damped_bound"):
        f["phi15"] = v("fig15_damped_bound")["max_abs_phi"]
    if v("fig16_undamped_drifts_off"):
        f["n_max"] = v("fig16_undamped_drifts_off")["max_abs_y"]
    if v("fig16_compared_with_fine_reference") and runs.ok("sp-1h-reference"):
        f["dn_loss"] = abs(v("fig16_compared_with_fine_reference")["DN"]["energy_drift_end"]) / float(
            runs["sp-1h-reference"].energy[0])
    if v("fig17_damping_increases_energy_error"):
        d = v("fig17_damping_increases_energy_error")
        f["e17_ratio"] = d["damped"] / d["undamped"]
    f["f18_verdict"] = "The projection runs were not made, so the comparison is still open."
    if v("fig18_baumgarte_smallest_bound"):
        d = v("fig18_baumgarte_smallest_bound")
        m, pre = d["max_abs_phi"], d["precorrection"]
        b = m["Baumgarte"]
        f["b18"] = b
        if claims["fig18_baumgarte_smallest_bound"].status == PASS:
            f["f18_verdict"] = (f"Measured here, Baumgarte's bound ({b:.1e} m) is the smallest of the three, "
                                "as the paper concludes.")
        else:
            proj = max(m["Blajer"], m["Yoon et al."])
            text = (f"Measured here, the corrections hold |φ| at {proj:.0e} m (round-off), far below "
                    f"Baumgarte's ≈ {b:.1e} m: the opposite of the paper's conclusion.")
            if pre and all(pre.values()):
                worst = max(p["max"] for p in pre.values())
                if worst < b:
                    text += (f" Even the violation one step before a correction (sampled, at most "
                             f"{worst:.1e} m) stays below Baumgarte's bound.")
                else:
                    text += (f" The violation one step before a correction (sampled) reaches {worst:.1e} m, "
                             "above Baumgarte's bound: only the corrected states are on the surface.")
            f["f18_verdict"] = text
    if runs.ok("sp-fig18-blajer") and runs.ok("sp-fig18-yoon"):
        eb = runs["sp-fig18-blajer"].summary["max_abs_energy_drift"]
        ey = runs["sp-fig18-yoon"].summary["max_abs_energy_drift"]
        f["f18_verdict"] += (f" The 'blajer' preset also restores the energy (max|ΔE| {eb:.1e} J); 'yoon' "
                             f"does not ({ey:.1e} J; Baumgarte's is larger still, lower panel).")
    return f


def _wrap_caption(caption: str, width: int) -> str:
    """Greedy line wrap that never splits a $…$ mathtext span; widths count rendered characters."""
    lines, cur, n = [], [], 0
    for tok in re.findall(r"[^\s$]*\$[^$]*\$[^\s$]*|\S+", caption):
        w = len(_plain_caption(tok))
        if cur and n + 1 + w > width:
            lines.append(" ".join(cur))
            cur, n = [], 0
        cur.append(tok)
        n += w + (1 if n else 0)
    lines.append(" ".join(cur))
    return "\n".join(lines)


def _log_ticks(ax):
    """Major decade labels only (minor labels crowd a log axis spanning less than a decade)."""
    from matplotlib.ticker import LogLocator, NullFormatter

    ax.yaxis.set_major_locator(LogLocator(base=10, numticks=12))
    ax.yaxis.set_minor_formatter(NullFormatter())


def draw_figure(spec: FigureSpec, runs: Runs, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    wide = spec.number == 16
    fig = Figure(figsize=(10.0 if wide else 7.0, 4.8 if spec.number in (11, 12, 13, 14, 15, 17, 18) else 4.4),
                 dpi=130, layout="constrained")
    spec.draw(fig, runs)
    for ax in fig.axes:
        ax.grid(True, which="major", alpha=0.3)
    fig.suptitle(_wrap_caption(spec.caption, 130 if wide else 88), fontsize=10.5)
    fig.savefig(path)


# --------------------------------------------------------------------------- report
@dataclass
class Report:
    out_dir: str
    quick: bool
    figures: list[FigureResult]
    claims: list[Claim]
    runs: dict[str, dict]              # key -> {"label", "settings", "cli", "rest", "summary" | "error"}
    timings: dict[str, float]
    files: dict[str, str] = field(default_factory=dict)

    @property
    def counts(self) -> dict[str, int]:
        c = {PASS: 0, FAIL: 0, INFO: 0, NOT_RUN: 0}
        for cl in self.claims:
            c[cl.status] = c.get(cl.status, 0) + 1
        return c

    def claim(self, key: str) -> Claim:
        for c in self.claims:
            if c.key == key:
                return c
        raise KeyError(key)

    def summary_text(self) -> str:
        lines = [f"nmkane figures: {len(self.figures)} figures and the claims report in {self.out_dir}"]
        for c in self.claims:
            lines.append(f"  [{c.status:7}] Fig. {c.label}: {c.claim}")
            lines.append(f"            {c.measured}")
        for f in self.figures:
            if f.error:
                lines.append(f"  figure {f.number} NOT DRAWN: {f.error}")
        n = self.counts
        lines.append(f"claims: {n[PASS]} pass, {n[FAIL]} fail, {n[NOT_RUN]} not run")
        lines.append(f"time: {self.timings['total_s']:.1f} s (runs {self.timings['runs_s']:.1f} s, "
                     f"figures {self.timings['figures_s']:.1f} s)")
        lines.append(f"open {self.files.get('html', '')} or {self.files.get('md', '')}")
        return "\n".join(lines)

    # ---- markdown
    def to_markdown(self) -> str:
        n = self.counts
        md = [
            "# Bajodah, Hodges & Chen (2005): figures regenerated, claims checked",
            "",
            f"Generated by `nmkane figures{' --quick' if self.quick else ''}` on "
            f"{time.strftime('%Y-%m-%d %H:%M', time.localtime())} in {self.timings['total_s']:.1f} s. "
            f"Claims: **{n[PASS]} PASS, {n[FAIL]} FAIL**"
            + (f", {n[NOT_RUN]} not run" if n[NOT_RUN] else "") + ".",
            "",
            *_choices_md(self.quick),
            "",
            "## Claims",
            "",
            "| Fig. | claim | paper | measured now | result |",
            "|---|---|---|---|---|",
            *[f"| {c.label} | {_md(c.claim)} | {_md(c.paper)} | {_md(c.measured)} | **{c.status}** |"
              for c in self.claims],
            "",
        ]
        for f in self.figures:
            md += [f"## Figure {f.number}", "", f"![{_md(f.caption)}]({f.file})", "", f"*{_plain_caption(f.caption)}*", ""]
            if f.error:
                md += [f"**Figure not drawn:** {f.error}", ""]
            if f.claims:
                md += ["| claim | paper | measured now | result |", "|---|---|---|---|"]
                md += [f"| {_md(c.claim)} | {_md(c.paper)} | {_md(c.measured)} | **{c.status}** |" for c in f.claims]
                md.append("")
            md += [f"**What this shows.** {f.explain}", ""]
            if f.note:
                md += [f"*Note.* {f.note}", ""]
            md += ["Runs: " + ", ".join(f"[`{k}`](#run-{k})" for k in f.runs), ""]
        md += ["## Runs", "",
               "Every run is the library's `simulate(settings)`; the same settings re-run it from the CLI or "
               "the REST service (`POST /api/runs`). Omitted fields (parameters, initial state) take the "
               "system's defaults, which are the paper's.", ""]
        for key, r in self.runs.items():
            md += [f"<a id=\"run-{key}\"></a>", f"### `{key}` — {_md(r['label'])}", ""]
            if r.get("cli"):
                md += ["```sh", r["cli"], "```", ""]
            else:
                md += ["(CLI: not expressible — the projection switches are REST/library settings)", ""]
            md += ["```sh", r["rest"], "```", ""]
            if r.get("rest_note"):
                md += [f"REST: {_md(r['rest_note'])}.", ""]
            if "error" in r:
                md += [f"**Not run:** {_md(r['error'])}", ""]
            else:
                md += [_md(_summary_line(r["summary"])), ""]
        md += ["## Timings", "", "| step | s |", "|---|---|"]
        md += [f"| {k} | {v:.2f} |" for k, v in self.timings.items()]
        md.append("")
        return "\n".join(md)

    # ---- html
    def to_html(self) -> str:
        e = html.escape
        n = self.counts
        rows = "".join(
            f"<tr><td>{e(c.label)}</td><td>{e(c.claim)}</td><td>{e(c.paper)}</td><td>{e(c.measured)}</td>"
            f"<td class='{c.status.replace(' ', '')}'>{e(c.status)}</td></tr>" for c in self.claims)
        parts = [f"""<!doctype html><html lang="en"><head><meta charset="utf-8">
<title>nmkane — paper figures and claims</title>
<style>
body{{font-family:system-ui,-apple-system,Segoe UI,sans-serif;max-width:1300px;margin:2em auto;padding:0 1em;color:#222;line-height:1.45}}
table{{border-collapse:collapse;font-size:.88em;width:100%}} td,th{{border:1px solid #ccc;padding:.3em .5em;vertical-align:top;text-align:left}}
th{{background:#f2f2f2}} .PASS{{background:#dff3df;font-weight:bold}} .FAIL{{background:#f8d7d7;font-weight:bold}}
.NOTRUN{{background:#f3ecd0;font-weight:bold}} .INFO{{background:#e6eef8}}
.fig{{display:flex;gap:1.2em;align-items:flex-start;flex-wrap:wrap;border-top:2px solid #ddd;padding-top:1em;margin-top:1.5em}}
.fig .plot{{flex:0 1 640px;min-width:320px}} .fig img{{width:100%;border:1px solid #ddd}} .fig .side{{flex:1 1 420px;min-width:340px}}
.caption{{font-style:italic}} pre{{background:#f6f6f6;padding:.5em;overflow-x:auto;font-size:.85em;white-space:pre-wrap}}
</style></head><body>
<h1>Bajodah, Hodges &amp; Chen (2005): figures regenerated, claims checked</h1>
<p>Generated by <code>nmkane figures{' --quick' if self.quick else ''}</code> on {e(time.strftime('%Y-%m-%d %H:%M'))}
in {self.timings['total_s']:.1f} s. Claims: <b>{n[PASS]} PASS, {n[FAIL]} FAIL</b>{f', {n[NOT_RUN]} not run' if n[NOT_RUN] else ''}.</p>
<ul>{''.join(f'<li>{e(x[2:])}</li>' for x in _choices_md(self.quick))}</ul>
<h2>Claims</h2><table><tr><th>Fig.</th><th>claim</th><th>paper</th><th>measured now</th><th>result</th></tr>{rows}</table>"""]
        for f in self.figures:
            crow = "".join(f"<tr><td>{e(c.claim)}</td><td>{e(c.paper)}</td><td>{e(c.measured)}</td>"
                           f"<td class='{c.status.replace(' ', '')}'>{e(c.status)}</td></tr>" for c in f.claims)
            table = (f"<table><tr><th>claim</th><th>paper</th><th>measured now</th><th>result</th></tr>{crow}</table>"
                     if f.claims else "<p>(no numerical claim in the paper for this figure)</p>")
            runs = ", ".join(f"<a href='#run-{e(k)}'><code>{e(k)}</code></a>" for k in f.runs)
            parts.append(f"""<div class="fig" id="fig{f.number}"><div class="plot"><img src="{e(f.file)}" alt="{e(_plain_caption(f.caption))}">
<p class="caption">{e(_plain_caption(f.caption))}</p></div><div class="side"><h2>Figure {f.number}</h2>
{f'<p><b>Figure not drawn:</b> {e(f.error)}</p>' if f.error else ''}{table}
<p><b>What this shows.</b> {e(f.explain)}</p>{f'<p><i>Note.</i> {e(f.note)}</p>' if f.note else ''}<p>Runs: {runs}</p></div></div>""")
        parts.append("<h2>Runs</h2><p>Every run is the library's <code>simulate(settings)</code>; the same settings "
                     "re-run it from the CLI or the REST service (<code>POST /api/runs</code>). Omitted fields "
                     "(parameters, initial state) take the system's defaults, which are the paper's.</p>")
        for key, r in self.runs.items():
            cli = (f"<pre>{e(r['cli'])}</pre>" if r.get("cli") else
                   "<p>(CLI: not expressible — the projection switches are REST/library settings)</p>")
            status = (f"<p><b>Not run:</b> {e(r['error'])}</p>" if "error" in r else
                      f"<p>{e(_summary_line(r['summary']))}</p>")
            note = f"<p>REST: {e(r['rest_note'])}.</p>" if r.get("rest_note") else ""
            parts.append(f"<h3 id='run-{e(key)}'><code>{e(key)}</code> — {e(r['label'])}</h3>{cli}"
                         f"<pre>{e(r['rest'])}</pre>{note}{status}")
        parts.append("<h2>Timings</h2><table>" + "".join(f"<tr><td>{e(k)}</td><td>{v:.2f} s</td></tr>"
                                                          for k, v in self.timings.items()) + "</table>")
        parts.append("</body></html>")
        return "\n".join(parts)

    def to_json(self) -> dict:
        return {"quick": self.quick, "claims": [asdict(c) for c in self.claims],
                "figures": [{"number": f.number, "file": f.file, "caption": _plain_caption(f.caption),
                             "claims": [c.key for c in f.claims], "runs": f.runs, "error": f.error}
                            for f in self.figures],
                "runs": self.runs, "timings": self.timings}


def _choices_md(quick: bool) -> list[str]:
    return [
        f"- Integrator everywhere: fixed-step Kutta–Merson (the paper's). Example 1 (Figs. 2–9): Δt = {DT_AH:g} s "
        f"over {T_AH:g} s — the paper states neither; by 20 s θ has settled and the load has fallen ≈ 50 m.",
        f"- Example 2: Figs. 11–15 and 17 over {T_EX2:g} s (the paper's), Fig. 16 over 1 h (the paper's), "
        f"Fig. 18 over {T_FIG18_QUICK if quick else T_FIG18:g} s (not stated in the paper"
        f"{'; quick mode' if quick else ''}).",
        f"- Fig. 16's reference: the minimal equation (137) at Δt = {0.005 if quick else 0.001:g} s"
        f"{' (quick mode)' if quick else ''}.",
        "- Parameters and initial states: the paper's (REFERENCE.md), with g = 9.81 m/s² and I = 2.5 kg·m².",
        "- Maxima (max|φ|, max|ΔE|) are over every integration step; plots show thinned output.",
    ]


def _md(s: str) -> str:
    return str(s).replace("|", "\\|").replace("\n", " ")


def _plain_caption(c: str) -> str:
    rep = {r"$\dot{\theta}$": "θ̇", r"$\dot{\phi}$": "φ̇", r"$\theta$": "θ", r"$\phi$": "φ", r"$\Delta E$": "ΔE",
           r"$\Gamma_1 = \Gamma_2 = 0$": "Γ1 = Γ2 = 0", r"$\Gamma_1 = -20$": "Γ1 = −20",
           r"$\Gamma_2 = -100$": "Γ2 = −100", r"$\Delta t = 0.01$": "Δt = 0.01", r"$\Delta t = 0.001$": "Δt = 0.001",
           r"$\Delta t = 0.1$": "Δt = 0.1", r"$y$": "y"}
    for k, v in rep.items():
        c = c.replace(k, v)
    return c


def _summary_line(s: dict) -> str:
    viol = ", ".join(f"{k} {v:.3g}" for k, v in s["max_abs_violation"].items())
    dE = s.get("max_abs_energy_drift")
    return (f"status {s['status']}: {s['steps']:,} steps in {s['wall_time_s']:.3f} s; max|violation| {viol}; "
            f"max|ΔE| {dE:.3g}" if dE is not None else f"status {s['status']}")


def _fmt(v) -> str:
    if isinstance(v, float) and v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    return str(v)


_CLI_OPTIONS = (("model", "--model"), ("formulation", "--formulation"), ("gamma", "--gamma"),
                ("gamma1", "--gamma1"), ("gamma2", "--gamma2"), ("projection", "--projection"),
                ("integrator", "--integrator"), ("dt", "--dt"), ("t_final", "--t-final"), ("every", "--every"))


def cli_command(settings: dict, out: str | None = None) -> str | None:
    """``nmkane run ...`` for these settings (None when a setting has no CLI option)."""
    known = {"system"} | {k for k, _ in _CLI_OPTIONS}
    if set(settings) - known:
        return None
    parts = ["nmkane", "run", settings["system"]]
    for key, opt in _CLI_OPTIONS:
        v = settings.get(key)
        if v is None or (key == "projection" and v == "none"):
            continue
        parts += [opt, _fmt(v)]
    if out:
        parts += ["--out", out]
    return " ".join(parts)


def rest_body(settings: dict) -> str:
    return json.dumps(settings, ensure_ascii=False)


def _rest_command(settings: dict) -> str:
    return ("curl -s -X POST http://127.0.0.1:8000/api/runs -H 'Content-Type: application/json' "
            f"-d '{rest_body(settings)}'")


# --------------------------------------------------------------------------- driver
def make_figures(out_dir: str, progress: bool | None = None, quick: bool = False) -> "Report":
    """Run everything, draw Figures 2–9 and 11–18 into ``out_dir`` and write the report there.

    ``progress=None`` shows progress bars when stderr is a terminal.  ``quick`` shortens the
    horizons where a claim allows it (see the module docstring).
    """
    t0 = time.perf_counter()
    if progress is None:
        progress = sys.stderr.isatty()
    os.makedirs(out_dir, exist_ok=True)
    t_runs = time.perf_counter()
    runs = collect_runs(quick=quick, progress=progress)
    runs_s = time.perf_counter() - t_runs
    claims = evaluate_claims(runs)
    by_key = {c.key: c for c in claims}
    facts = _facts(runs, by_key)

    t_fig = time.perf_counter()
    results: list[FigureResult] = []
    specs = FIGURES
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(specs), unit="fig", desc="figures", leave=False)
    try:
        for spec in specs:
            fname = f"fig{spec.number:02d}_{spec.slug}.png"
            err = None
            path = os.path.join(out_dir, fname)
            try:
                draw_figure(spec, runs, path)
            except Exception as e:  # one broken figure must not lose the others or the report
                err = f"{type(e).__name__}: {e}"
                if os.path.exists(path):       # never show a stale image from an earlier run
                    os.remove(path)
            fig_claims = [c for c in claims if spec.number in c.figures]
            explain = _explain(spec.explain, facts)
            if spec.number != 18 and any(c.status == FAIL for c in fig_claims):   # Fig. 18's text follows the numbers
                explain = ("[A claim of this figure FAILS now (see the table); the text below describes what "
                           "the paper expects.] " + explain)
            results.append(FigureResult(spec.number, fname, spec.caption, explain,
                                        list(spec.runs), fig_claims, spec.note, err))
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    figures_s = time.perf_counter() - t_fig

    run_docs = {}
    for key, settings in runs.settings.items():
        doc = {"label": RUN_LABELS.get(key, key), "settings": settings,
               "cli": cli_command(settings, out=f"{key}.json"), "rest": _rest_command(settings)}
        steps = math.ceil(settings["t_final"] / settings["dt"] - 1e-9)
        rows = steps // settings.get("every", 1) + 2
        if steps > REST_DEFAULT_LIMITS["max_steps"] or rows > REST_DEFAULT_LIMITS["max_rows"]:
            doc["rest_note"] = (f"{steps:,} steps, {rows:,} output rows: above the REST service's default "
                                f"limits ({REST_DEFAULT_LIMITS['max_steps']:,} steps, "
                                f"{REST_DEFAULT_LIMITS['max_rows']:,} rows); start it with "
                                f"NMKANE_MAX_STEPS={max(steps, REST_DEFAULT_LIMITS['max_steps'])} "
                                f"NMKANE_MAX_ROWS={max(rows, REST_DEFAULT_LIMITS['max_rows'])}")
        if key in runs.results:
            doc["summary"] = {k: v for k, v in runs.results[key].summary.items()
                              if k in ("status", "message", "steps", "wall_time_s", "max_abs_violation",
                                       "max_abs_energy_drift", "final_energy_drift")}
        if key in runs.errors:
            doc["error"] = runs.errors[key]
        run_docs[key] = doc
    timings = {"runs_s": runs_s,
               "integration_s (sum over runs, 2 threads)": float(sum(r.summary["wall_time_s"]
                                                                     for r in runs.results.values())),
               "oracle_s": float(runs.extra.get("oracle", {}).get("wall_s", 0.0)),
               "figures_s": figures_s}
    report = Report(out_dir, quick, results, claims, run_docs, timings)
    report.timings["total_s"] = time.perf_counter() - t0
    paths = {"md": os.path.join(out_dir, "report.md"), "html": os.path.join(out_dir, "report.html"),
             "json": os.path.join(out_dir, "report.json")}
    _write(paths["md"], report.to_markdown())
    _write(paths["html"], report.to_html())
    _write(paths["json"], json.dumps(report.to_json(), indent=1, default=_json_default, ensure_ascii=False))
    report.files = paths
    return report


def _explain(text: str, facts: dict) -> str:
    try:
        return text.format(**facts)
    except (KeyError, ValueError, IndexError):
        return text


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.bool_,)):
        return bool(o)
    raise TypeError(type(o).__name__)


def _write(path: str, text: str) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    """``nmkane figures [--out DIR] [--quick] [--no-progress] [--strict]``."""
    p = argparse.ArgumentParser(prog="nmkane figures", description=__doc__.split("\n")[0])
    p.add_argument("--out", default="figures", help="output directory (default ./figures)")
    p.add_argument("--quick", action="store_true", help="shorter horizons where the claim allows")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--strict", action="store_true", help="exit 1 when a claim fails or could not be checked")
    args = p.parse_args(argv)
    report = make_figures(args.out, progress=False if args.no_progress else None, quick=args.quick)
    print(report.summary_text())
    n = report.counts
    if any(f.error for f in report.figures):
        return 1
    return 1 if args.strict and (n[FAIL] or n[NOT_RUN]) else 0


if __name__ == "__main__":
    sys.exit(main())
