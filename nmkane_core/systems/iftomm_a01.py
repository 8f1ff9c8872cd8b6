"""IFToMM benchmark A01: the simple (planar) pendulum.

Published specification (IFToMM / MBS benchmark library, problem A01, M. González 2005,
http://lim.ii.udc.es/mbsbenchmark/dist/A01/A01_specification.xml): "The planar simple
pendulum is composed by a lumped mass of 1 kg and a massless link of 1 m length.  The
system is under gravity effects (9.81 N/kg acting in the negative y direction) ... The
analysis to be performed is a dynamic simulation with a duration of 2000 s.  Initially,
the system is at rest (all velocities are zero) and in horizontal position: the value for
the x-coordinate of point P1 is +1.0 m.  The reference solution for this problem is the
time-history of the position of point P1 (x and y coordinates).  The maximun allowed
errors are 1.0E-1 (low precission) and 1.0E-3 (high precission), measured with 4000 output
steps".  (The OpenSim 3.2 implementation, RehabEngGroup/MBSbenchmarksInOpenSim, simulates
10 s, with P1 starting at x = −1 m, in 0.637 s of CPU.)

Model: the point mass P1 at (x, y) with the bar as the holonomic constraint
``bar`` = x² + y² − L² (the nonminimal formulation, as the paper's Example 2), speeds
u1 = ẋ, u2 = ẏ.  No single partition serves the whole motion: with u_D = u1 (variant
``cartesian``) J2 = 2x vanishes where the pendulum hangs down, with u_D = u2 (variant
``cartesian-y``) J2 = 2y vanishes in the horizontal start.  The two are declared
equivalent, so a run switches from one to the other where the kernel's estimate of J2
flags it (the summary lists the switches; today's pivot-ratio estimate sees a 1×1 J2 only
where it is exactly 0 — ``cartesian-y`` at the start —, and near x = 0 the paper's path with
a small J2 is still accurate: docs/closed-loops.md); the rank-robust solve needs neither.

Exact motion: with α the angle from the downward vertical (α(0) = π/2, α̇(0) = 0),
sin(α/2) = k sn(K(k) − ω t, k), k = sin(π/4), ω = √(g/L) (:func:`exact_motion`).
"""

from __future__ import annotations

import math

from ..declare.system import Parameter, System

PARAMETERS = {
    "L": Parameter(1.0, 0.0, 100.0, "m", "length of the massless bar"),
    "m": Parameter(1.0, 0.0, 1e4, "kg", "the lumped mass P1"),
    "g": Parameter(9.81, 0.0, 100.0, "m/s²", "gravitational acceleration (along −y)", min_inclusive=True),
}

#: OpenSim 3.2 CPU time for A01 over 10 s (help/benchmarks/A01_SimplePendulum.rst: 0.637 s)
OPENSIM_CPU_S = 0.637

WHAT_TO_TRY = (
    "The pendulum is the paper's sliding particle on a circle: a point mass held by the bar "
    "x² + y² = L². At the page's step (Δt = 1e-3) the bar keeps its length to round-off (1e-11 m²) with "
    "or without Baumgarte terms. Take Δt = 0.05: without them (Γ1 = Γ2 = 0) the bar slowly shortens "
    "(x² + y² − L² reaches −1.5e-4 m² at 10 s and keeps falling); with Γ1 = −20, Γ2 = −100 it stays "
    "within 6e-5 m². Choose the model cartesian-y (u_D = ẏ): its J2 = 2y is 0 at the horizontal start, so "
    "the run begins on cartesian (u_D = ẋ) and switches back at t = 0.025 s (the status line says when). "
    "Where the bar hangs down, cartesian's J2 = 2x passes through 0 between steps: the run does not switch "
    "and stays on the exact motion. These runs use the paper's solve on each model's own partition; with "
    "solve = auto one model re-picks its partition where J2 becomes ill-conditioned, and the switches name "
    "the partitions (u_I = (u1) ↔ (u2)) instead of the models."
)


