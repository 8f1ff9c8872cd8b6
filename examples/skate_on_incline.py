"""A skate on an inclined plane — an nmkane systems file with one linear nonholonomic constraint.

Load it with ``nmkane run skate-on-incline --systems examples/skate_on_incline.py``.

A blade (mass m, moment of inertia I about its contact point, which is its centre of
mass) slides on a plane inclined at angle α; x points down the slope.  The blade cannot
slip sideways: −sin θ ẋ + cos θ ẏ = 0 (linear in the speeds).  A classic of nonholonomic
mechanics (Neimark & Fufaev): started with a spin ω, the skate does not run away downhill
— θ = ωt, and x oscillates within g sin α/ω² of its start while y drifts sideways at the
mean speed g sin α/(2ω).  Energy (kinetic plus potential) is conserved.

Coordinates q = (x, y, θ), speeds u = (ẋ, ẏ, θ̇).  One constraint: one dependent speed.
Solving it for ẏ (J2 = cos θ) fails where the blade points across the slope (θ = ±π/2);
solving it for ẋ (J2 = −sin θ) fails where it points along it (θ = 0, π).  A spinning
skate meets both, so the file declares the two partitions as equivalent variants: a run
switches to the other where its own J2 becomes ill-conditioned, and back (the summary
lists every switch).
"""

from nmkane_core import Parameter, System, register


def skate_model(solve_for: str):
    """The skate with the constraint solved for ``solve_for`` ("u1" = ẋ or "u2" = ẏ)."""
    import sympy as sp  # inside the function: a cached run of this system never imports sympy

    from nmkane_core import MechanicalModel, plain_symbols

    x, y, th = plain_symbols("x y theta")
    u1, u2, u3 = plain_symbols("u1 u2 u3")
    m, I, g, alpha = sp.symbols("m I g alpha", positive=True)
    return MechanicalModel(
        q=(x, y, th),
        u=(u1, u2, u3),
        params=(m, I, g, alpha),
        C=sp.eye(3),
        D=sp.zeros(3, 1),
        Q=sp.diag(m, m, I),
        P=sp.Matrix([m * g * sp.sin(alpha), 0, 0]),
        nonholonomic={"no_side_slip": -sp.sin(th) * u1 + sp.cos(th) * u2},
        u_independent=(u1, u3) if solve_for == "u2" else (u2, u3),
        energy=m / 2 * (u1**2 + u2**2) + I / 2 * u3**2 - m * g * sp.sin(alpha) * x,
    )


def skate_visuals():
    """The inclined plane (a strip along the slope), the blade on it, the path of its contact point."""
    import sympy as sp

    from nmkane_core import plain_symbols
    from nmkane_core.declare.visuals import Frame, Visuals, box, rot_y, rot_z, strip, trace

    x, y, th = plain_symbols("x y theta")
    alpha = sp.Symbol("alpha", positive=True)
    down = sp.Matrix([sp.cos(alpha), 0, -sp.sin(alpha)])  # x: down the slope
    normal = sp.Matrix([sp.sin(alpha), 0, sp.cos(alpha)])
    on_plane = down * x + sp.Matrix([0, y, 0])
    return Visuals(
        frames=(Frame("skate", tuple(on_plane), rot_y(alpha) * rot_z(th)),),
        shapes=(
            strip("slope", [tuple(down * s) for s in (-2, 2)], 16.0, "y", color=(205, 212, 200), opacity=0.8),
            box("blade", "skate", (0.5, 0.03, 0.08), (0, 0, 0.04), color=(60, 60, 70)),
            box("boot", "skate", (0.25, 0.1, 0.12), (0, 0, 0.14), color=(200, 60, 40)),
            trace("path", tuple(on_plane + normal * sp.Float(0.005))),
        ),
    )


register(
    System(
        name="skate-on-incline",
        title="Skate on an inclined plane",
        variants={"solve-u2": lambda: skate_model("u2"), "solve-u1": lambda: skate_model("u1")},
        equivalents={"solve-u2": ("solve-u1",), "solve-u1": ("solve-u2",)},
        parameters={
            "m": Parameter(1.0, 0.0, 1e3, "kg", "mass of the skate"),
            "I": Parameter(0.1, 0.0, 1e3, "kg·m²", "moment of inertia about the contact point"),
            "g": Parameter(9.81, 0.0, 100.0, "m/s²", "gravitational acceleration", min_inclusive=True),
            "alpha": Parameter(0.2, 0.0, 1.5, "rad", "inclination of the plane"),
        },
        default_initial={"x": 0.0, "y": 0.0, "theta": 0.0, "u1": 0.0, "u3": 2.0},
        default_dt=0.001,
        default_t_final=10.0,
        description="A knife edge on a slope: a linear nonholonomic constraint; it does not run away downhill.",
        visuals=skate_visuals,
    )
)
