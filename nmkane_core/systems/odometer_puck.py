"""A puck on a spring whose flywheel is geared to a measuring wheel: a constraint nonlinear
in the speeds.

A puck (mass m) slides on a horizontal plane, pulled to the origin by a spring k.  A
measuring wheel of radius ρ rolls on the plane in the direction the puck moves and drives
a flywheel (moment of inertia J, angle s): ṡ = |v|/ρ, i.e. the constraint
φ = ρ u3 − √(u1² + u2²) = 0, nonlinear (not even polynomial) in the speeds.  Its force is
along the velocity and does no work (φ is homogeneous of degree one in the speeds), so
E = m|v|²/2 + J ṡ²/2 + k|r|²/2 is conserved.  Along the path the puck is heavier —
m + J/ρ² — than across it (m): the tests compare with these intrinsic equations.
"""

from __future__ import annotations

from ..declare.system import Parameter, System

WHAT_TO_TRY = (
    "With J = 0 the orbit is a fixed ellipse. Raise the flywheel's inertia J: the puck gets heavier "
    "along its path only, so the ellipse precesses and changes shape while the energy stays "
    "constant. Speeds near zero make the constraint's gradient blow up — start with a good push. "
    "The measuring wheel's force on the puck (wheel.tangential) acts along the path: it brakes the "
    "puck where the flywheel speeds up and pushes where it slows down — work goes back and forth "
    "between them, none is lost."
)

INITIAL_CONTROLS = {  # the sliders of the initial values (ranges around the defaults)
    "x": (-2.0, 4.0, "x [m] (puck, from the anchor)"),
    "y": (-2.0, 2.0, "y [m] (puck, from the anchor)"),
    "s": (-2.0, 2.0, "s (flywheel angle) [rad]"),
    "u1": (-2.0, 2.0, "u1 = ẋ (puck's velocity along x) [m/s]"),
    "u2": (-1.6, 3.2, "u2 = ẏ (puck's velocity along y) [m/s]"),
}


def _model():
    import sympy as sp

    from ..symbolic.model import MechanicalModel, plain_symbols

    x, y, s = plain_symbols("x y s")
    u1, u2, u3 = plain_symbols("u1 u2 u3")
    m, J, rho, k = sp.symbols("m J rho k", positive=True)
    return MechanicalModel(
        q=(x, y, s),
        u=(u1, u2, u3),
        params=(m, J, rho, k),
        C=sp.eye(3),
        D=sp.zeros(3, 1),
        Q=sp.diag(m, m, J),
        P=sp.Matrix([-k * x, -k * y, 0]),
        nonholonomic={"odometer": rho * u3 - sp.sqrt(u1**2 + u2**2)},
        u_independent=(u1, u2),
        energy=m / 2 * (u1**2 + u2**2) + J / 2 * u3**2 + k / 2 * (x**2 + y**2),
        description="flywheel speed = path speed / ρ (nonlinear in the speeds)",
    )


def _visuals():
    import sympy as sp

    from ..declare.visuals import Frame, Visuals, box, cylinder, ground, rot_z, segments, sphere, trace
    from ..symbolic.model import plain_symbols

    x, y, s = plain_symbols("x y s")
    return Visuals(
        frames=(Frame("puck", (x, y, 0), None), Frame("flywheel", (x, y, sp.Float(0.16)), rot_z(s))),
        shapes=(
            ground(0),
            cylinder("puck", "puck", 0.2, 0.1, offset=(0, 0, 0.05), color=(40, 90, 200)),
            cylinder("flywheel", "flywheel", 0.16, 0.04, color=(200, 160, 40)),
            box("flywheel_mark", "flywheel", (0.16, 0.03, 0.05), (0.08, 0, 0), color=(60, 60, 70)),
            cylinder("anchor", None, 0.05, 0.3, offset=(0, 0, 0.15), color=(90, 90, 90)),
            segments("spring", [((0, 0, sp.Float(0.08)), (x, y, sp.Float(0.08)))], color=(150, 40, 30)),
            sphere("anchor_top", 0.07, None, (0, 0, 0.3), color=(90, 90, 90)),
            trace("path", (x, y, sp.Float(0.005))),
        ),
    )


def _forces(variant: str):
    """The measuring wheel's force on the puck, along the path: the constraint
    φ = ρ u3 − |v| is written on the puck's velocity v = (u1, u2), ∂φ/∂v = −v/|v|, so the force
    is R = −λ v/|v| — one component along the tangent v/|v| (the multiplier route)."""
    import sympy as sp

    from ..declare.forces import Forces, PointForce, multiplier
    from ..symbolic.model import plain_symbols

    x, y, u1, u2 = plain_symbols("x y u1 u2")
    speed = sp.sqrt(u1**2 + u2**2)
    return Forces(
        forces=(
            PointForce(
                "wheel",
                at=(x, y, sp.Float(0.05)),
                components=(-multiplier("odometer"),),
                frame=sp.Matrix([u1 / speed, u2 / speed, 0]),
                labels=("tangential",),
                route="multipliers",
                on="the puck, where the measuring wheel touches the plane",
                description="the force the measuring wheel's constraint puts on the puck, along its path "
                "(positive: pushing forward)",
            ),
        ),
    )


def odometer_puck() -> System:
    return System(
        name="odometer-puck",
        title="Puck with an odometer flywheel (nonlinear constraint)",
        variants=_model,
        parameters={
            "m": Parameter(1.0, 0.0, 100.0, "kg", "mass of the puck"),
            "J": Parameter(0.02, 0.0, 1.0, "kg·m²", "flywheel's moment of inertia", min_inclusive=True),
            "rho": Parameter(0.1, 0.0, 1.0, "m", "measuring wheel's radius"),
            "k": Parameter(1.0, 0.0, 100.0, "N/m", "spring stiffness"),
        },
        default_initial={"x": 1.0, "y": 0.0, "s": 0.0, "u1": 0.0, "u2": 0.8, "u3": 8.0},
        default_dt=0.005,
        default_t_final=30.0,
        description="ṡ = |v|/ρ: a constraint nonlinear in the speeds that does no work.",
        visuals=_visuals,
        forces=_forces,
        what_to_try=WHAT_TO_TRY,
        initial_controls=INITIAL_CONTROLS,
    )
