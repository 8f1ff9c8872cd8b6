"""A particle in a bowl, driven along it at constant speed — an nmkane systems file.

Load it with ``nmkane run isokinetic-bowl --systems examples/isokinetic_bowl.py`` (or
``nmkane serve --systems ...``, or ``NMKANE_SYSTEMS=examples/isokinetic_bowl.py``).

A point mass m moves on the paraboloid z = (x² + y²)/(2R) (a holonomic constraint) under
gravity, and a drive keeps its speed at v0: √(ẋ² + ẏ² + ż²) − v0 = 0 (a nonholonomic
constraint that is *not polynomial* in the speeds — the natural way to say "speed along
the path").  The drive's force is along the velocity, so the kinetic energy m v0²/2 stays
constant while the particle climbs and falls: it is the quantity reported as the
energy, and its drift measures the integration's accuracy.

Coordinates q = (x, y, z), speeds u = (ẋ, ẏ, ż); two constraints leave one independent
speed, u_I = ẋ.  J2 (∂[φ; ψ̇]/∂(ẏ, ż)) is singular where ẏ + (y/R) ż = 0, e.g. when the
particle crosses the plane y = 0 moving along x: the run then reports ``singular``.
"""

from nmkane_core import Parameter, System, register


def bowl_model():
    import sympy as sp  # inside the function: a cached run of this system never imports sympy

    from nmkane_core import MechanicalModel, plain_symbols

    x, y, z = plain_symbols("x y z")
    u1, u2, u3 = plain_symbols("u1 u2 u3")
    m, g, R, v0 = sp.symbols("m g R v0", positive=True)
    return MechanicalModel(
        q=(x, y, z),
        u=(u1, u2, u3),
        params=(m, g, R, v0),
        C=sp.eye(3),
        D=sp.zeros(3, 1),  # q̇ = u
        Q=m * sp.eye(3),
        P=sp.Matrix([0, 0, -m * g]),  # free particle under gravity
        holonomic={"bowl": z - (x**2 + y**2) / (2 * R)},
        nonholonomic={"speed": sp.sqrt(u1**2 + u2**2 + u3**2) - v0},
        u_independent=(u1,),
        energy=m / 2 * (u1**2 + u2**2 + u3**2),  # kinetic energy: constant
        q_dependent=(z,),
    )


def bowl_visuals():
    """The bowl as rings and meridians on the paraboloid, the particle and its path."""
    import sympy as sp

    from nmkane_core import plain_symbols
    from nmkane_core.declare.visuals import Visuals, polyline, sphere, trace

    x, y, z = plain_symbols("x y z")
    R = sp.Symbol("R", positive=True)
    angles = [2 * sp.pi * k / 48 for k in range(49)]
    rings = [  # circles of radius r on z = r²/(2R): r = R/4 … 5R/4
        polyline(f"ring{i}", [(r * sp.cos(a), r * sp.sin(a), r**2 / (2 * R)) for a in angles], (150, 160, 178), 1.5)
        for i, r in enumerate(R * sp.Rational(k, 4) for k in range(1, 6))
    ]
    radii = [R * sp.Rational(k, 8) for k in range(11)]
    meridians = [
        polyline(f"meridian{j}", [(r * sp.cos(a), r * sp.sin(a), r**2 / (2 * R)) for r in radii], (150, 160, 178), 1.5)
        for j, a in enumerate(2 * sp.pi * k / 12 for k in range(12))
    ]
    return Visuals(
        shapes=(
            *rings,
            *meridians,
            sphere("particle", 0.08, at=(x, y, z), color=(220, 80, 35)),
            trace("path", (x, y, z)),
        ),
    )


register(
    System(
        name="isokinetic-bowl",
        title="Particle driven at constant speed in a bowl",
        variants=bowl_model,
        parameters={
            "m": Parameter(1.0, 0.0, 1e3, "kg", "mass of the particle"),
            "g": Parameter(9.81, 0.0, 100.0, "m/s²", "gravitational acceleration", min_inclusive=True),
            "R": Parameter(2.0, 0.0, 1e3, "m", "radius of curvature of the bowl at its bottom"),
            "v0": Parameter(1.5, 0.0, 100.0, "m/s", "the driven speed"),
        },
        # z, u2, u3 are completed from the constraints; u2 = 1 is the guess that picks the branch ẏ > 0
        default_initial={"x": 1.0, "y": 0.5, "u1": 0.3, "u2": 1.0},
        default_dt=0.001,
        default_t_final=10.0,
        description="A holonomic surface and a speed constraint √(ẋ²+ẏ²+ż²) = v0, non-polynomial in the speeds.",
        visuals=bowl_visuals,
    )
)
