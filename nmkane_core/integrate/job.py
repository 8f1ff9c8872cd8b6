"""What the loop drivers integrate (:class:`Job`) and what they give back (:class:`LoopOutput`).

A :class:`Job` holds numbers and compiled kernels only — the run layer's
:class:`~nmkane_core.run.plan.Plan` makes it from checked settings — so the drivers know
nothing of systems, registries or settings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..kernel.interface import CompiledModel
from .methods import ScipyMethod, Tableau

__all__ = ["Alternative", "Job", "LoopOutput"]


@dataclass(frozen=True)
class Alternative:
    """An equivalent variant a run may switch to near a singular configuration: its name,
    compiled kernel module and parameter vector (variants may order parameters differently)."""

    name: str
    module: CompiledModel
    p: np.ndarray


@dataclass(frozen=True)
class Job:
    """One integration: the method, the kernel, the initial state and every numeric setting."""

    method: Tableau | ScipyMethod
    module: CompiledModel  # the compiled kernel of the chosen variant
    variant: str
    x0: np.ndarray
    p: np.ndarray  # parameter vector, in the kernel's order
    G: np.ndarray  # Γ (nonholonomic), Γ1, Γ2 (holonomic)
    G1: np.ndarray
    G2: np.ndarray
    dt: float  # the step (fixed-step methods) or the first step tried (adaptive ones)
    t_final: float
    every: int
    rtol: float
    atol: float
    rcond_min: float  # J2 or T below this condition estimate: the run ends singular
    rcond_switch: float  # ... below this: switch to an alternative, when there is one
    proj: np.ndarray | None  # the loops' projection options (ProjectionOptions.as_array), None: none
    near_proj: np.ndarray | None = None  # without proj: the projection of steps near a singular position
    alternatives: tuple[Alternative, ...] = ()
    forces: bool = True  # report the constraint forces and multipliers of every output row
    solve: int = 2  # kernels with the rank-robust solve: 0 the paper's, 1 robust, 2 auto (others: the paper's)
    max_rank: int = -1  # the model's independent equations (n − p, or the rank found); −1: the kernel's default
    order: tuple[int, ...] = ()  # the partition to start with, as J's column order [u_I, u_D] (): J's own
    drift_limit: float = math.inf  # |E − E0| above this ends the run (STATUS_DRIFTED)
    violation_limit: float = math.inf  # a reported violation above this ends it too


@dataclass
class LoopOutput:
    """What a loop driver returns: the rows it computed and how the integration ended."""

    status: int  # a STATUS_* code (nmkane_core.kernel.constants)
    stop: str | None  # "timeout" | "cancelled" | "max_steps" | "max_rows" | None
    t: np.ndarray
    x: np.ndarray
    E: np.ndarray
    V: np.ndarray
    F: np.ndarray  # constraint forces F_c = Q u̇ − P of each row (model order); no columns: not asked for
    L: np.ndarray  # multipliers λ of each row (F_c = Jᵀλ)
    stats: np.ndarray  # STATS_* layout (nmkane_core.kernel.constants)
    steps: int
    evals: int  # right-hand-side evaluations
    t_end: float
    switches: list[dict] = field(default_factory=list)
    fail_msg: str | None = None
    unknown_multipliers: list[tuple[float, float]] = field(default_factory=list)  # switched rows (t from, to)
    solve_log: list[np.ndarray] = field(default_factory=list)  # the rank-robust solve's records (constants LOG_*)
    solve_log_dropped: int = 0  # records beyond the loops' buffers (counted, not kept)
