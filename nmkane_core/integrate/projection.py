"""Post-step constraint corrections ("geometric elimination of constraint violation").

After every accepted integrator step the state is moved back onto the constraint
manifold without changing the equations of motion, in the family of Blajer (2002,
Multibody Syst. Dyn. 7:265–284) and Yoon, Howe & Greenwood (1994, J. Mech. Des.
116:1058–1064).  The compiled loops apply, with a weighting matrix W:

(P) positions, ψ(q) = 0 — Newton / Gauss–Newton on the holonomic constraints:
        q ← q − W_q⁻¹ Ψ_qᵀ (Ψ_q W_q⁻¹ Ψ_qᵀ)⁻¹ ψ(q),      Ψ_q = ∂ψ/∂q,
    repeated up to ``iterations`` times (1 = one-shot), the Jacobian re-evaluated at
    each corrected point (``jacobian="updated"``) or frozen at the uncorrected point
    (``"frozen"``, simplified Newton);
(V) speeds, at the corrected q, on all velocity-level constraints c = [φ; ψ̇]:
        u ← u − W_u⁻¹ Jᵀ (J W_u⁻¹ Jᵀ)⁻¹ c(q, u),            J = ∂c/∂u,
    one step for constraints linear in u, Newton (≤ 3 steps) for nonlinear ones;
(E) optionally the speeds are scaled, u ← λu with λ² = (E0 − E(q,0))/(E(q,u) − E(q,0)),
    to restore the initial energy E0 (valid for conservative systems whose constraints
    are homogeneous in u, as in both examples).

Weights: ``identity`` — W = I (Moore–Penrose pseudoinverse, Euclidean-shortest
correction); ``mass`` — the kinetic-energy metric, W_u = Q (the holonomic mass matrix)
and W_q = C⁻ᵀ Q C⁻¹ (so W_q⁻¹ = C Q⁻¹ Cᵀ), whose corrections are ideal constraint
impulses.

Presets (Blajer 2002; Yoon, Howe & Greenwood 1994 — the presets follow the usual reading
of the two papers, not a transcription of their text; every switch is exposed so that
other readings can be tried):

=========  ========  ==========  =========  ======
preset     weight    iterations  Jacobian   energy
=========  ========  ==========  =========  ======
blajer     identity  3           updated    yes
yoon       mass      3           updated    no
=========  ========  ==========  =========  ======

In Example 2 (Q = m I, C = I) the two weights coincide, so the presets differ there only
by the energy correction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ProjectionOptions", "PRESETS", "projection_options"]


@dataclass(frozen=True)
class ProjectionOptions:
    name: str
    weight: str = "identity"  # identity | mass
    iterations: int = 3
    jacobian: str = "updated"  # updated | frozen
    energy: bool = False

    def as_array(self, info) -> np.ndarray | None:
        """The compiled loops' ``proj`` argument (with the model's dimensions); ``None`` for
        no projection."""
        if self.name == "none":
            return None
        return np.array(
            [
                1 if self.weight == "mass" else 0,
                self.iterations,
                1 if self.jacobian == "updated" else 0,
                1 if self.energy else 0,
                info.n,
                info.m,
                len(info.nonholonomic),
                len(info.holonomic),
            ],
            dtype=np.int64,
        )


PRESETS = {
    "none": ProjectionOptions("none"),
    "blajer": ProjectionOptions("blajer", weight="identity", iterations=3, jacobian="updated", energy=True),
    "yoon": ProjectionOptions("yoon", weight="mass", iterations=3, jacobian="updated", energy=False),
}


def projection_options(name: str, weight=None, iterations=None, jacobian=None, energy=None) -> ProjectionOptions:
    base = PRESETS[name]
    return ProjectionOptions(
        name,
        weight=base.weight if weight is None else weight,
        iterations=base.iterations if iterations is None else int(iterations),
        jacobian=base.jacobian if jacobian is None else jacobian,
        energy=base.energy if energy is None else bool(energy),
    )
