"""A stand-in for a pip-installed package that adds systems through the ``nmkane.systems``
entry-point group (tests/test_plugins.py points a fake entry point here)."""


def _model():
    import sympy as sp

    from nmkane_core import MechanicalModel, plain_symbols

    x, y, th = plain_symbols("x y theta")
    u1, u2, u3 = plain_symbols("u1 u2 u3")
    m, inertia = sp.symbols("m I", positive=True)
    return MechanicalModel(
        q=(x, y, th),
        u=(u1, u2, u3),
        params=(m, inertia),
        C=sp.eye(3),
        D=sp.zeros(3, 1),
        Q=sp.diag(m, m, inertia),
        P=sp.zeros(3, 1),
        nonholonomic={"no_side_slip": -sp.sin(th) * u1 + sp.cos(th) * u2},
        u_independent=(u2, u3),
    )


def register_all() -> None:
    from nmkane_core import Parameter, System, register

    register(
        System(
            name="entry-point-skate",
            variants=_model,
            parameters={"m": Parameter(1.0, 0, 10), "I": Parameter(0.1, 0, 10)},
            default_initial={"theta": 0.5, "u2": 0.5, "u3": 2.0},
        )
    )
