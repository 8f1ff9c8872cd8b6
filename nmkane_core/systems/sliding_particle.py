"""Example 2 of the paper: a particle sliding on the parabola (114), eqs. (114)–(137).

Gravity acts along +y (y points down, the parabola is a bowl).  Coordinates (x, y),
speeds u1 = ẋ, u2 = ẏ, u_I = u1.  Two formulations: ``nonminimal`` — the paper's method
with the holonomic constraint ψ = y + x²/l0 − l0 in acceleration form, optionally with the
Baumgarte terms (112); ``minimal`` — Kane's minimal equation (137) in x alone, derived
here with KanesMethod from the particle constrained to the curve, reporting y and u2 as
outputs.

Visuals: the bowl ψ = 0 as a translucent strip and the particle, drawn with y pointing
down (at height −y).  The viewer starts on the paper's Fig. 16-like comparison
(``showcase``): the damped nonminimal run (DN: Γ1 = −20, Γ2 = −100) with two ghosts, the
minimal solution (M) and the same run undamped (N: Γ = 0).
"""

from __future__ import annotations

from ..declare.system import Parameter, System

PARAMETERS = {
    "l0": Parameter(1.0, 0.0, 1e3, "m", "parabola parameter in ψ = y + x²/l0 − l0"),
    "m": Parameter(1.0, 0.0, 1e6, "kg", "mass of the particle"),
    "g": Parameter(9.81, 0.0, 1e3, "m/s²", "gravitational acceleration (along +y)", min_inclusive=True),
}


WHAT_TO_TRY = (
    "The page opens on the paper's Fig. 16 comparison: the damped nonminimal run (DN: Γ1 = −20, Γ2 = −100) "
    "with two ghosts, the minimal solution (M, Kane's equation (137)) and the same nonminimal run without "
    "stabilization (N: Γ = 0). Watch log₁₀|φ|: undamped, the particle drifts off the parabola; damped, it "
    "stays on it; the minimal equation has no constraint to violate. Make Δt smaller: the undamped drift "
    "shrinks (Figs. 11–12). Positive gains make the constraint error grow: with Γ1 = +1 it grows without "
    "bound until the run stops, status drifted, where the energy passes 10⁶ times its initial scale (t ≈ 28 s)."
)

INITIAL_CONTROLS = {  # the sliders of the independent initial values (y and u2 follow from the parabola)
    "x": (-2.0, 4.0, "x [m] (y follows)"),
    "u1": (-2.0, 2.0, "u1 = ẋ [m/s] (u2 follows)"),
}


def _nonminimal():
    import sympy as sp

    from ..symbolic.model import MechanicalModel, plain_symbols

    x, y = plain_symbols("x y")
    u1, u2 = plain_symbols("u1 u2")
    l0, m, g = sp.symbols("l0 m g", real=True)
    return MechanicalModel(
        name="nonminimal",
        q=(x, y),
        u=(u1, u2),
        params=(l0, m, g),
        C=sp.eye(2),
        D=sp.zeros(2, 1),
        Q=m * sp.eye(2),
        P=sp.Matrix([0, m * g]),  # (118) holonomic system
        holonomic={"surface": y + x**2 / l0 - l0},  # (114)
        u_independent=(u1,),
        energy=m / 2 * (u1**2 + u2**2) + m * g * (l0 - y),  # (123)
        q_dependent=(y,),
        description="nonminimal equations (119)–(126)",
    )


def _minimal():
    import sympy as sp
    from sympy.physics import mechanics as me

    from ..symbolic.model import MechanicalModel

    x = me.dynamicsymbols("x")
    u1 = me.dynamicsymbols("u1")
    l0, m, g = sp.symbols("l0 m g", real=True)
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    y_of_x = l0 - x**2 / l0  # (114) solved for y
    Pp = O.locatenew("P", x * N.x + y_of_x * N.y)  # (127)
    Pp.set_vel(N, u1 * N.x + y_of_x.diff(x) * u1 * N.y)  # (129)
    u2_of = y_of_x.diff(x) * u1
    energy = m / 2 * (u1**2 + u2_of**2) + m * g * (l0 - y_of_x)
    return MechanicalModel.from_mechanics(
        "minimal",
        q=[x],
        u=[u1],
        kd_eqs=[x.diff(me.dynamicsymbols._t) - u1],
        bodies=[me.Particle("Pm", Pp, m)],
        loads=[(Pp, m * g * N.y)],
        frame=N,
        params=(l0, m, g),
        energy=energy,
        outputs={"y": y_of_x, "u2": u2_of},
        monitors={"surface": sp.simplify(y_of_x + x**2 / l0 - l0)},
        description="Kane's minimal equation (137)",
    )


