"""The runs behind the figures: the plan (settings by key), making them, and the derived
measurements (the Kane's-method cross-check of Example 1, the pre-correction violation of Fig. 18).

Choices the paper leaves open are stated in the package docstring (:mod:`nmkane_core.paper`).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import NmkaneError
from ..kernel.built import built
from ..run.registry import get_system

__all__ = ["Runs", "collect_runs", "run_plan", "RUN_LABELS"]

#: Horizons and steps (s).  The package docstring gives the reasons.
T_AH = 20.0  # Example 1, Figs. 2–9 (not stated in the paper)
DT_AH = 0.01
T_EX2 = 500.0  # Figs. 11–15, 17 (paper)
T_FIG18_QUICK = 100.0  # Fig. 18 in quick mode
T_FIG16 = 3600.0  # Fig. 16 (paper: 1 h)
T_FIG18 = 500.0  # Fig. 18 (not stated in the paper)
DT_FIG16_REF = 0.001  # Fig. 16's fine-step reference, minimal equation (137)
DT_FIG16_REF_QUICK = 0.005  # the same in quick mode
GAINS = {"gamma1": -20.0, "gamma2": -100.0}  # the paper's Γ1 (s⁻¹), Γ2 (s⁻²)
KM = "kutta-merson"
PRECORRECTION_SAMPLES = 500  # states of a projection run re-stepped without correction (Fig. 18)


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
        "sp-damped-dt0.001": {**sp, "formulation": "nonminimal", **GAINS, "dt": 0.001, "t_final": T_EX2, "every": 20},
        "sp-1h-minimal": {**sp, "formulation": "minimal", "dt": 0.1, "t_final": T_FIG16, "every": 1},
        "sp-1h-nonminimal": {**sp, "formulation": "nonminimal", "dt": 0.1, "t_final": T_FIG16, "every": 1},
        "sp-1h-damped": {**sp, "formulation": "nonminimal", **GAINS, "dt": 0.1, "t_final": T_FIG16, "every": 1},
        "sp-1h-reference": {
            **sp,
            "formulation": "minimal",
            "dt": DT_FIG16_REF_QUICK if quick else DT_FIG16_REF,
            "t_final": T_FIG16,
            "every": 20 if quick else 100,
        },
        "sp-fig18-baumgarte": {**sp, "formulation": "nonminimal", **GAINS, "dt": 0.01, "t_final": t18, "every": 1},
        "sp-fig18-blajer": {
            **sp,
            "formulation": "nonminimal",
            "projection": "blajer",
            "dt": 0.01,
            "t_final": t18,
            "every": 1,
        },
        "sp-fig18-yoon": {
            **sp,
            "formulation": "nonminimal",
            "projection": "yoon",
            "dt": 0.01,
            "t_final": t18,
            "every": 1,
        },
        # the weakest member of the projection family: one Newton step with the Jacobian at the
        # uncorrected point, no energy correction (does the conclusion depend on the switches?)
        "sp-fig18-oneshot": {
            **sp,
            "formulation": "nonminimal",
            "projection": "yoon",
            "projection_iterations": 1,
            "projection_jacobian": "frozen",
            "projection_energy": False,
            "dt": 0.01,
            "t_final": t18,
            "every": 1,
        },
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
    results: dict = field(default_factory=dict)  # key -> simulate.Run
    errors: dict[str, str] = field(default_factory=dict)  # key -> why it was not run
    extra: dict = field(default_factory=dict)  # derived measurements (oracle, pre-correction)
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
    from ..run.simulate import resolve, simulate_many

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
    runs.results = dict(zip(plans, done, strict=True))
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
    """Kane's minimal equations of Appell–Hamel from sympy's KanesMethod (nmkane_core.systems.appell_hamel_oracle,
    an independent derivation), integrated with DOP853 at rtol 1e-11 on the output times."""
    if not runs.ok("ah-nonlinear"):
        return {"error": runs.errors.get("ah-nonlinear", "no nonlinear run")}
    try:
        from scipy.integrate import solve_ivp

        from ..systems.appell_hamel_oracle import appell_hamel_minimal_rhs

        t_start = time.perf_counter()
        run = runs["ah-nonlinear"]
        names = _state_names("appell-hamel")  # the oracle's order: q, then u
        s0 = np.array([run.state[n][0] for n in names])
        rhs = appell_hamel_minimal_rhs(**run.settings["params"])
        sol = solve_ivp(rhs, (0.0, float(run.t[-1])), s0, method="DOP853", rtol=1e-11, atol=1e-11, t_eval=run.t)
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
    from ..run.simulate import simulate

    dt = settings["dt"]
    stride = max(1, (len(run.t) - 1) // PRECORRECTION_SAMPLES)
    idx = np.arange(0, len(run.t) - 1, stride)
    names = _state_names(settings["system"])
    vals = np.empty(idx.size)
    for j, i in enumerate(idx):
        one = simulate(
            {
                "system": settings["system"],
                "formulation": settings["formulation"],
                "integrator": settings["integrator"],
                "dt": dt,
                "t_final": dt,
                "initial": {n: float(run.state[n][i]) for n in names},
            },
            progress=False,
        )
        vals[j] = one.summary["max_abs_violation"]["surface"]
    return {
        "max": float(vals.max()),
        "median": float(np.median(vals)),
        "samples": int(idx.size),
        "stride": stride * int(settings.get("every", 1)),
        "t": run.t[idx] + dt,
        "values": vals,
    }


def _state_names(system: str) -> tuple[str, ...]:
    """The full state of ``system``: its coordinates q, then its speeds u."""
    sys_ = get_system(system)
    return built(sys_).state_names
