"""A finished run: :class:`Run`, arrays by name and the summary, and its files (JSON, CSV, NPZ).

:func:`nmkane_core.run.finish.finish` makes it from what a loop driver returns.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..schema import RunResult, RunSummary

__all__ = ["Run"]


@dataclass
class Run:
    """A finished run: arrays by name and the summary (convert with :meth:`document`)."""

    system: str
    settings: dict
    t: np.ndarray
    state: dict[str, np.ndarray]
    energy: np.ndarray | None
    violation: dict[str, np.ndarray]
    summary: dict
    #: F_c = Q u̇ − P by speed name (the generalized constraint force; the run's u̇, stabilization
    #: included), one value per output row; empty when the run was asked not to report it
    constraint_forces: dict[str, np.ndarray] = field(default_factory=dict)
    #: λ by constraint name with F_c = Jᵀλ, J = ∂[φ; ψ̇]/∂u — Chetaev's multiplier of a
    #: constraint nonlinear in the speeds.  λ depends on how a constraint is written (scale it by
    #: 2 and its λ halves), F_c does not; with redundant constraints λ is not unique (the basic
    #: solution, zero on the equations found dependent, is reported)
    multipliers: dict[str, np.ndarray] = field(default_factory=dict)
    #: the physical forces a system declares at points (:mod:`nmkane_core.declare.forces`), by
    #: ``NAME.LABEL`` (``contact.normal``): each force's components along its declared axes, one
    #: value per output row; empty when the system declares none or forces were not asked for
    point_forces: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def status(self) -> str:
        return self.summary["status"]

    def show(self, **options):
        """The run inline in Jupyter (the last line of a cell): the 3D animation with a
        playback bar and the plots, offline — drawn by the installed viewer (the web app's
        export, :mod:`nmkane_core.run.viewer`); ``height=`` in pixels."""
        from .viewer import show_run

        return show_run(self, **options)

    def document(self, id: str | None = None) -> RunResult:
        return RunResult(
            id=id,
            system=self.system,
            settings=self.settings,
            t=self.t.tolist(),
            state={k: v.tolist() for k, v in self.state.items()},
            energy=None if self.energy is None else self.energy.tolist(),
            violation={k: v.tolist() for k, v in self.violation.items()},
            constraint_forces={k: v.tolist() for k, v in self.constraint_forces.items()},
            multipliers={k: v.tolist() for k, v in self.multipliers.items()},
            point_forces={k: v.tolist() for k, v in self.point_forces.items()},
            summary=RunSummary(**self.summary),
        )

    def columns(self) -> dict[str, np.ndarray]:
        cols = {"t": self.t, **self.state}
        if self.energy is not None:
            cols["energy"] = self.energy
        cols.update({f"violation_{k}": v for k, v in self.violation.items()})
        cols.update({f"force_{k}": v for k, v in self.constraint_forces.items()})
        cols.update({f"multiplier_{k}": v for k, v in self.multipliers.items()})
        cols.update(self.point_forces)  # NAME.LABEL: no state, violation or force_ column has a dot
        return cols

    def to_csv(self) -> str:
        cols = self.columns()
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols)
        for row in zip(*[c.tolist() for c in cols.values()], strict=True):
            w.writerow([repr(v) for v in row])
        return buf.getvalue()

    def save(self, path: str) -> None:
        """Write ``.json`` (the run document), ``.csv`` or ``.npz``."""
        if path.endswith(".json"):
            with open(path, "w") as f:
                f.write(self.document().model_dump_json(by_alias=True))
        elif path.endswith(".csv"):
            with open(path, "w") as f:
                f.write(self.to_csv())
        elif path.endswith(".npz"):
            import json

            arrays: dict = {
                **self.columns(),
                "summary": json.dumps(self.summary),
                "settings": json.dumps(self.settings),
            }
            np.savez_compressed(path, **arrays)
        else:
            raise InputError("out", path, "a file name ending in .json, .csv or .npz", "unknown format")

    def thin(self, max_rows: int, limit: str = "") -> None:
        """Keep at most ``max_rows`` output rows (evenly spaced, the last one kept); the summary
        still covers every step and its warnings say the output was thinned (``limit``: whose
        limit, e.g. "service limit max_rows = 100,000")."""
        n = self.t.size
        if n <= max_rows:
            return
        k = math.ceil((n - 1) / (max_rows - 1))
        idx = np.unique(np.r_[np.arange(0, n, k), n - 1])
        self.t = self.t[idx]
        self.state = {name: v[idx] for name, v in self.state.items()}
        self.energy = None if self.energy is None else self.energy[idx]
        self.violation = {name: v[idx] for name, v in self.violation.items()}
        self.constraint_forces = {name: v[idx] for name, v in self.constraint_forces.items()}
        self.multipliers = {name: v[idx] for name, v in self.multipliers.items()}
        self.point_forces = {name: v[idx] for name, v in self.point_forces.items()}
        self.summary["warnings"] = [
            *self.summary.get("warnings", []),
            f"output thinned from {n:,} to {idx.size:,} rows ({limit or f'at most {max_rows:,}'}); "
            "the summary covers every step",
        ]
