"""The Chaplygin sleigh: a rigid body on a blade whose mass centre is a distance ``a``
ahead of the contact point.

With the blade's no-side-slip constraint the forward speed v of the contact point and
the turning rate ω obey v̇ = a ω², ω̇ = −(m a / J) v ω with J = I + m a² (I about the
mass centre).  Energy E = (m v² + J ω²)/2 is conserved, so with V = √(2E/m),
s(t) = (m a V / J) t + artanh(v0/V):  v = V tanh s,  ω = sign(ω0) √(m/J) V sech s —
any spin is converted into straight motion (the tests compare the run with this).
"""

from __future__ import annotations

from ..declare.system import Parameter, System
from ._planar import blade_model

WHAT_TO_TRY = (
    "Start it spinning (u3) with little forward speed: the spin dies away and the sleigh ends up "
    "sliding straight ahead at the speed √(2E/m) — energy is converted, not lost. Put the mass "
    "centre behind the blade (a < 0): the straight motion backwards is the one that survives. With a "
    "= 0 it is a knife edge again and turns for ever. Watch the blade force (blade.lateral): it is "
    "m v ω I/(I + m a²), less than the centripetal force of a point mass, and it fades with the spin — "
    "a sideways push on the blade is what turns spin into forward speed."
)

INITIAL_CONTROLS = {  # the sliders of the initial values (ranges around the defaults)
    "x": (-2.0, 2.0, "x [m] (blade's contact point)"),
    "y": (-2.0, 2.0, "y [m] (blade's contact point)"),
    "theta": (-2.0, 2.0, "θ (heading) [rad]"),
    "u1": (-1.9, 2.1, "u1 (forward speed) [m/s]"),
    "u3": (-4.0, 8.0, "u3 = θ̇ (spin) [rad/s]"),
}


def _model():
    return blade_model("default", with_offset=True)


def _visuals():
    import sympy as sp

    from ..declare.visuals import Frame, Visuals, box, ground, rot_z, sphere, trace
    from ..symbolic.model import plain_symbols

    x, y, th = plain_symbols("x y theta")
    a = sp.Symbol("a", real=True)
    G = (x + a * sp.cos(th), y + a * sp.sin(th), sp.Float(0.25))
    return Visuals(
        frames=(Frame("sleigh", (x, y, 0), rot_z(th)),),
        shapes=(
            ground(0),
            box("blade", "sleigh", (0.5, 0.03, 0.1), (0, 0, 0.05), color=(90, 100, 115)),
            box("deck", "sleigh", (sp.Abs(a) + 1.0, 0.6, 0.06), (a / 2, 0, 0.13), color=(170, 110, 60)),
            box("runner_l", "sleigh", (sp.Abs(a) + 1.0, 0.04, 0.04), (a / 2, 0.3, 0.02), color=(120, 80, 40)),
            box("runner_r", "sleigh", (sp.Abs(a) + 1.0, 0.04, 0.04), (a / 2, -0.3, 0.02), color=(120, 80, 40)),
            sphere("mass_centre", 0.1, at=G, color=(220, 60, 40)),
            trace("blade_path", (x, y, sp.Float(0.005))),
            trace("centre_path", (G[0], G[1], sp.Float(0.006)), color=(40, 120, 220)),
        ),
    )


def _forces(variant: str):
    """The blade force on the sleigh, λ B.y at the blade's contact point (the multiplier route)."""
    from ._planar import blade_force

    return blade_force("the sleigh, at its blade")


def chaplygin_sleigh() -> System:
    return System(
        name="chaplygin-sleigh",
        title="Chaplygin sleigh",
        variants=_model,
        parameters={
            "m": Parameter(1.0, 0.0, 100.0, "kg", "mass"),
            "I": Parameter(0.1, 0.0, 10.0, "kg·m²", "moment of inertia about the mass centre"),
            "a": Parameter(0.5, -2.0, 2.0, "m", "mass centre ahead of the blade", min_inclusive=True),
        },
        default_initial={"x": 0.0, "y": 0.0, "theta": 0.0, "u1": 0.1, "u3": 2.0},
        default_dt=0.01,
        default_t_final=20.0,
        description="A blade behind the mass centre: spin is converted into straight motion.",
        visuals=_visuals,
        forces=_forces,
        what_to_try=WHAT_TO_TRY,
        initial_controls=INITIAL_CONTROLS,
    )
