"""The knife edge (a skate) on a horizontal plane: the simplest nonholonomic system.

Its blade cannot slip sideways.  With no forces the forward speed v and the turning rate ω
stay constant and the contact point runs on a circle of radius v/ω (a closed form the
tests compare with).  Model: `._planar` with the mass centre on the contact point.
"""

from __future__ import annotations

from ..declare.system import Parameter, System
from ._planar import blade_model

WHAT_TO_TRY = (
    "Set the turning rate u3 to zero: the skate runs straight. Any other value draws a circle of "
    "radius u1/u3 — change u1 and u3 and watch the radius follow. The blade force (the arrow at the "
    "blade, blade.lateral) keeps the blade from slipping: it points to the circle's centre and is "
    "exactly the centripetal force m v ω (1 × 1 × 0.5 = 0.5 N by default) — double u1 and it doubles. "
    "It does no work: the energy drift stays at round-off."
)

INITIAL_CONTROLS = {  # the sliders of the initial values (ranges around the defaults)
    "x": (-2.0, 2.0, "x [m] (blade's contact point)"),
    "y": (-2.0, 2.0, "y [m] (blade's contact point)"),
    "theta": (-2.0, 2.0, "θ (heading) [rad]"),
    "u1": (-2.0, 4.0, "u1 (forward speed) [m/s]"),
    "u3": (-1.5, 2.5, "u3 = θ̇ (turning rate) [rad/s]"),
}


def _model():
    return blade_model("default", with_offset=False)


def _visuals():
    import sympy as sp

    from ..declare.visuals import Frame, Visuals, box, ground, rot_z, sphere, trace
    from ..symbolic.model import plain_symbols

    x, y, th = plain_symbols("x y theta")
    return Visuals(
        frames=(Frame("blade", (x, y, 0), rot_z(th)),),
        shapes=(
            ground(0),
            box("blade", "blade", (0.8, 0.03, 0.12), (0, 0, 0.06), color=(90, 100, 115)),
            box("boot", "blade", (0.5, 0.22, 0.25), (-0.05, 0, 0.245), color=(40, 90, 200)),
            sphere("toe", 0.06, "blade", (0.4, 0, 0.12), color=(230, 180, 40)),
            trace("path", (x, y, sp.Float(0.005))),
        ),
    )


def _forces(variant: str):
    """The blade force on the skate: the constraint u2 = v_P · B.y = 0 is written on the contact
    point's velocity, so the force at P is λ ∂u2/∂v_P = λ B.y (the multiplier route)."""
    from ._planar import blade_force

    return blade_force("the skate, at its blade")


def knife_edge() -> System:
    return System(
        name="knife-edge",
        title="Knife edge (skate)",
        variants=_model,
        parameters={
            "m": Parameter(1.0, 0.0, 100.0, "kg", "mass"),
            "I": Parameter(0.1, 0.0, 10.0, "kg·m²", "moment of inertia about the vertical"),
        },
        default_initial={"x": 0.0, "y": 0.0, "theta": 0.0, "u1": 1.0, "u3": 0.5},
        default_dt=0.01,
        default_t_final=20.0,
        description="A blade that cannot slip sideways: it runs on a circle of radius v/ω.",
        visuals=_visuals,
        forces=_forces,
        what_to_try=WHAT_TO_TRY,
        initial_controls=INITIAL_CONTROLS,
    )
