"""The rank-robust solve's records (the loops' ``solve_log``) in the words of a run's summary.

Each record is one change of the constraint solve during a run — the paper's solve with
another partition, or the rank-robust solve where no partition is well-conditioned — or the
inconsistent constraints that ended it (:mod:`nmkane_core.kernel.constants`, ``LOG_*``).
:func:`solve_switches` lists the changes like model switches (``summary.switches``);
:func:`inconsistency` gives the facts of an inconsistent stop for its message.
"""

from __future__ import annotations

from ..integrate.job import LoopOutput
from ..kernel.constants import (
    LOG_HEAD,
    LOG_INCONSISTENT,
    LOG_PAPER,
    STATS_MAX_LEAVE,
    STATS_MAX_STAB,
    STATS_MIN_PIVOT,
    STATS_MIN_RANK,
    STATS_NEAR_PROJECTIONS,
    STATS_ROBUST_EVALS,
)

__all__ = ["inconsistency", "robust_in_use", "robust_summary", "solve_switches"]

NAMES_SHOWN = 6  # equations named in a switch before "… (k in all)"


def _names(names: list[str]) -> str:
    if len(names) <= NAMES_SHOWN:
        return ", ".join(names)
    return ", ".join(names[:NAMES_SHOWN]) + f", … ({len(names)} in all)"


def _partition_label(module, info, order) -> str:
    pi = module.PI
    ind = [info.u[int(module.PERM[int(j)])] for j in order[:pi]]
    return f"partition u_I = ({', '.join(ind)})" if ind else "partition with no independent speed"


def _dropped(info, row) -> list[str]:
    flags = row[LOG_HEAD : LOG_HEAD + info.m]
    return [name for name, f in zip(info.constraint_names, flags, strict=True) if f == 1.0]


def _robust_label(info, row) -> str:
    dropped = _dropped(info, row)
    text = f"rank-robust solve (rank {int(row[3])} of {info.m}"
    return text + (f"; dependent there: {_names(dropped)})" if dropped else ")")


def solve_switches(module, info, order: tuple[int, ...], paper_first: bool, out: LoopOutput) -> list[dict]:
    """The changes of solve and partition as switch records (t, from, to, rcond): the paper's
    solve with a partition (named by its independent speeds) or the rank-robust solve (its rank
    and the equations it found dependent); ``rcond`` the J2 estimate that made the change.
    ``order``, ``paper_first``: the partition the run started with, and whether it started with
    the paper's solve."""
    if not getattr(module, "ROBUST", False) or not out.solve_log:
        return []
    order = order or tuple(range(info.n))
    current = _partition_label(module, info, order) if paper_first else "rank-robust solve"
    switches = []
    for row in out.solve_log:
        kind = int(row[1])
        if kind == LOG_INCONSISTENT:
            continue
        to = _partition_label(module, info, row[LOG_HEAD:]) if kind == LOG_PAPER else _robust_label(info, row)
        switches.append({"t": float(row[0]), "from": current, "to": to, "rcond": float(row[2])})
        current = to
    return switches


def inconsistency(info, out: LoopOutput) -> dict:
    """The facts of an inconsistent stop (its last record): rank, m, the dependent equations
    and their relative residual."""
    rows = [r for r in out.solve_log if int(r[1]) == LOG_INCONSISTENT]
    if not rows:
        return {"rank": "?", "m": info.m, "dropped": "?", "residual": float("nan")}
    row = rows[-1]
    return {"rank": int(row[3]), "m": info.m, "dropped": _names(_dropped(info, row)), "residual": float(row[2])}


def robust_in_use(module, solve: int) -> bool:
    """Whether a run's evaluations went through the rank-robust machinery: kernels with it,
    unless the paper's solve (0) was asked for on a declared partition (csrc/nmk.h's
    ``robust_in_use``)."""
    return bool(getattr(module, "ROBUST", False)) and not (getattr(module, "DECLARED", False) and solve == 0)


def robust_summary(module, out: LoopOutput, solve: int) -> dict | None:
    """What the rank-robust solve did in a run (kernels with it, unless the run asked for the
    paper's solve on a declared partition): how many evaluations used it, its smallest kept
    pivot and rank, the largest kinetic-energy share of a projection's speed correction, and the
    solve changes not listed (beyond the loops' record buffers)."""
    if not robust_in_use(module, solve):
        return None
    stats = out.stats
    evals = int(stats[STATS_ROBUST_EVALS])
    return {
        "evaluations": evals,
        "min_pivot": float(stats[STATS_MIN_PIVOT]) if evals else None,
        "min_rank": int(stats[STATS_MIN_RANK]) if evals else None,
        "max_projection_share": float(stats[STATS_MAX_LEAVE]),
        "max_stabilization_share": float(stats[STATS_MAX_STAB]),
        "near_singular_projections": int(stats[STATS_NEAR_PROJECTIONS]),
        "changes_not_listed": int(out.solve_log_dropped),
    }
