"""The paper's claims, measured now on the runs of :mod:`.runs`: the rows of the claims table.

Each claim is one function ``measure(runs) -> (measured, status, values)`` and one row of
:data:`CLAIMS` (the report's order) naming the figures it belongs to, the claim in our words,
the paper's words, and the runs it needs.  A claim whose runs were not made is NOT RUN.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np

from .runs import DT_AH, T_AH, Runs
from .text import fig_label, num

__all__ = ["PASS", "FAIL", "INFO", "NOT_RUN", "Claim", "ClaimSpec", "CLAIMS", "evaluate_claims", "drift"]

PASS, FAIL, INFO, NOT_RUN = "PASS", "FAIL", "INFO", "NOT RUN"


@dataclass
class Claim:
    """One row of the claims table."""

    key: str
    figures: tuple[int, ...]
    claim: str
    paper: str
    measured: str
    status: str  # PASS | FAIL | INFO | NOT RUN
    values: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        return fig_label(self.figures)


@dataclass(frozen=True)
class ClaimSpec:
    """A claim as declared: ``measure(runs)`` runs only when every run in ``needs`` is ok."""

    key: str
    figures: tuple[int, ...]
    claim: str
    paper: str
    needs: tuple[str, ...]
    measure: Callable[[Runs], tuple[str, str, dict]]

    def evaluate(self, runs: Runs) -> Claim:
        missing = [f"{k}: {runs.errors.get(k, 'not in this report')}" for k in self.needs if not runs.ok(k)]
        if missing:
            return Claim(self.key, self.figures, self.claim, self.paper, f"not run — {'; '.join(missing)}", NOT_RUN)
        measured, status, values = self.measure(runs)
        return Claim(self.key, self.figures, self.claim, self.paper, measured, status, values)


def evaluate_claims(runs: Runs) -> list[Claim]:
    """The claims table (the order of the report)."""
    return [spec.evaluate(runs) for spec in CLAIMS]


# --------------------------------------------------------------------------- measures
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


def drift(run):
    """ΔE(t) = E(t) − E(0)."""
    return run.energy - run.energy[0]


# ---- Example 1 (Appell–Hamel, Figs. 2–9) ------------------------------------------------
def models_same_motion(runs: Runs):
    nc, lc = runs["ah-nonlinear"], runs["ah-linear"]
    d = {n: _absmax(nc.state[n] - lc.state[n]) for n in nc.state}
    worst = max(d, key=lambda k: d[k])
    return (
        f"max difference over {T_AH:g} s: {num(d[worst])} ({worst}); θ {num(d['theta'])} rad, z {num(d['z'])} m",
        _ok(d[worst] < 1e-6),
        {"max_abs_diff": d},
    )


def matches_kanes_method_oracle(runs: Runs):
    o = runs.extra.get("oracle", {"error": "not computed"})
    if "error" in o:
        return f"not run — {o['error']}", NOT_RUN, {}
    worst = max(o["max_abs_diff"], key=o["max_abs_diff"].get)
    v = o["max_abs_diff"][worst]
    return (
        f"max |NC − KanesMethod| over all 10 states: {num(v)} ({worst})",
        _ok(v < 1e-6),
        {"max_abs_diff": o["max_abs_diff"]},
    )


def theta_reaches_steady_state(runs: Runs):
    r = runs["ah-nonlinear"]
    th, thd = r.state["theta"], r.state["u1"]
    late = r.t >= r.t[-1] / 2
    change = float(th[late].max() - th[late].min())
    return (
        f"θ({r.t[-1]:g} s) = {th[-1]:.4f} rad; |θ̇| at the end {num(abs(thd[-1]))} rad/s; "
        f"θ moves {num(change)} rad over the second half",
        _ok(abs(thd[-1]) < 1e-3 and change < 1e-2),
        {"theta_end": float(th[-1]), "theta_dot_end": float(thd[-1]), "theta_change_late": change},
    )


def load_falls_wheel_speeds_up(runs: Runs):
    r = runs["ah-nonlinear"]
    phd, z = r.state["u2"], r.state["z"]
    mono = bool(np.all(np.diff(phd) > 0) and np.all(np.diff(z) < 0))
    return (
        f"φ̇: {phd[0]:.3g} → {phd[-1]:.3g} rad/s, z: {z[0]:.3g} → {z[-1]:.3g} m, "
        f"{'both monotonic' if mono else 'NOT monotonic'}",
        _ok(mono),
        {"phi_dot": (float(phd[0]), float(phd[-1])), "z": (float(z[0]), float(z[-1]))},
    )


def fig9_energy_drift(runs: Runs):
    nc = runs["ah-nonlinear"].summary["max_abs_energy_drift"]
    lc = runs["ah-linear"].summary["max_abs_energy_drift"]
    return (
        f"max|ΔE|: NC {num(nc)} J, LC {num(lc)} J (NC/LC = {nc / lc:.2f}); Kutta–Merson, Δt = {DT_AH:g} s, {T_AH:g} s",
        _ok(nc < lc),
        {"nonlinear": nc, "linear": lc},
    )


# ---- Example 2 (sliding particle), Figs. 11–14: no stabilization --------------------------
def undamped_grows(runs: Runs, kind: str):
    """φ (kind "phi") or ΔE grows: the last fifth's max over the first fifth's, at both steps."""
    vals, parts, ok = {}, [], True
    for dt in (0.01, 0.001):
        r = runs[f"sp-undamped-dt{dt:g}"]
        v = r.violation["surface"] if kind == "phi" else drift(r)
        first, last = _fifths(v)
        vals[dt] = {"first_fifth": first, "last_fifth": last}
        ok &= last > 3 * first
        parts.append(f"Δt = {dt:g}: {num(first)} → {num(last)} (×{last / first:.3g})")
    tf = runs["sp-undamped-dt0.01"].t[-1]
    return (
        f"max{'|φ|' if kind == 'phi' else '|ΔE|'} first vs last fifth of {tf:g} s: " + "; ".join(parts),
        _ok(ok),
        vals,
    )


def undamped_smaller_step(runs: Runs, kind: str):
    """max|φ| (kind "phi") or max|ΔE| is smaller at Δt = 0.001 s than at 0.01 s."""
    big = runs["sp-undamped-dt0.01"]
    small = runs["sp-undamped-dt0.001"]
    if kind == "phi":
        b, s = big.summary["max_abs_violation"]["surface"], small.summary["max_abs_violation"]["surface"]
        unit = "m"
    else:
        b, s = big.summary["max_abs_energy_drift"], small.summary["max_abs_energy_drift"]
        unit = "J"
    return (
        f"Δt = 0.01: {num(b)} {unit}; Δt = 0.001: {num(s)} {unit} ({b / s:.3g} times smaller)",
        _ok(s < b),
        {"dt0.01": b, "dt0.001": s},
    )


# ---- Fig. 15: Baumgarte's terms (112) -------------------------------------------------
def fig15_damped_bound(runs: Runs):
    r = runs["sp-damped-dt0.001"]
    m = r.summary["max_abs_violation"]["surface"]
    ok_b, a, b = _bounded(r.violation["surface"])
    return (
        f"max|φ| = {m:.3e} m over {r.t[-1]:g} s (every step); max over first/second half "
        f"{a:.3e} / {b:.3e} ({'bounded' if ok_b else 'GROWING'})",
        _ok(m < 2.0e-11 and ok_b),
        {"max_abs_phi": m, "first_half": a, "second_half": b},
    )


# ---- Fig. 16: 1 h at Δt = 0.1 s; M minimal (137), N nonminimal, DN damped nonminimal ----
def _y_range(runs: Runs, key: str):
    y = runs[key].state["y"]
    return float(y.min()), float(y.max())


def fig16_damped_stays_in_bowl(runs: Runs):
    l0 = runs["sp-1h-damped"].settings["params"]["l0"]
    lo, hi = -0.1 * l0, 1.1 * l0
    dn, m = _y_range(runs, "sp-1h-damped"), _y_range(runs, "sp-1h-minimal")
    ok = lo <= dn[0] and dn[1] <= hi and lo <= m[0] and m[1] <= hi
    return (
        f"y over 1 h: DN [{dn[0]:.3f}, {dn[1]:.3f}] m, M [{m[0]:.3f}, {m[1]:.3f}] m "
        f"(bowl: [0, {l0:g}] m, allowed ±10 %)",
        _ok(ok),
        {"damped": dn, "minimal": m},
    )


def fig16_undamped_drifts_off(runs: Runs):
    l0 = runs["sp-1h-nonminimal"].settings["params"]["l0"]
    n = _absmax(runs["sp-1h-nonminimal"].state["y"])
    orders = math.log10(n / l0)
    return (
        f"N: max|y| = {num(n)} m = {orders:.1f} orders of magnitude above l0 = {l0:g} m; "
        f"max|φ| {num(runs['sp-1h-nonminimal'].summary['max_abs_violation']['surface'])} m",
        _ok(orders >= 2),
        {"max_abs_y": n, "orders": orders},
    )


def fig16_compared_with_fine_reference(runs: Runs):
    ref = runs["sp-1h-reference"]
    vals: dict[str, Any] = {}
    parts: list[str] = []
    for name, key in (("M", "sp-1h-minimal"), ("N", "sp-1h-nonminimal"), ("DN", "sp-1h-damped")):
        r = runs[key]
        y_ref = np.interp(r.t, ref.t, ref.state["y"])
        last = r.t >= r.t[-1] - 600
        rms = float(np.sqrt(np.mean((r.state["y"][last] - y_ref[last]) ** 2)))
        dE = float(drift(r)[-1])
        vals[name] = {
            "rms_last_10min": rms,
            "energy_drift_end": dE,
            "y_range_last_10min": (float(r.state["y"][last].min()), float(r.state["y"][last].max())),
        }
        parts.append(f"{name} {num(rms)} m (ΔE(1 h) {num(dE)} J)")
    E0 = float(ref.energy[0])
    ok = vals["DN"]["rms_last_10min"] < vals["N"]["rms_last_10min"] / 100
    return (
        "RMS of y − y_ref over the last 10 min: "
        + "; ".join(parts)
        + f"; E0 = {E0:.3g} J. DN is far closer than N, but neither M nor DN tracks the reference's "
        f"phase at Δt = 0.1 s, and DN has lost {abs(vals['DN']['energy_drift_end']) / E0:.0%} of E0 "
        f"(its y swings only over [{vals['DN']['y_range_last_10min'][0]:.2f}, "
        f"{vals['DN']['y_range_last_10min'][1]:.2f}] m at the end)",
        _ok(ok),
        vals,
    )


# ---- Fig. 17 vs Fig. 14 -------------------------------------------------------------------
def fig17_damping_increases_energy_error(runs: Runs):
    d = runs["sp-damped-dt0.001"].summary["max_abs_energy_drift"]
    u = runs["sp-undamped-dt0.001"]
    # same horizon for both: the undamped run may be shorter in quick mode
    dmp = runs["sp-damped-dt0.001"]
    within = dmp.t <= u.t[-1] + 1e-9
    d_same = _absmax(drift(dmp)[within])
    u_m = u.summary["max_abs_energy_drift"]
    return (
        f"max|ΔE| at Δt = 0.001 s over {u.t[-1]:g} s: damped {num(d_same)} J vs undamped {num(u_m)} J "
        f"(×{d_same / u_m:.3g}); damped over {dmp.t[-1]:g} s: {num(d)} J",
        _ok(d_same > u_m),
        {"damped": d_same, "undamped": u_m, "damped_full": d},
    )


# ---- Fig. 18: Baumgarte vs the post-step corrections of Blajer and of Yoon et al. ------
FIG18_RUNS = {"Baumgarte": "sp-fig18-baumgarte", "Blajer": "sp-fig18-blajer", "Yoon et al.": "sp-fig18-yoon"}


def fig18_all_bounded(runs: Runs):
    vals, parts, ok = {}, [], True
    for name, key in FIG18_RUNS.items():
        b, a1, a2 = _bounded(runs[key].violation["surface"])
        vals[name] = {"first_half": a1, "second_half": a2, "bounded": b}
        ok &= b
        parts.append(f"{name} {a1:.2e} / {a2:.2e}")
    return "max|φ| first / second half (m): " + "; ".join(parts), _ok(ok), vals


def fig18_baumgarte_smallest_bound(runs: Runs):
    m = {name: runs[key].summary["max_abs_violation"]["surface"] for name, key in FIG18_RUNS.items()}
    pre: dict[str, Any] = {}
    for name, key in FIG18_RUNS.items():
        p = runs.extra.get(f"precorrection:{key}")
        if name != "Baumgarte":
            pre[name] = p and {k: p[k] for k in ("max", "median", "samples", "stride")}
    smallest = min(m, key=lambda k: m[k])
    ok = smallest == "Baumgarte"
    text = "max|φ| (m): " + ", ".join(f"{k} {v:.2e}" for k, v in m.items())
    if all(pre.values()):
        text += (
            f"; one step before a correction (max over {next(iter(pre.values()))['samples']} "
            "steps sampled over the run): " + ", ".join(f"{k} {p['max']:.2e}" for k, p in pre.items())
        )
    one = runs.results.get("sp-fig18-oneshot")
    if one is not None and one.status == "ok":
        m["one-shot"] = one.summary["max_abs_violation"]["surface"]
        text += f"; one-shot variant {m['one-shot']:.2e}"
    if not ok:
        text += (
            f". DISAGREES with the paper: the post-step corrections hold |φ| at round-off, "
            f"{m['Baumgarte'] / max(m[smallest], 1e-300):.1e} times below Baumgarte's bound"
        )
    return text, _ok(ok), {"max_abs_phi": m, "precorrection": pre}


# --------------------------------------------------------------------------- the table
_AH = ("ah-nonlinear", "ah-linear")
_UNDAMPED = ("sp-undamped-dt0.01", "sp-undamped-dt0.001")
_FIG16 = ("sp-1h-minimal", "sp-1h-nonminimal", "sp-1h-damped", "sp-1h-reference")

CLAIMS: tuple[ClaimSpec, ...] = (
    ClaimSpec(
        "models_same_motion",
        (2, 3, 4, 5, 6, 7, 8),
        "The nonlinear (NC) and linear (LC) constraint models give the same motion",
        '"the solutions … should not be different, irrespective of the way the constraint '
        'equations are manipulated" (§2.5)',
        _AH,
        models_same_motion,
    ),
    ClaimSpec(
        "matches_kanes_method_oracle",
        (2, 3, 4, 5, 6, 7, 8),
        "The nonminimal solution agrees with Kane's minimal equations derived independently "
        "(sympy KanesMethod, DOP853, rtol 1e-11)",
        "— (cross-check, not in the paper)",
        ("ah-nonlinear",),
        matches_kanes_method_oracle,
    ),
    ClaimSpec(
        "theta_reaches_steady_state",
        (2, 4, 6),
        "θ tends to a constant steady-state value (θ̇ → 0) as the wheel keeps rolling",
        '"The angle θ tends to reach a constant steady state value" (text by Fig. 6)',
        ("ah-nonlinear",),
        theta_reaches_steady_state,
    ),
    ClaimSpec(
        "load_falls_wheel_speeds_up",
        (3, 5, 8),
        "The load falls (z decreases) and spins the wheel up (φ̇ increases)",
        "qualitative (Figs. 5, 8)",
        ("ah-nonlinear",),
        load_falls_wheel_speeds_up,
    ),
    ClaimSpec(
        "fig9_nonlinear_energy_drift_below_linear",
        (9,),
        "Nonlinear constraint model: smaller max|ΔE| than the linear model (same integrator, same Δt)",
        '"the nonlinearity in the constraint equations subdues the growing deviation in the total energy"',
        _AH,
        fig9_energy_drift,
    ),
    ClaimSpec(
        "fig11_12_undamped_violation_grows",
        (11, 12),
        "Without stabilization the constraint violation φ grows with time",
        '"It is clearly seen that φ grows with time"',
        _UNDAMPED,
        partial(undamped_grows, kind="phi"),
    ),
    ClaimSpec(
        "fig11_12_smaller_step_smaller_violation",
        (11, 12),
        "max|φ| is smaller at Δt = 0.001 s than at Δt = 0.01 s",
        '"Reducing Δt reduces the growth of φ"',
        _UNDAMPED,
        partial(undamped_smaller_step, kind="phi"),
    ),
    ClaimSpec(
        "fig13_14_undamped_energy_drift_grows",
        (13, 14),
        "Without stabilization |ΔE| grows with time",
        '"The same is concluded for … the energy integral E"',
        _UNDAMPED,
        partial(undamped_grows, kind="energy"),
    ),
    ClaimSpec(
        "fig13_14_smaller_step_smaller_energy_drift",
        (13, 14),
        "max|ΔE| is smaller at Δt = 0.001 s than at Δt = 0.01 s",
        '"The same is concluded for … E"',
        _UNDAMPED,
        partial(undamped_smaller_step, kind="energy"),
    ),
    ClaimSpec(
        "fig15_damped_bound",
        (15,),
        "Γ1 = −20, Γ2 = −100, Δt = 0.001 s, 500 s: φ stays bounded, |φ| < 2.0e−11 m",
        "|φ| < 2.0 × 10⁻¹¹ m (independent Kutta–Merson: ≈ 1.8 × 10⁻¹¹ m)",
        ("sp-damped-dt0.001",),
        fig15_damped_bound,
    ),
    ClaimSpec(
        "fig16_damped_stays_in_bowl",
        (16,),
        "Δt = 0.1 s, 1 h: the damped nonminimal (DN) y stays within the bowl's range, as the minimal (M) one does",
        "DN stays near the surface, M on it (Fig. 16)",
        _FIG16,
        fig16_damped_stays_in_bowl,
    ),
    ClaimSpec(
        "fig16_undamped_drifts_off",
        (16,),
        "Δt = 0.1 s, 1 h: the undamped nonminimal (N) y drifts off by orders of magnitude",
        '"the damping of constraint violations is crucial for accurate fast long-term simulations"',
        _FIG16,
        fig16_undamped_drifts_off,
    ),
    ClaimSpec(
        "fig16_compared_with_fine_reference",
        (16,),
        "Against a fine-step minimal reference, DN's y error is orders of magnitude below N's",
        'solutions compared with "the most accurate one obtained from … (137)"',
        _FIG16,
        fig16_compared_with_fine_reference,
    ),
    ClaimSpec(
        "fig17_damping_increases_energy_error",
        (14, 17),
        "With Baumgarte damping the energy deviation is larger than without (Fig. 17 vs 14)",
        '"This deviation represents a deterioration in accuracy compared to the '
        'constraint-unstabilized system for the same Δt"',
        ("sp-damped-dt0.001", "sp-undamped-dt0.001"),
        fig17_damping_increases_energy_error,
    ),
    ClaimSpec(
        "fig18_all_bounded",
        (18,),
        "Δt = 0.01 s: Baumgarte, Blajer and Yoon et al. all keep |φ| bounded",
        "all three bounded (Fig. 18)",
        tuple(FIG18_RUNS.values()),
        fig18_all_bounded,
    ),
    ClaimSpec(
        "fig18_baumgarte_smallest_bound",
        (18,),
        "Baumgarte (Γ1 = −20, Γ2 = −100) gives the smallest |φ| bound of the three",
        '"Clearly the augmentation of Baumgarte numerical stabilization terms yields better constraint '
        'violation dynamics"',
        tuple(FIG18_RUNS.values()),
        fig18_baumgarte_smallest_bound,
    ),
)
