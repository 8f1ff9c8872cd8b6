"""What the numeric side needs to know about a model, without sympy.

A :class:`ModelInfo` is plain data (names and counts) stored beside a compiled kernel in
the on-disk cache, so that a fresh process can resolve, run and report a cached model
without building the symbolic description again.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

__all__ = ["ModelInfo"]


@dataclass(frozen=True)
class ModelInfo:
    name: str
    q: tuple[str, ...]
    u: tuple[str, ...]
    params: tuple[str, ...]
    nonholonomic: tuple[str, ...]
    holonomic: tuple[str, ...]
    monitors: tuple[str, ...]  # reported beside the constraints (not constraints)
    outputs: tuple[str, ...]
    u_independent: tuple[str, ...]
    q_dependent: tuple[str, ...]
    has_energy: bool

    @property
    def n(self) -> int:
        return len(self.q)

    @property
    def m(self) -> int:
        return len(self.nonholonomic) + len(self.holonomic)

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return self.nonholonomic + self.holonomic

    @property
    def viol_names(self) -> tuple[str, ...]:
        """Columns of the kernel's violation output: constraints, then monitors."""
        return self.constraint_names + self.monitors

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.q + self.u

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> ModelInfo:
        data = json.loads(text)
        fields: dict = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        return cls(**fields)

    @classmethod
    def from_derivation(cls, d) -> ModelInfo:
        md = d.model
        q_dep = md.q_dependent or _pick_q_dependent(d)
        return cls(
            name=md.name,
            q=tuple(map(str, md.q)),
            u=tuple(map(str, md.u)),
            params=tuple(map(str, md.params)),
            nonholonomic=tuple(md.nonholonomic),
            holonomic=tuple(md.holonomic),
            monitors=tuple(k for k in md.monitors if k not in md.constraint_names),
            outputs=tuple(md.outputs),
            u_independent=tuple(map(str, md.u_independent)),
            q_dependent=tuple(map(str, q_dep)),
            has_energy=md.energy is not None,
        )


def _pick_q_dependent(d):
    """One coordinate per holonomic constraint, by the first nonzero entry of ∂ψ/∂q."""
    if not d.m_h:
        return ()
    jac = d.psi.jacobian(d.q)
    chosen = []
    for i in range(d.m_h):
        for j, qj in enumerate(d.q):
            if jac[i, j] != 0 and qj not in chosen:
                chosen.append(qj)
                break
    return tuple(chosen)
