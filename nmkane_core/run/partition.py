"""The partition and the rank of a system's constraints, found numerically (docs/closed-loops.md §3).

A model may leave ``u_independent`` and ``q_dependent`` out: the library then picks them by
Gaussian elimination with complete pivoting on the equilibrated constraint Jacobians at the
system's declared default state (Wehage & Haug 1982, :func:`~nmkane_core.symbolic.robust.partition_by_pivoting`):
u_D from J = ∂[φ; ψ̇]/∂u, the coordinates solved from ψ from ∂ψ/∂q.  What a user sets (the
independent values, ``Built.independent``) follows from that choice.  A model may also declare
more equations than dependent speeds (redundant ones): the number of independent speeds is
n − rank J, with the rank measured at the default state (:func:`constraint_report`);
registration checks it against a declared partition (:func:`check_rank`).
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..declare.system import System
from ..errors import InputError
from ..kernel.built import built
from ..symbolic.robust import (
    DECLARATION_RANK_TOL,
    partition_by_pivoting,
    partition_rcond,
    pivot_steps,
    robust_solve,
)

__all__ = ["Partition", "check_rank", "constraint_report", "explain_partition", "max_rank", "partition"]


@dataclass(frozen=True)
class Partition:
    """A variant's partition: the coordinates solved from the holonomic constraints, the
    independent speeds, and the kernel's column order [u_I, u_D] that goes with them."""

    q_dependent: tuple[str, ...]
    u_independent: tuple[str, ...]
    order: tuple[int, ...]
    declared: bool


_CACHE: dict[tuple[int, str, str], tuple[weakref.ref, object]] = {}
_LOCK = threading.RLock()


def _cached(system: System, variant: str, kind: str, make):
    key = (id(system), variant, kind)
    with _LOCK:
        entry = _CACHE.get(key)
        if entry is not None and entry[0]() is system:
            return entry[1]
    value = make()
    with _LOCK:
        _CACHE[key] = (weakref.ref(system), value)
    return value


def _state_vector(info, values: Mapping[str, float]) -> np.ndarray:
    return np.array([float(values.get(s, 0.0)) for s in info.state_names], float)


def partition(system: System, variant: str | None = None) -> Partition:
    """The variant's partition: the declared one, or the one picked by pivoting at the declared
    default state (missing values taken as 0).  Made once per system and variant; it is also
    what ``built(system).independent`` reports."""
    variant = system.check_variant(variant)
    return _cached(system, variant, "partition", lambda: _make_partition(system, variant))


def _make_partition(system: System, variant: str) -> Partition:
    b = built(system)
    module, info = b.kernel(variant)
    if not info.m or info.u_independent:
        part = Partition(info.q_dependent, info.u_independent if info.m else info.u, tuple(range(info.n)), True)
    else:
        x = _state_vector(info, system.default_initial)
        p = b.param_vector(variant, system.resolve_params({}))
        J, _, _, psi_q, _ = module.state_terms(0.0, x, p)
        q_dep: tuple[str, ...] = ()
        if info.holonomic:
            cols, _, _ = partition_by_pivoting(np.asarray(psi_q), DECLARATION_RANK_TOL)
            q_dep = tuple(info.q[j] for j in sorted(cols))
        dep, _, _ = partition_by_pivoting(np.asarray(J), DECLARATION_RANK_TOL)
        ind = [j for j in range(info.n) if j not in dep]
        # the kernel's columns are the model's speeds (no declared partition: PERM is the identity)
        part = Partition(q_dep, tuple(info.u[j] for j in ind), tuple(ind + sorted(dep)), False)
    b.partitions[variant] = (part.q_dependent, part.u_independent)
    return part


def constraint_report(system: System, variant: str | None, state: dict[str, float]) -> dict:
    """The constraints' rank at the system's default state ``state`` (completed:
    :func:`~nmkane_core.run.initial.default_state`) (the kernel's J, its columns
    equilibrated, Householder QR with column pivoting at :data:`DECLARATION_RANK_TOL`):
    ``rank``, ``m``, ``independent_speeds`` = n − rank, ``redundant`` (the equations found
    dependent there, by name), the partition (``u_independent``, ``q_dependent``, whether it
    is ``declared``) and ``rcond`` (the smallest kept pivot: how far from losing rank)."""
    variant = system.check_variant(variant)
    return _cached(system, variant, "report", lambda: _make_report(system, variant, state))