def model(name: str = "cartesian", dependent: str = "u1", partition: bool = True):
    """The nonminimal pendulum; ``dependent``: the speed solved from the constraint (u1 or u2)."""
    import sympy as sp

    from ..symbolic.model import MechanicalModel, plain_symbols

    x, y = plain_symbols("x y")
    u1, u2 = plain_symbols("u1 u2")
    L, m, g = sp.symbols("L m g", positive=True)
    return MechanicalModel(
        name=name,
        q=(x, y),
        u=(u1, u2),
        params=(L, m, g),
        C=sp.eye(2),
        D=sp.zeros(2, 1),
        Q=m * sp.eye(2),
        P=sp.Matrix([0, -m * g]),
        holonomic={"bar": x**2 + y**2 - L**2},
        u_independent=((u2,) if dependent == "u1" else (u1,)) if partition else (),
        q_dependent=((x,) if dependent == "u1" else (y,)) if partition else (),
        energy=m / 2 * (u1**2 + u2**2) + m * g * y,
        description=f"point mass on a bar x² + y² = L², u_D = {dependent}",
    )


def exact_motion(t, L: float = 1.0, g: float = 9.81):
    """(x, y, ẋ, ẏ) of P1 for the benchmark's start (horizontal, at rest, x = +L)."""
    import numpy as np
    from scipy.special import ellipj, ellipk

    k = math.sin(math.pi / 4)
    K = ellipk(k * k)
    om = math.sqrt(g / L)
    sn, cn, dn, _ = ellipj(K - om * np.asarray(t, float), k * k)
    s = k * sn  # sin(α/2)
    c = np.sqrt(1 - s * s)  # cos(α/2) ≥ 0 (|α| ≤ π/2)
    sin_a, cos_a = 2 * s * c, 1 - 2 * s * s
    # α̇: d/dt sin(α/2) = cos(α/2) α̇/2 = −k ω cn dn
    adot = -2 * k * om * cn * dn / c
    return L * sin_a, -L * cos_a, L * cos_a * adot, L * sin_a * adot


def acceptance(t, x_P1, y_P1) -> dict[str, float]:
    """The benchmark's quantity: the largest error of P1's position against the exact motion."""
    import numpy as np

    xe, ye, _, _ = exact_motion(t)
    return {"P1_position": float(max(np.abs(np.asarray(x_P1) - xe).max(), np.abs(np.asarray(y_P1) - ye).max()))}


def _visuals():
    import sympy as sp

    from ..declare.visuals import Visuals, segments, sphere, trace
    from ..symbolic.model import plain_symbols

    x, y = plain_symbols("x y")
    L = sp.Symbol("L", positive=True)
    return Visuals(
        shapes=(
            segments("support", [((-0.3 * L, 0, 0), (0.3 * L, 0, 0))], color=(80, 80, 80), thickness=3),
            segments("bar", [((0, 0, 0), (x, 0, y))], color=(90, 100, 115), thickness=3),
            sphere("P1", 0.06 * L, at=(x, 0, y), color=(214, 48, 39)),
            trace("P1_path", (x, 0, y)),
        ),
        view=(0.0, -1.0, 0.2),
    )


def iftomm_a01() -> System:
    return System(
        name="iftomm-a01",
        title="IFToMM A01: simple pendulum",
        variants={
            "cartesian": lambda: model("cartesian", "u1"),
            "cartesian-y": lambda: model("cartesian-y", "u2"),
        },
        default_variant="cartesian",
        equivalents={"cartesian": ("cartesian-y",), "cartesian-y": ("cartesian",)},
        singular_hints={
            "cartesian": "J2 = 2x vanishes where the bar hangs down (x = 0).",
            "cartesian-y": "J2 = 2y vanishes where the bar is horizontal (y = 0).",
        },
        parameters=PARAMETERS,
        default_initial={"x": 1.0, "y": 0.0, "u1": 0.0, "u2": 0.0},
        initial_controls={
            "y": (-1.0, 1.0, "y [m] (the mass's height; x follows from the bar)"),
            "u2": (-5.0, 5.0, "u2 = ẏ (the mass's vertical speed) [m/s]"),
        },
        default_dt=1e-3,
        default_t_final=2000.0,
        default_integrator="kutta-merson",
        # the paper's solve on each declared partition, the equivalent variants switching between
        # them: what this page teaches; solve="auto" re-partitions inside one model instead
        default_solve="paper",
        default_gamma1=-20.0,
        default_gamma2=-100.0,
        description="IFToMM benchmark A01: a 1 kg mass on a massless 1 m bar, released horizontal; 2000 s.",
        visuals=_visuals,
        what_to_try=WHAT_TO_TRY,
        showcase={"t_final": 10.0},
    )