def _visuals():
    import sympy as sp

    from ..declare.visuals import Visuals, sphere, strip
    from ..symbolic.model import plain_symbols

    x, y = plain_symbols("x y")
    l0 = sp.Symbol("l0", real=True)
    path = [(s * l0, 0, s**2 * l0 - l0) for s in (sp.Rational(k - 40, 25) for k in range(81))]  # x ∈ ±1.6 l0
    return Visuals(
        shapes=(
            strip("bowl", path, 1.0, "y"),
            # 0.4 m across: large enough to see in the first view, which frames its whole ±1 m motion
            sphere("particle", 0.2, at=(x, 0, -y), color=(31, 119, 180)),
        ),
        view=(0.0, -1.0, 0.3),
    )


def _forces(variant: str):
    """The surface's normal force on the particle, along the parabola's tangent and normal.

    The axes are drawn in the visuals' world ((x, y) at (x, 0, −y)): t̂ along increasing x,
    n̂ out of the bowl (the concave side).  ``nonminimal``: R = λ ∇ψ, the multiplier route
    (the constraint is written on the position, ψ̇ = ∇ψ · v: ∂ψ̇/∂v = ∇ψ); ``minimal``: Newton's
    law on the particle, R = m a − m g ŷ with a = (u̇1, d(u2)/dt), u2 = −2x u1/l0 on the curve.
    The tangential component is zero (no friction): a check of either route."""
    import sympy as sp

    from ..declare.forces import Forces, PointForce, multiplier, rate
    from ..symbolic.model import plain_symbols

    x, y, u1 = plain_symbols("x y u1")
    l0, m, g = sp.symbols("l0 m g", real=True)
    slope = 2 * x / l0  # |∇ψ|² = 1 + slope²
    s = sp.sqrt(1 + slope**2)
    t_model, n_model = sp.Matrix([1, -slope]) / s, sp.Matrix([-slope, -1]) / s
    if variant == "nonminimal":
        R = multiplier("surface") * sp.Matrix([slope, 1])  # λ ∇ψ
        route = "multipliers"
    else:
        a = sp.Matrix([rate("u1"), -2 * (u1**2 + x * rate("u1")) / l0])
        R = m * a - sp.Matrix([0, m * g])
        route = "newton"
    world = sp.Matrix([[1, 0], [0, 0], [0, -1]])  # model (x, y) → world (x, 0, −y)
    return Forces(
        forces=(
            PointForce(
                "normal",
                at=(x, 0, -y),
                components=(sp.simplify(R.dot(t_model)), R.dot(n_model)),
                frame=(world * t_model).row_join(world * n_model),
                labels=("tangential", "normal"),
                route=route,
                on="the particle",
                description="the surface's force on the particle: m g cos α + m v² κ along the normal, none along "
                "the tangent",
            ),
        ),
    )


def sliding_particle() -> System:
    return System(
        name="sliding-particle",
        title="Particle sliding on a parabola (Example 2)",
        option="formulation",
        variants={"nonminimal": _nonminimal, "minimal": _minimal},
        default_variant="nonminimal",
        parameters=PARAMETERS,
        default_initial={"x": 1.0, "y": 0.0, "u1": 0.0, "u2": 0.0},
        completion_variant="nonminimal",
        default_dt=0.01,
        default_t_final=20.0,
        default_integrator="kutta-merson",
        default_solve="paper",  # the paper's solve on the declared partition, as the paper runs it
        description=(
            "The paper's Example 2: a particle sliding without friction on the parabola ψ = y + x²/l0 − l0 = 0 "
            "(114), gravity along +y (y points down: the parabola is a bowl). The holonomic constraint is used "
            "in acceleration form; its drift is damped by the Baumgarte gains Γ1, Γ2 (112)."
        ),
        visuals=_visuals,
        forces=_forces,
        what_to_try=WHAT_TO_TRY,
        initial_controls=INITIAL_CONTROLS,
        # the paper's Fig. 16-like comparison: DN shown, M and N (Γ = 0) as ghosts
        showcase={"gamma1": -20.0, "gamma2": -100.0, "dt": 0.05, "t_final": 300.0, "compare": "all", "speed": 5.0},
    )