def _make_report(system: System, variant: str, state: dict[str, float]) -> dict:
    b = built(system)
    module, info = b.kernel(variant)
    part = partition(system, variant)
    out = {
        "rank": 0,
        "m": info.m,
        "independent_speeds": info.n,
        "redundant": [],
        "u_independent": list(part.u_independent),
        "q_dependent": list(part.q_dependent),
        "declared": part.declared,
        "rcond": 1.0,
    }
    if not info.m:
        return out
    x = _state_vector(info, state)
    p = b.param_vector(variant, system.resolve_params({}))
    J = np.asarray(module.state_terms(0.0, x, p)[0])
    sol = robust_solve(np.eye(info.n), np.zeros(info.n), J, np.zeros(info.m), DECLARATION_RANK_TOL)
    out.update(
        rank=sol.rank,
        independent_speeds=info.n - sol.rank,
        redundant=[info.constraint_names[i] for i in sol.dependent],
        rcond=sol.rcond,
    )
    return out


def check_rank(system: System, variant: str | None, state: dict[str, float]) -> dict:
    """The report of :func:`constraint_report`, after checking that a declared partition leaves
    as many independent speeds as the constraints do at the default state; raises
    :class:`InputError` saying both numbers and the redundant equations otherwise."""
    variant = system.check_variant(variant)
    rep = constraint_report(system, variant, state)
    info = built(system).info(variant)
    declared = len(info.u_independent)
    if info.m and declared and declared != rep["independent_speeds"]:
        where = system.name if len(system.variants) == 1 else f"{system.name} ({system.option} {variant})"
        redundant = f"; redundant there: {', '.join(rep['redundant'])}" if rep["redundant"] else ""
        raise InputError(
            f"{where}: u_independent",
            list(info.u_independent),
            f"{rep['independent_speeds']} independent speed(s): the {info.m} constraints have rank "
            f"{rep['rank']} at the default state{redundant} — declare n − rank = "
            f"{rep['independent_speeds']} independent speeds, or leave u_independent out",
            f"declared {declared} independent speed{'s' if declared != 1 else ''}, the constraints leave "
            f"{rep['independent_speeds']} at the default state",
        )
    return rep


def max_rank(system: System, variant: str | None, state: dict[str, float]) -> int:
    """The number of independent constraint equations a run's robust solve may keep: n − p for
    a declared partition, else the rank at the default state ``state``."""
    variant = system.check_variant(variant)
    info = built(system).info(variant)
    if not info.m:
        return 0
    if info.u_independent:
        return info.n - len(info.u_independent)
    return int(constraint_report(system, variant, state)["rank"])


def explain_partition(system: System, variant: str | None, state: dict[str, float]) -> list[str]:
    """Why the variant's partition is what it is, as lines of text: declared by the model, or
    picked by Wehage & Haug's elimination with complete pivoting on the equilibrated J (and on
    ∂ψ/∂q for the coordinates solved from ψ = 0) at the default state ``state`` — each pivot
    (the speed made dependent, the constraint it is solved from, |pivot|) — and J2's condition
    estimate there (the scale-free one ``solve="auto"`` watches)."""
    variant = system.check_variant(variant)
    b = built(system)
    module, info = b.kernel(variant)
    part = partition(system, variant)
    if not info.m:
        return ["no constraints: every speed is independent"]
    x = _state_vector(info, state)
    p = b.param_vector(variant, system.resolve_params({}))
    J, _, _, psi_q, _ = module.state_terms(0.0, x, p)
    J, psi_q = np.asarray(J), np.asarray(psi_q)
    how = "declared by the model" if part.declared else "picked by pivoting at the default state"
    lines = [f"partition: u_I = ({', '.join(part.u_independent)}), {how}"]
    if not part.declared:
        lines += _pivot_lines(J, info.u, info.constraint_names, "u_D", DECLARATION_RANK_TOL)
        if info.holonomic:
            lines += _pivot_lines(psi_q, info.q, info.holonomic, "q solved", DECLARATION_RANK_TOL)
    elif part.q_dependent:
        lines.append(f"  q solved from ψ = 0: {', '.join(part.q_dependent)} (declared)")
    n_ind = len(part.u_independent)
    if J.shape[0] == info.n - n_ind:  # a square J2: its estimate
        rc = partition_rcond(J[:, list(part.order)], n_ind)
        lines.append(f"  J2 estimate at the default state: {rc:.3g} (solve auto leaves the partition below 1e-6)")
    else:
        lines.append(
            f"  {J.shape[0]} equations for {info.n - n_ind} dependent speeds: redundant, the rank-robust solve"
        )
    return lines


def _pivot_lines(A: np.ndarray, cols, rows, what: str, tol: float) -> list[str]:
    """One line per pivot of the elimination on A: the column made dependent, the row, |pivot|."""
    steps = pivot_steps(A, tol)
    out = [f"  {what}: pivots of the elimination (|pivot| of the equilibrated rows, largest first):"]
    out += [f"    {cols[c]} from {rows[r]}: {v:.3g}" for c, r, v in steps]
    left = [rows[i] for i in range(len(rows)) if i not in {r for _, r, _ in steps}]
    if left:
        out.append(f"    redundant there (no pivot above {tol:g}): {', '.join(left)}")
    return out
