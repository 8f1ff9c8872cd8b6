"""``nmkane tune SYSTEM [run options]``: Baumgarte gains for the given step size and integrator.

Γ (nonholonomic) and Γ1, Γ2 (holonomic) with the smallest max constraint violation over the
horizon, among runs that end ``ok``, keep every error eigenvalue λ with λ·Δt inside the
integrator's stability region, and keep the energy drift within ``--energy-factor`` × the
unstabilized run's (see :mod:`nmkane_core.sweep.tune`).  Gains given with ``--gamma``,
``--gamma1``, ``--gamma2`` are run too, and the report says where they stand.
Exit code 0 with a choice, 1 when no candidate qualifies, 2 on bad input.
"""

from __future__ import annotations

import argparse

from ..errors import InputError
from .argtypes import finite, positive_int
from .command import Command
from .common import load_plugged_systems
from .run_options import add_run_options, settings_from_args
from .sweep_cmd import add_sweep_options


def _add_arguments(p: argparse.ArgumentParser) -> None:
    add_run_options(p)
    p.add_argument(
        "--points", type=positive_int, default=10, help="candidates per gain axis (default 10; Γ1 × Γ2 is a grid)"
    )
    p.add_argument(
        "--energy-factor",
        dest="energy_factor",
        type=finite,
        default=10.0,
        help="allowed max energy drift as a multiple of the unstabilized run's (default 10)",
    )
    p.add_argument("--plot", metavar="FILE.png", help="draw the trade-off: violation against energy drift")
    add_sweep_options(p)


def _fmt(v) -> str:
    return "—" if v is None else f"{v:.3e}"


def _gains(g: dict) -> str:
    names = {"gamma": "Γ", "gamma1": "Γ1", "gamma2": "Γ2"}
    return ", ".join(f"{names[k]} = {v:.4g}" for k, v in g.items())


def report(res, system: str, energy_factor: float) -> str:
    """The choice and its numbers, as the terminal shows them."""
    from ..sweep.tune import rank

    ref = res.reference
    lines = [
        f"{system}: {res.integrator}, dt = {res.dt:g} s",
        f"stability   {res.integrator}'s real-axis interval is [{res.interval:.4f}, 0] (from its stability "
        f"polynomial): Γ·Δt ≥ {res.interval:.4f}, i.e. Γ ≥ {res.interval / res.dt:.4g} s⁻¹; every error "
        "eigenvalue λ (Γ; roots of s² − Γ1·s − Γ2) must have |R(λΔt)| ≤ 1",
        f"reference   Γ = Γ1 = Γ2 = 0: {ref['status']}, max |violation| "
        + ", ".join(f"{k} {v:.3e}" for k, v in ref["max_abs_violation"].items())
        + f"; max |ΔE| {_fmt(ref['max_abs_energy_drift'])} (allowed ×{energy_factor:g})",
    ]
    for stage, cands in res.stages.items():
        feas = sum(c.feasible for c in cands)
        stable = sum(c.stable for c in cands)
        best = res.chosen.get(stage)
        skipped = res.outside.get(stage, 0)
        head = (
            f"{stage:<11} {len(cands) + skipped} candidates, {skipped} outside the stability region (not run), "
            f"{len(cands) - stable} unstable, {feas} qualify: "
        )
        if best is None:
            lines.append(head + "none qualifies")
        else:
            lines.append(
                head + f"{_gains(best.gains)} → max |violation| {best.violation:.3e}, max |ΔE| {_fmt(best.energy)}"
            )
        g = res.given.get(stage)
        if g is not None:
            place = rank(res, stage)
            where = (
                f"ranks {place[0]} of {place[1]} qualifying"
                if place
                else (
                    "does not qualify: "
                    + (
                        "unstable for this step"
                        if not g.stable
                        else f"status {g.status}"
                        if g.status != "ok"
                        else "energy drift too large"
                    )
                )
            )
            lines.append(
                f"{'given':<11} {_gains(g.gains)} → max |violation| {_fmt(g.violation)}, "
                f"max |ΔE| {_fmt(g.energy)}; {where}"
            )
    f = res.final
    lines.append(
        f"chosen      {_gains(res.gains)}: {f['status']}, max |violation| "
        + ", ".join(f"{k} {v:.3e}" for k, v in f["max_abs_violation"].items())
        + f"; max |ΔE| {_fmt(f['max_abs_energy_drift'])}"
    )
    return "\n".join(lines)


def plot_tradeoff(res, path: str, title: str) -> None:
    """Violation against energy drift per stage; qualifying, chosen and given runs marked."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        from ..errors import NmkaneError

        raise NmkaneError("--plot needs matplotlib: pip install 'nmkane[figures]'") from None
    stages = list(res.stages)
    fig, axes = plt.subplots(1, len(stages), figsize=(6.4 * len(stages), 4.8), dpi=110, squeeze=False)
    for ax, stage in zip(axes[0], stages, strict=True):
        cands = [c for c in res.stages[stage] if c.violation and c.energy]
        for ok, style, label in ((True, "o", "qualifies"), (False, "x", "does not qualify")):
            sel = [c for c in cands if c.feasible == ok]
            ax.loglog([c.energy for c in sel], [c.violation for c in sel], style, label=label, alpha=0.7)
        for c, mark, label in ((res.chosen.get(stage), "*", "chosen"), (res.given.get(stage), "s", "given")):
            if c is not None and c.violation and c.energy:
                ax.loglog([c.energy], [c.violation], mark, ms=14, mfc="none", label=f"{label}: {_gains(c.gains)}")
        e_ref = res.reference.get("max_abs_energy_drift")
        if e_ref:
            ax.axvline(e_ref, color="grey", ls=":", label="unstabilized energy drift")
            ax.axvline(e_ref * res.energy_factor, color="red", ls="--", lw=0.8, label="allowed energy drift")
        ax.set_xlabel("max |ΔE|")
        ax.set_ylabel(f"max |violation| ({stage})")
        ax.set_title(f"{title}: {stage}")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _run(args: argparse.Namespace) -> int:
    from ..run.plan import validate_settings
    from ..sweep.executors import make_executor
    from ..sweep.tune import tune

    if args.plot and not args.plot.endswith((".png", ".svg", ".pdf")):
        raise InputError("--plot", args.plot, "a file name ending in .png, .svg or .pdf", "unknown format")
    load_plugged_systems(args)
    base = validate_settings(settings_from_args(args)).model_dump(exclude_none=True)
    with make_executor(
        args.dask, args.workers, systems=tuple(args.systems), warm=(base,), time_limit=args.time_limit
    ) as ex:
        res = tune(base, points=args.points, energy_factor=args.energy_factor, executor=ex)
    print(report(res, args.system, args.energy_factor))
    if args.plot:
        plot_tradeoff(res, args.plot, args.system)
        print(f"plot -> {args.plot}")
    return 0 if all(c is not None for c in res.chosen.values()) else 1


COMMAND = Command(
    "tune", "choose Γ (Γ1, Γ2) for a step size and integrator within its stability region", _add_arguments, _run
)
