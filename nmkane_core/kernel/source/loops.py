# ruff: noqa: F821
"""Generic compiled kernel: the right-hand side and the integrator loops (the paper's numeric
solve itself is in source/paper.py, appended with it).

This file is *not imported*.  :mod:`nmkane_core.kernel.codegen` appends its source to every
generated kernel module, after the model-specific part that defines the dimensions
``N, M, MNH, MH, PI, NV`` (n speeds, m constraints of which MNH nonholonomic and MH
holonomic, p = PI independent speeds, NV reported violations), the permutation ``PERM``
from [u_I, u_D] back to the model's speeds, and the straight-line functions ``terms`` and
``diagnostics``.  The integrators are tableau-driven (methods are data): one fixed-step
loop and one adaptive loop serve every explicit Runge–Kutta tableau.

The loops' status codes (``STATUS_*``), the layout of their ``stats`` array (``STATS_*``)
and the adaptive step control (``STEP_*``) come from :mod:`nmkane_core.kernel.constants`,
which the generated module imports.  The loops' parameter lists are the fields of their
argument records (:class:`~nmkane_core.kernel.interface.FixedArgs`,
:class:`~nmkane_core.kernel.interface.AdaptiveArgs`): each loop is written
``def integrate_fixed(*FixedArgs):`` here and the generator writes the fields in.

Every function is compiled with ``error_model="numpy"`` (as are the generated ones): a
division by zero gives ±inf or NaN, as the square root of a negative number does, instead
of raising ZeroDivisionError out of compiled code.  The loops' own finiteness checks turn
such values into a status (``STATUS_DIVERGED``; the adaptive loop first rejects the trial
step and shrinks it), so no exception from the model's expressions reaches the caller.

``proj`` (int64 array) = [weight (0 identity, 1 mass), position iterations, Newton (1
updated Jacobian, 0 frozen), energy correction (0/1), N, M, MNH, MH], or None for no
projection (numba then prunes the projection from the loop's compile).
"""

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def terms_call(t, x, p, w):
    """``terms`` compiled once as a function, for cold paths (projection, completion)."""
    terms(t, x, p, w)


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def make_workspace():
    """The flat scratch array of one right-hand side evaluation (allocated once per run).

    Layout (offsets are constants of the generated module): J = [J1 J2] at OJ (m×n),
    b = B1u + B2 at OB, φ at OPHIN, ψ̇ at OPSID, ψ at OPSI, Q at OQ (n×n), P at OP,
    C u + D at OQD, R = [−J1 | −b + s] → [A | B̂] at OR (m×(p+1)), W = Q A2ᵀ at OW
    (n×p), A2 Q A2ᵀ at OMR (p×p), P − Q_{·D}B̂ at OY, A2(P − Q_{·D}B̂) → u̇_I at OUI,
    (rcond J2, rcond T) at ORC.
    """
    w = np.zeros(WSIZE)
    w[ORC] = 1.0
    w[ORC + 1] = 1.0
    if ROBUST:
        _solve_defaults(w)
    return w


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def rhs_ws(t, x, p, G, G1, G2, K, row, w):
    """ẋ = [C u + D; T⁻¹V̂] into K[row]; w[ORC], w[ORC + 1] receive the rcond of J2, T.
    With w[OFLAG] set, what :func:`_forces` needs is kept (:func:`_keep_for_forces`).
    Kernels with the rank-robust solve run ``_rhs_robust`` (source/robust.py) instead."""
    if ROBUST:
        _rhs_robust(t, x, p, G, G1, G2, K, row, w)  # INLINE
    else:
        _rhs_paper(t, x, p, G, G1, G2, K, row, w)  # INLINE


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _keep_for_forces(w):
    """Q and P of this evaluation into w[OQC], w[OPC] (with w[OFLAG] set: a step's first stage
    from a recorded state), for :func:`_forces` after the step's later stages overwrote them.
    The forces are computed after the step, not in the stage loop: any work in that loop's
    body, even a matrix–vector product taken once per recorded row, made every evaluation of
    the bench's paper system about 20 % slower (numba/LLVM; ``nmkane bench``)."""
    for i in range(N * N):
        w[OQC + i] = w[OQ + i]
    for i in range(N):
        w[OPC + i] = w[OP + i]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _stages(t, h, x, p, G, G1, G2, TA, TC, K, xs, w, rcond_min, stats, order, solve_log):
    """Fill the stage derivatives K[i] of one explicit RK step; return a status code.
    (``order``, ``solve_log``: the rank-robust solve's partition and records, kernels with ROBUST.)"""
    S = TC.shape[0]
    n2 = 2 * N
    for i in range(S):
        for j in range(n2):
            xs[j] = x[j]
        for l in range(i):
            ha = h * TA[i, l]
            if ha != 0.0:
                for j in range(n2):
                    xs[j] += ha * K[l, j]
        total = 0.0
        for j in range(n2):
            total += abs(xs[j])
        if not math.isfinite(total):  # a stage left the finite numbers: divergence
            return STATUS_DIVERGED
        rhs_ws(t + TC[i] * h, xs, p, G, G1, G2, K, i, w)  # INLINE
        if ROBUST:
            code = _robust_outcome(t + TC[i] * h, h, w, stats, order, solve_log, i == 0)
            if code != STATUS_OK:
                return code
        rc0 = w[ORC]
        rc1 = w[ORC + 1]
        if rc0 <= rcond_min or rc1 <= rcond_min:
            if not _finite_work(w):  # not singular: the model's expressions are not defined here
                return STATUS_DIVERGED
        if rc0 < stats[STATS_RCOND_J2]:
            stats[STATS_RCOND_J2] = rc0
        if rc1 < stats[STATS_RCOND_T]:
            stats[STATS_RCOND_T] = rc1
        if rc0 <= rcond_min:
            return STATUS_J2_SINGULAR
        if rc1 <= rcond_min:
            return STATUS_T_SINGULAR
        if i == 0:  # with OFLAG, the first stage has kept what the forces need: later stages keep nothing
            w[OFLAG] = 0.0
    return STATUS_OK


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _robust_outcome(t, h, w, stats, order, solve_log, start):
    """After an evaluation of a kernel with the rank-robust solve (a stage of a step ``h``): its
    counters into ``stats``, a change of solve or partition into the solve log, and the status
    it ends a run with (Q not positive definite, J u̇ = c inconsistent, the Baumgarte terms
    carrying more than ROBUST_LEAVE_KE of the kinetic energy in a step; not finite terms:
    diverged).  J u̇ = c is judged at a step's ``start`` only, the state the integrator
    accepted: a later stage's trial state is off the constraints by the step's truncation
    error (O(h²) for the second stage), where redundant equations disagree by that much for
    no fault of the motion; its least-squares u̇ is used as it is."""
    st = w[OSV + SV_STATUS]
    if st == 2.0 and not start:
        st = 0.0
        w[OSV + SV_STATUS] = 0.0
    if st != 0.0 and not _finite_work(w):
        return STATUS_DIVERGED
    share = h * h * w[OSV + SV_STAB]
    if share > stats[STATS_MAX_STAB]:
        stats[STATS_MAX_STAB] = share
    if w[OSV + SV_USED] == 1.0:
        stats[STATS_ROBUST_EVALS] += 1.0
        if w[OSV + SV_PIVOT] < stats[STATS_MIN_PIVOT]:
            stats[STATS_MIN_PIVOT] = w[OSV + SV_PIVOT]
        if w[OSV + SV_RANK] < stats[STATS_MIN_RANK]:
            stats[STATS_MIN_RANK] = w[OSV + SV_RANK]
    if w[OSV + SV_CHANGED] != 0.0 or st == 2.0:
        _log_solve(t, w, stats, order, solve_log)
    code = STATUS_OK
    if st == 1.0:
        code = STATUS_Q_SINGULAR
    elif st == 2.0:
        code = STATUS_INCONSISTENT
    elif share > ROBUST_LEAVE_KE:
        code = STATUS_LEFT_CONSTRAINTS
    return code


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _finite_work(w):
    """Whether the right-hand side's work array is finite (the cold path of a zero or tiny
    condition estimate: a NaN pivot — √ of a negative number, 0/0 — also gives rcond 0)."""
    for i in range(ORC):
        if not math.isfinite(w[i]):
            return False
    return True


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _record(t, x, p, viol, stats, nv):
    """Diagnostics of an accepted state; running maxima in ``stats``. Returns E, or NaN
    (and leaves the maxima untouched) when any diagnostic is not finite."""
    E = diagnostics(t, x, p, viol)
    dE = E - stats[STATS_E0]
    if not math.isfinite(dE):
        return np.nan
    for i in range(nv):
        if not math.isfinite(viol[i]):
            return np.nan
    if abs(dE) > stats[STATS_MAX_DRIFT]:
        stats[STATS_MAX_DRIFT] = abs(dE)
    stats[STATS_FINAL_DRIFT] = dE
    for i in range(nv):
        v = abs(viol[i])
        if v > stats[STATS_VIOL + i]:
            stats[STATS_VIOL + i] = v
    return E


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _forces(w, K, krow):
    """The constraint forces of the state whose derivative is K[krow] (after ``rhs_ws`` with
    w[OFLAG] set, and any evaluations since without it): F_c = Q u̇ − P into w[OFC] ([u_I, u_D]
    order) and the multipliers λ of F_c = Jᵀλ into w[OLAM], from the dependent rows
    (F_c)_D = J2ᵀλ (exact: the independent rows (F_c)_I = J1ᵀλ follow from A2 F_c = 0, the
    nonminimal equations).  u̇ is the run's own, the Baumgarte terms included."""
    if ROBUST:
        _forces_robust(w, K, krow)
    else:
        _forces_paper(w, K, krow)


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _store_forces(w, row, out_F, out_L):
    """The forces in w (from :func:`_forces`) as output row ``row`` (model order)."""
    for r in range(N):
        out_F[row, PERM[r]] = w[OFC + r]
    for a in range(M):
        out_L[row, a] = w[OLAM + a]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _project_step(t, x, p, w, ps, proj, stats, viol, perm):
    """The post-step projection of an accepted state; its status (a singular correction
    matrix; with the rank-robust solve also: the motion left the constraints)."""
    code = project(t, x, p, w, ps, proj, stats[STATS_E0], viol, perm)  # INLINE
    if ROBUST:
        if w[OSV + SV_LEAVE] > stats[STATS_MAX_LEAVE]:
            stats[STATS_MAX_LEAVE] = w[OSV + SV_LEAVE]
    status = STATUS_OK
    if code == 1:
        status = STATUS_PROJECTION_FAILED
    elif code == 2:
        status = STATUS_LEFT_CONSTRAINTS
    return status


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def integrate_fixed(*FixedArgs):  # the fields of kernel.interface.FixedArgs
    """Steps k0 … k1−1 of a fixed-step run of ``nsteps`` steps; ``x`` is advanced in place.

    Row r of the outputs holds the state after step r·every (and the final state), and its
    constraint forces (``out_F``, ``out_L``; none when they have no rows): those of a row come
    with the first stage of the step that starts from it, so the row written by a call's last
    step is returned as ``pending`` (−1: none) for the next call — or the driver — to fill.
    Returns (status, steps done so far, next free row, pending row).
    """
    S = TC.shape[0]
    n2 = 2 * N
    K = np.empty((S, n2))
    xs = np.empty(n2)
    xn = np.empty(n2)
    viol = np.empty(NV)
    w = make_workspace()
    if ROBUST:
        solve_setup(w, solve, rank_tol, max_rank, consistency_tol, rcond_robust, rcond_min, order, proj is not None)
    ps = make_projection_scratch()
    perm = PERM.copy()
    forces = out_F.shape[0] > 0
    for k in range(k0, k1):
        t = t0 + k * dt
        h = dt if k < nsteps - 1 else t_final - t
        w[OFLAG] = 1.0 if pending >= 0 else 0.0
        code = _stages(t, h, x, p, G, G1, G2, TA, TC, K, xs, w, rcond_min, stats, order, solve_log)
        if code != STATUS_OK:
            return code, k, row, pending
        if pending >= 0:  # the forces of the row this step started from (its first stage)
            _forces(w, K, 0)
            _store_forces(w, pending, out_F, out_L)
            pending = -1
        for j in range(n2):
            xn[j] = x[j]
        for i in range(S):
            hb = h * TB[i]
            if hb != 0.0:
                for j in range(n2):
                    xn[j] += hb * K[i, j]
        total = 0.0
        for j in range(n2):
            total += abs(xn[j])
        if not math.isfinite(total):
            return STATUS_DIVERGED, k, row, pending
        tn = t0 + (k + 1) * dt if k < nsteps - 1 else t_final
        if proj is not None:
            code = _project_step(tn, xn, p, w, ps, proj, stats, viol, perm)
            if code != STATUS_OK:
                return code, k, row, pending
        E = _record(tn, xn, p, viol, stats, NV)
        if not math.isfinite(E):
            return STATUS_DIVERGED, k, row, pending
        for j in range(n2):
            x[j] = xn[j]
        if (k + 1) % every == 0 or k + 1 == nsteps:
            out_t[row] = tn
            for j in range(n2):
                out_x[row, j] = x[j]
            out_E[row] = E
            for j in range(NV):
                out_V[row, j] = viol[j]
            if forces:
                pending = row
            row += 1
    return STATUS_OK, k1, row, pending


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _step_error(t, h, x, xn, p, K, TB, TE, w, proj, atol, rtol):
    """The embedded step's new state into ``xn`` and (its scaled RMS error estimate
    h Σ TE_i K_i, whether the new state is finite; inf when it is not).  With the robust solve and a projection, without
    the error's components along the constraint normals (the projection's business):
    source/robust.py _tangent (ODX is a robust kernel's slot)."""
    S = K.shape[0]
    n2 = x.shape[0]
    errsum = 0.0
    if ROBUST and proj is not None:
        for j in range(n2):
            acc = 0.0
            accE = 0.0
            for i in range(S):
                acc += TB[i] * K[i, j]
                accE += TE[i] * K[i, j]
            xn[j] = x[j] + h * acc
            w[ODX + j] = h * accE
            if not math.isfinite(xn[j]):
                return np.inf, False
        _tangent(t + h, xn, p, w, proj)
        for j in range(n2):
            sc = atol + rtol * max(abs(x[j]), abs(xn[j]))
            e = w[ODX + j] / sc
            errsum += e * e
    else:
        for j in range(n2):
            acc = 0.0
            accE = 0.0
            for i in range(S):
                acc += TB[i] * K[i, j]
                accE += TE[i] * K[i, j]
            xn[j] = x[j] + h * acc
            if not math.isfinite(xn[j]):
                return np.inf, False
            sc = atol + rtol * max(abs(x[j]), abs(xn[j]))
            e = h * accE / sc
            errsum += e * e
    return math.sqrt(errsum / n2), True


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def integrate_adaptive(*AdaptiveArgs):  # the fields of kernel.interface.AdaptiveArgs
    """Adaptive embedded-RK run from t until t_final, the output buffer is full, or
    ``max_steps`` attempts; error = h Σ TE_i K_i, step control with exponent ``err_exp``.

    Constraint forces of the rows as in ``integrate_fixed`` (``pending``: a row that receives
    the forces of the starting state, or −1); the row written by the call's last accepted step
    is returned as ``pending`` (−1: none) for the driver to fill.
    Returns (status, t, h, rows written, accepted steps, attempted steps, pending row).
    """
    S = TC.shape[0]
    n2 = 2 * N
    K = np.empty((S, n2))
    xs = np.empty(n2)
    xn = np.empty(n2)
    viol = np.empty(NV)
    w = make_workspace()
    if ROBUST:
        solve_setup(w, solve, rank_tol, max_rank, consistency_tol, rcond_robust, rcond_min, order, proj is not None)
    ps = make_projection_scratch()
    perm = PERM.copy()
    cap = out_t.shape[0]
    row = 0
    attempts = 0
    forces = out_F.shape[0] > 0
    while t < t_final and row < cap:
        if attempts >= max_steps:
            return STATUS_BUDGET, t, h, row, accepted, attempts, pending
        attempts += 1
        last = False
        if t + h >= t_final or (t_final - t - h) < STEP_LAST_REL * abs(t_final):
            h = t_final - t
            last = True
        w[OFLAG] = 1.0 if pending >= 0 else 0.0
        code = _stages(t, h, x, p, G, G1, G2, TA, TC, K, xs, w, rcond_min, stats, order, solve_log)
        if pending >= 0 and w[OFLAG] == 0.0:  # the first stage came through: the row's forces
            _forces(w, K, 0)
            _store_forces(w, pending, out_F, out_L)
            pending = -1
        # a stage that left the finite numbers (a trial step past a point where the model's
        # expressions are not defined: √ of a negative number, a zero denominator) is rejected
        # like an infinite error: the step shrinks, and the run fails only below hmin
        finite = code == STATUS_OK
        if code != STATUS_OK and code != STATUS_DIVERGED:
            return code, t, h, row, accepted, attempts, pending
        if finite:
            err, finite = _step_error(t, h, x, xn, p, K, TB, TE, w, proj, atol, rtol)
        else:
            err = np.inf
        nonfinite = not finite
        if err <= 1.0:
            tn = t_final if last else t + h
            if proj is not None:
                code = _project_step(tn, xn, p, w, ps, proj, stats, viol, perm)
                if code != STATUS_OK:
                    return code, t, h, row, accepted, attempts, pending
            E = _record(tn, xn, p, viol, stats, NV)
            if not math.isfinite(E):
                return STATUS_DIVERGED, t, h, row, accepted, attempts, pending
            t = tn
            for j in range(n2):
                x[j] = xn[j]
            accepted += 1
            if accepted % every == 0 or t >= t_final:
                out_t[row] = t
                for j in range(n2):
                    out_x[row, j] = x[j]
                out_E[row] = E
                for j in range(NV):
                    out_V[row, j] = viol[j]
                if forces:
                    pending = row
                row += 1
            if err == 0.0:
                fac = STEP_FAC_MAX
            else:
                fac = min(STEP_FAC_MAX, max(STEP_FAC_MIN, STEP_SAFETY * err ** (-err_exp)))
        else:
            fac = STEP_FAC_MIN if not math.isfinite(err) else max(STEP_FAC_MIN, STEP_SAFETY * err ** (-err_exp))
        h = min(h * fac, hmax)
        if h < hmin and t < t_final:  # non-finite trial steps down to hmin: the state cannot go on finite
            return STATUS_DIVERGED if nonfinite else STATUS_FAILED, t, h, row, accepted, attempts, pending
    return STATUS_OK, t, h, row, accepted, attempts, pending
