# ruff: noqa: F821
"""Generic compiled kernel, part 2: what Python callers evaluate at given states — the
right-hand side with its condition estimates, diagnostics and outputs over many rows, and
the constraint quantities that complete and check initial states.

Not imported: :mod:`nmkane_core.kernel.codegen` appends this source after
:mod:`nmkane_core.kernel.source.loops` in every generated kernel module (see that file for the
names the model-specific part defines).
"""

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def rhs(t, x, p, G, G1, G2):
    """Convenience form for Python callers and tests: returns (ẋ, rcond J2, rcond T)."""
    w = make_workspace()
    K = np.empty((1, 2 * N))
    rhs_ws(t, x, p, G, G1, G2, K, 0, w)
    return K[0].copy(), w[ORC], w[ORC + 1]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def diagnostics_rows(ts, xs, p, E, V):
    """Energy and violations of many states (scipy adapter, initial row)."""
    viol = np.empty(NV)
    for r in range(ts.shape[0]):
        E[r] = diagnostics(ts[r], xs[r], p, viol)
        for j in range(NV):
            V[r, j] = viol[j]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def outputs_rows(ts, xs, p, O):
    out = np.empty(NO)
    for r in range(ts.shape[0]):
        outputs(ts[r], xs[r], p, out)
        for j in range(NO):
            O[r, j] = out[j]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def state_terms(t, x, p):
    """Constraint quantities at one state, for completing and checking initial states:
    (J = ∂[φ; ψ̇]/∂u in the model's speed order, [φ; ψ̇], ψ, ∂ψ/∂q, reported violations)."""
    w = make_workspace()
    constraint_terms(t, x, p, w)  # J, φ, ψ̇ only (no Q, P: a small compile)
    positions(t, x, p, w)
    J = np.empty((M, N))
    for a in range(M):
        for j in range(N):
            J[a, PERM[j]] = w[OJ + a * N + j]
    c = np.empty(M)
    for a in range(MNH):
        c[a] = w[OPHIN + a]
    for a in range(MH):
        c[MNH + a] = w[OPSID + a]
    psi = w[OPSI : OPSI + MH].copy()
    psi_q = w[OPSQ : OPSQ + MH * N].copy().reshape((MH, N))
    viol = np.empty(NV)
    diagnostics(t, x, p, viol)
    return J, c, psi, psi_q, viol


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def forces_rows(ts, xs, p, G, G1, G2, F, L):
    """Constraint forces (F_c = Q u̇ − P, model order) and multipliers of many states, for the
    drivers whose steps are not the loops' (the scipy adapter): one right-hand side each."""
    w = make_workspace()
    K = np.empty((1, 2 * N))
    for r in range(ts.shape[0]):
        w[OFLAG] = 1.0
        rhs_ws(ts[r], xs[r], p, G, G1, G2, K, 0, w)
        _forces(w, K, 0)
        _store_forces(w, r, F, L)
