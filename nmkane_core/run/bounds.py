"""The bounds past which a run stops with status ``drifted``: its energy drift |E − E0| and its
reported constraint violations (``RunSettings.max_energy_drift``, ``max_violation``).

A run whose motion blows up — an unstable step, the equations amplifying a round-off kick at
a singular position until the motion leaves its branch — used to go on until the state stopped
being finite, its energy grown by 50 orders of magnitude.  The loops now stop at the first
accepted state past a bound (kernel ``STATUS_DRIFTED``; that state is not kept) and the
summary names the bound.  Unset, the energy bound is 10⁶ times the run's initial energy scale,
max(|E0|, ½u₀ᵀQu₀): far beyond what a drift of the integrator or of an unstabilized constraint
reaches (the paper's unstabilized 500 s runs stay below 10⁻¹ of it), and reached by a blow-up
within a few steps.  The violations have no default bound: their units are the model's.
"""

from __future__ import annotations

import math

import numpy as np

from ..kernel.info import ModelInfo
from ..kernel.interface import CompiledModel
from ..schema import RunSettings

__all__ = ["ENERGY_BOUND_FACTOR", "energy_scale", "run_bounds"]

#: the unset energy bound, in units of the initial energy scale
ENERGY_BOUND_FACTOR = 1e6


def energy_scale(module: CompiledModel, x0: np.ndarray, p: np.ndarray) -> float:
    """max(|E0|, ½u₀ᵀQu₀) at the initial state: Q from one evaluation of the model's terms (in
    the kernel's speed order [u_I, u_D]; ``PERM`` maps it to the model's)."""
    n = module.N
    E0, V0 = np.empty(1), np.empty((1, module.NV))
    module.diagnostics_rows(np.zeros(1), x0[None, :], p, E0, V0)
    w = module.make_workspace()
    K = np.empty((1, 2 * n))
    G, H = np.zeros((module.MNH, module.MNH)), np.zeros((module.MH, module.MH))
    with np.errstate(all="ignore"):
        module.rhs_ws(0.0, x0, p, G, H, H, K, 0, w)
    Q = w[module.OQ : module.OQ + n * n].reshape(n, n)
    u = x0[n:][module.PERM]
    kinetic = 0.5 * float(u @ Q @ u)
    scale = max(abs(float(E0[0])), kinetic if math.isfinite(kinetic) else 0.0)
    return scale if math.isfinite(scale) else 0.0


def run_bounds(
    s: RunSettings, module: CompiledModel, info: ModelInfo, x0: np.ndarray, p: np.ndarray
) -> tuple[float, float]:
    """(energy drift bound, violation bound) of a run: the request's, or the defaults above
    (``math.inf``: none)."""
    violation = s.max_violation if s.max_violation is not None else math.inf
    if s.max_energy_drift is not None:
        return s.max_energy_drift, violation
    if not info.has_energy:
        return math.inf, violation
    scale = energy_scale(module, x0, p)
    return (ENERGY_BOUND_FACTOR * scale if scale > 0.0 else math.inf), violation
