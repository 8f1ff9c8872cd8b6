"""The paper's Figures 2–9 and 11–18: caption, runs, how each is drawn, and what it shows.

:data:`FIGURES` is the list the report follows; :func:`facts` gathers the measured numbers
its "what this shows" paragraphs quote.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .claims import PASS, Claim
from .drawing import draw_ah, draw_ex2, draw_fig4, draw_fig6, draw_fig7, draw_fig9, draw_fig16, draw_fig18
from .runs import Runs

__all__ = ["FigureSpec", "FigureResult", "FIGURES", "facts"]


@dataclass
class FigureSpec:
    """One figure of the paper, as this report draws and explains it."""

    number: int
    slug: str
    caption: str  # the paper's caption
    runs: tuple[str, ...]
    draw: Callable  # draw(fig, runs): fills the matplotlib Figure (drawing.py)
    explain: str  # what this shows, in plain words (may use {name} fields from `facts`)
    note: str = ""


@dataclass
class FigureResult:
    """A figure as written into the report: its PNG, its claims, or why it was not drawn."""

    number: int
    file: str
    caption: str
    explain: str
    runs: list[str]
    claims: list[Claim]
    note: str = ""
    error: str | None = None


FIGURES: tuple[FigureSpec, ...] = (
    FigureSpec(
        2,
        "theta",
        r"Figure 2. Example 1: $\theta$ vs. t.",
        ("ah-nonlinear", "ah-linear"),
        draw_ah("theta", r"$\theta$ (rad)"),
        "θ is the heading of the wheel's plane. It starts turning at 1 rad/s, the turning dies "
        "out within a few seconds, and the heading then stays fixed (≈ {theta_end:.3f} rad): from "
        "then on the wheel rolls straight ahead. The two ways of writing the rolling constraints "
        "(nonlinear NC, linear LC) give the same curve, and so does an independent derivation of "
        "Kane's minimal equations with sympy (circles).",
    ),
    FigureSpec(
        3,
        "phi",
        r"Figure 3. Example 1: $\phi$ vs. t.",
        ("ah-nonlinear", "ah-linear"),
        draw_ah("phi", r"$\phi$ (rad)"),
        "φ is the angle the wheel has rolled through. The curve bends upward: the load pulls the "
        "thread off the drum, so the wheel rolls faster and faster (here φ is the wheel's angle, "
        "not the constraint violation of Example 2).",
    ),
    FigureSpec(
        4,
        "theta_dot",
        r"Figure 4. Example 1: $\dot{\theta}$ vs. t.",
        ("ah-nonlinear", "ah-linear"),
        draw_fig4,
        "The turning rate θ̇ falls from 1 rad/s to zero (|θ̇| ≈ {theta_dot_end:.1e} rad/s at the end): "
        "the mechanism stops turning and only rolls.",
    ),
    FigureSpec(
        5,
        "phi_dot",
        r"Figure 5. Example 1: $\dot{\phi}$ vs. t.",
        ("ah-nonlinear", "ah-linear"),
        draw_ah("u2", r"$\dot{\phi}$ (rad/s)"),
        "The rolling rate φ̇ grows steadily: the load's weight acts through the drum like a constant "
        "torque, so once the turning has died out the wheel speeds up at a constant rate, like a "
        "body sliding down a frictionless incline.",
    ),
    FigureSpec(
        6,
        "theta_dot_vs_phi",
        r"Figure 6. Example 1: $\dot{\theta}$ vs. $\phi$.",
        ("ah-nonlinear", "ah-linear"),
        draw_fig6,
        "The same turning rate plotted against how far the wheel has rolled: θ̇ reaches zero within "
        "the first turns of the wheel and stays there while φ keeps growing — the steady state the "
        "paper describes.",
    ),
    FigureSpec(
        7,
        "y_vs_x",
        "Figure 7. Example 1: y vs. x.",
        ("ah-nonlinear", "ah-linear"),
        draw_fig7,
        "The load's track on the x-y plane (it rides on the frame). It curves while the mechanism "
        "turns and then runs along a straight line, with the points spaced further and further "
        "apart as the mechanism speeds up.",
    ),
    FigureSpec(
        8,
        "z",
        "Figure 8. Example 1: z vs. t.",
        ("ah-nonlinear", "ah-linear"),
        draw_ah("z", "z (m)"),
        "The load's height falls faster and faster, as the thread unwinds from the drum. The model "
        "has no floor: the load passes z = 0 and keeps falling (the web app shows it dropping "
        "into a shaft).",
        note='The paper\'s caption reads "Example 3.1: z vs. t.", a slip for Example 1.',
    ),
    FigureSpec(
        9,
        "energy_lc_nc",
        "Figure 9. Example 1: Energy integral, LC: linear constraints, NC: nonlinear constraints.",
        ("ah-nonlinear", "ah-linear"),
        draw_fig9,
        "The mechanism is conservative, so its energy E should never change; ΔE is purely numerical "
        "error. Both models are integrated with the same method and step. The errors are tiny "
        "(nano-joules) but the nonlinear model's stays smaller (max|ΔE| NC/LC = {nc_lc:.2f}): "
        "writing the constraints nonlinearly in the speeds acts as a passive damper of numerical "
        "error, which is the paper's point.",
    ),
    FigureSpec(
        11,
        "phi_undamped_dt0.01",
        r"Figure 11. Example 2: Constraint violation, $\phi$: $\Gamma_1 = \Gamma_2 = 0$, $\Delta t = 0.01$ s.",
        ("sp-undamped-dt0.01",),
        draw_ex2("sp-undamped-dt0.01", "phi"),
        "φ measures how far the computed particle is off the bowl's surface. The nonminimal "
        "equations hold the particle on the surface only through the surface's second time "
        "derivative (φ̈ = 0), so nothing pulls back the small error each step makes in φ and φ̇: "
        "it is integrated twice and piles up, and |φ| keeps growing (lower panel, log scale).",
    ),
    FigureSpec(
        12,
        "phi_undamped_dt0.001",
        r"Figure 12. Example 2: Constraint violation, $\phi$: $\Gamma_1 = \Gamma_2 = 0$, $\Delta t = 0.001$ s.",
        ("sp-undamped-dt0.001",),
        draw_ex2("sp-undamped-dt0.001", "phi"),
        "The same with a ten times smaller step: the drift still grows with time, but it is about "
        "{phi_ratio:.2g} times smaller — paid for with ten times more steps.",
    ),
    FigureSpec(
        13,
        "energy_undamped_dt0.01",
        r"Figure 13. Example 2: Energy integral: $\Gamma_1 = \Gamma_2 = 0$, $\Delta t = 0.01$ s.",
        ("sp-undamped-dt0.01",),
        draw_ex2("sp-undamped-dt0.01", "energy"),
        "The particle's energy should stay at its initial value m g l0; the deviation ΔE grows "
        "along with the constraint drift: a particle that drifts off the surface no longer feels "
        "the right forces.",
    ),
    FigureSpec(
        14,
        "energy_undamped_dt0.001",
        r"Figure 14. Example 2: Energy integral: $\Gamma_1 = \Gamma_2 = 0$, $\Delta t = 0.001$ s.",
        ("sp-undamped-dt0.001",),
        draw_ex2("sp-undamped-dt0.001", "energy"),
        "With the smaller step the energy error is far smaller but still grows. Compare its size with Fig. 17.",
    ),
    FigureSpec(
        15,
        "phi_damped_dt0.001",
        r"Figure 15. Example 2: Constraint violation, $\phi$: $\Gamma_1 = -20$, $\Gamma_2 = -100$, "
        r"$\Delta t = 0.001$ s.",
        ("sp-damped-dt0.001",),
        draw_ex2("sp-damped-dt0.001", "phi", bound=(2.0e-11, "paper's bound |φ| < 2.0e−11 m")),
        'Baumgarte\'s terms replace "the surface\'s acceleration error is zero" by "φ̈ + 20 φ̇ + 100 φ '
        '= 0": any drift now dies out like a critically damped spring with a 0.1 s time constant, '
        "instead of accumulating. φ no longer grows; it stays at the level the step's local error "
        "feeds in, below 2·10⁻¹¹ m ({phi15:.2e} m measured).",
    ),
    FigureSpec(
        16,
        "y_1h_dt0.1",
        r"Figure 16. Example 2: $y$ solution after 1 h, $\Delta t = 0.1$ s: M minimal, N nonminimal "
        r"($\Gamma_1 = \Gamma_2 = 0$), DN damped nonminimal ($\Gamma_1 = -20$, $\Gamma_2 = -100$).",
        ("sp-1h-minimal", "sp-1h-nonminimal", "sp-1h-damped", "sp-1h-reference"),
        draw_fig16,
        "A coarse step (0.1 s) over an hour. Without stabilization (N) the particle drifts off the "
        "bowl to y ≈ {n_max:.0e} m — nonsense. With Baumgarte's terms (DN) it stays on the bowl, "
        "as the minimal equation (M, which cannot leave the surface) does. Staying on the surface "
        "is not the same as being accurate, as the paper warns: against a fine-step reference both "
        "M and DN are out of phase after an hour, and DN has bled away {dn_loss:.0%} of its energy, "
        "so its swing has shrunk to the bottom of the bowl (right panel).",
    ),
    FigureSpec(
        17,
        "energy_damped_dt0.001",
        r"Figure 17. Example 2: Energy integral deviation $\Delta E$: $\Gamma_1 = -20$, $\Gamma_2 = -100$, "
        r"$\Delta t = 0.001$ s.",
        ("sp-damped-dt0.001",),
        draw_ex2("sp-damped-dt0.001", "energy"),
        "The price of the stabilization: the Baumgarte terms are extra forces that do work, so the "
        "energy error is larger than without them at the same step (about {e17_ratio:.0f} times Fig. 14's), "
        "even though the constraint is now held (Fig. 15).",
    ),
    FigureSpec(
        18,
        "phi_baumgarte_blajer_yoon",
        r'Figure 18. Example 2: Constraint violation $\phi$: $\Delta t = 0.01$ s; "1" Baumgarte, '
        r'"2" Blajer, "3" Yoon et al.',
        ("sp-fig18-baumgarte", "sp-fig18-blajer", "sp-fig18-yoon", "sp-fig18-oneshot"),
        draw_fig18,
        "Two ways to stop the drift. Baumgarte changes the equations of motion so that drift decays "
        "on its own; the post-step corrections of Blajer and of Yoon et al. leave the equations alone "
        "and, after every step, move the state back onto the surface (positions, then speeds). "
        "{f18_verdict} The two papers' texts were not available, so the presets follow the family "
        "both belong to (see nmkane_core.integrate.projection and the claims table for the numbers).",
        note="Fig. 18's horizon is not stated in the paper; 500 s is used, as for Figs. 11–15 (100 s in quick "
        "mode). The "
        "upper panel shows the maximum of |φ| per window on a log scale (a signed linear plot "
        "would show the projections as a flat line at zero).",
    ),
)


def facts(runs: Runs, claims: dict[str, Claim]) -> dict:
    """Numbers quoted in the "what this shows" paragraphs (NaN when a run is missing)."""
    nan = float("nan")
    f: dict[str, Any] = dict(
        theta_end=nan,
        theta_dot_end=nan,
        nc_lc=nan,
        phi_ratio=nan,
        phi15=nan,
        n_max=nan,
        dn_loss=nan,
        e17_ratio=nan,
        b18=nan,
        f18_verdict="",
    )

    def v(k: str) -> Any:
        return claims[k].values if k in claims and claims[k].values else None

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
            runs["sp-1h-reference"].energy[0]
        )
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
            f["f18_verdict"] = (
                f"Measured here, Baumgarte's bound ({b:.1e} m) is the smallest of the three, as the paper concludes."
            )
        else:
            proj = max(m["Blajer"], m["Yoon et al."])
            text = (
                f"Measured here, the corrections hold |φ| at {proj:.0e} m (round-off), far below "
                f"Baumgarte's ≈ {b:.1e} m: the opposite of the paper's conclusion."
            )
            if pre and all(pre.values()):
                worst = max(p["max"] for p in pre.values())
                if worst < b:
                    text += (
                        f" Even the violation one step before a correction (sampled, at most "
                        f"{worst:.1e} m) stays below Baumgarte's bound."
                    )
                else:
                    text += (
                        f" The violation one step before a correction (sampled) reaches {worst:.1e} m, "
                        "above Baumgarte's bound: only the corrected states are on the surface."
                    )
            f["f18_verdict"] = text
    if runs.ok("sp-fig18-blajer") and runs.ok("sp-fig18-yoon"):
        eb = runs["sp-fig18-blajer"].summary["max_abs_energy_drift"]
        ey = runs["sp-fig18-yoon"].summary["max_abs_energy_drift"]
        f["f18_verdict"] += (
            f" The 'blajer' preset also restores the energy (max|ΔE| {eb:.1e} J); 'yoon' "
            f"does not ({ey:.1e} J; Baumgarte's is larger still, lower panel)."
        )
    return f
