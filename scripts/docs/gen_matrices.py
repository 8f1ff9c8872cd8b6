"""For "How it works": the paper's matrices of Example 2 derived now, and the integrators and
projections a run can ask for (from ``GET /api/systems``)."""

from __future__ import annotations

from _md import code, fill, table
from gen_catalogue import systems_document

NAMES = (
    ("J1", "(17)", "∂φ/∂u_I"),
    ("J2", "(18)", "∂φ/∂u_D"),
    ("A", "(20)", "−J2⁻¹J1"),
    ("B", "(20)", "−J2⁻¹(B1 u + B2)"),
    ("A1", "(22)", "[−A  I]"),
    ("A2", "(40)", "[I  Aᵀ]"),
    ("T", "(44)", "[A1; A2 Q]"),
    ("V", "(44)", "[B; A2 P]"),
)


def sliding_particle():
    """Example 2 as the getting-started page writes it (the public API only)."""
    import sympy as sp

    from nmkane_core import MechanicalModel, derive, plain_symbols

    x, y = plain_symbols("x y")
    u1, u2 = plain_symbols("u1 u2")
    l0, m, g = sp.symbols("l0 m g", real=True)
    model = MechanicalModel(
        name="particle",
        q=(x, y),
        u=(u1, u2),
        params=(l0, m, g),
        C=sp.eye(2),
        D=sp.zeros(2, 1),
        Q=m * sp.eye(2),
        P=sp.Matrix([0, m * g]),
        holonomic={"surface": y + x**2 / l0 - l0},
        u_independent=(u1,),
    )
    return derive(model)


def pages() -> dict[str, str]:
    import sympy as sp

    d = sliding_particle()
    blocks = []
    for name, eq, meaning in NAMES:
        pretty = sp.pretty(sp.simplify(d.matrix(name)), use_unicode=True, wrap_line=False)
        blocks += [f"**{name}** {eq} = {meaning}:", "", "```text", pretty, "```", ""]
    doc = systems_document()
    integrators = table(("`integrator`", "what it is"), [(code(k), v) for k, v in doc["integrators"].items()])
    projections = ", ".join(code(p) for p in doc["projections"]) + "."
    return {
        "how-it-works.md": fill(
            "how-it-works.md",
            {"matrices": "\n".join(blocks), "integrators": integrators, "projections": projections},
        )
    }
