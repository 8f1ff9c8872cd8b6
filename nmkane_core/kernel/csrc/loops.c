/* The right-hand side and the integrator loops: one fixed-step loop and one adaptive loop serve
 * every explicit Runge-Kutta tableau (methods are data).  A division by zero gives +-inf or NaN,
 * as the square root of a negative number does; the loops' finiteness checks turn such values
 * into a status (STATUS_DIVERGED; the adaptive loop first rejects the trial step and shrinks it).
 *
 * proj (i64 array) = [weight (0 identity, 1 mass), position iterations, Newton (1 updated
 * Jacobian, 0 frozen), energy correction (0/1), N, M, MNH, MH], or NULL for no projection. */

/* The flat scratch array of one right-hand side evaluation (WORKSPACE in kernel/interface.py),
 * zeroed, with the condition estimates at 1 and the robust solve's defaults. */
static void init_workspace(const nmk_model *md, double *w) {
    memset(w, 0, (size_t)md->WSIZE * sizeof(double));
    w[md->ORC] = 1.0;
    w[md->ORC + 1] = 1.0;
    w[md->ORC + 2] = 1.0;
    if (md->ROBUST) solve_defaults(md, w);
}

/* x' = [C u + D; T^-1 V^] into K[row]; w[ORC], w[ORC + 1] receive the rcond of J2, T (the
 * kinematics' estimate, w[ORC + 2], is the caller's: stages(), nmk_rhs_ws).  With w[OFLAG] set,
 * what forces() needs is kept (keep_for_forces). */
static NMK_HOT void rhs_ws(const nmk_model *md, double t, const double *x, const double *p, const double *G,
                   const double *G1, const double *G2, double *K, i64 row, double *w) {
    if (robust_in_use(md, w))
        rhs_robust(md, t, x, p, G, G1, G2, K, row, w);
    else
        rhs_paper(md, t, x, p, G, G1, G2, K, row, w);
}

/* Q and P of this evaluation into w[OQC], w[OPC] (with w[OFLAG] set: a step's first stage from a
 * recorded state), for forces() after the step's later stages overwrote them. */
static NMK_HOT void keep_for_forces(const nmk_model *md, double *w) {
    memcpy(w + md->OQC, w + md->OQ, (size_t)(md->N * md->N) * sizeof(double));
    memcpy(w + md->OPC, w + md->OP, (size_t)md->N * sizeof(double));
}

/* Whether the right-hand side's work array is finite (the cold path of a zero or tiny condition
 * estimate: a NaN pivot also gives rcond 0). */
static int finite_work(const nmk_model *md, const double *w) {
    for (i64 i = 0; i < md->ORC; ++i)
        if (!isfinite(w[i])) return 0;
    return 1;
}

/* After an evaluation of a kernel with the rank-robust solve (a stage of a step h): its counters
 * into stats, a change of solve or partition into the solve log, and the status it ends a run
 * with (Q not positive definite, J u' = c inconsistent, the Baumgarte terms carrying more than
 * ROBUST_LEAVE_KE of the kinetic energy in a step; not finite terms: diverged).  J u' = c is
 * judged at a step's start only, the state the integrator accepted. */
static i64 robust_outcome(const nmk_model *md, double t, double h, double *w, double *stats, i64 *order,
                          nmk_log *solve_log, int start) {
    const i64 OSV = md->OSV;
    if (!robust_in_use(md, w)) return STATUS_OK;
    double st = w[OSV + SV_STATUS];
    if (st == 2.0 && !start) {
        st = 0.0;
        w[OSV + SV_STATUS] = 0.0;
    }
    if (st != 0.0 && !finite_work(md, w)) return STATUS_DIVERGED;
    double share = h * h * w[OSV + SV_STAB];
    if (share > stats[STATS_MAX_STAB]) stats[STATS_MAX_STAB] = share;
    if (w[OSV + SV_USED] == 1.0) {
        stats[STATS_ROBUST_EVALS] += 1.0;
        if (w[OSV + SV_PIVOT] < stats[STATS_MIN_PIVOT]) stats[STATS_MIN_PIVOT] = w[OSV + SV_PIVOT];
        if (w[OSV + SV_RANK] < stats[STATS_MIN_RANK]) stats[STATS_MIN_RANK] = w[OSV + SV_RANK];
    }
    if (w[OSV + SV_CHANGED] != 0.0 || st == 2.0) log_solve(md, t, w, stats, order, solve_log);
    i64 code = STATUS_OK;
    if (st == 1.0)
        code = STATUS_Q_SINGULAR;
    else if (st == 2.0)
        code = STATUS_INCONSISTENT;
    else if (share > ROBUST_LEAVE_KE)
        code = STATUS_LEFT_CONSTRAINTS;
    return code;
}

/* Fill the stage derivatives K[i] of one explicit RK step (S stages); return a status code: the
 * first of J2, T and the kinematics' C whose estimate falls to rcond_min, or, near a singular
 * chart (C's estimate below KIN_NEAR), a step whose stages see that estimate change by more than
 * KIN_STEP_CHANGE of its smallest value (STATUS_C_UNRESOLVED: the step misses the coordinates'
 * swing there; the adaptive loop shrinks it, a fixed step ends the run).  Where C varies (KN > 0)
 * its estimate is made at the step's start, and at its other stages while it is below KIN_WATCH. */
static i64 stages(const nmk_model *md, double t, double h, const double *x, const double *p, const double *G,
                  const double *G1, const double *G2, const double *TA, const double *TC, i64 S, double *K,
                  double *xs, double *w, double rcond_min, double *stats, i64 *order, nmk_log *solve_log) {
    const i64 n2 = 2 * md->N;
    double klo = INFINITY, khi = 0.0; /* the kinematics' estimate over the stages */
    for (i64 i = 0; i < S; ++i) {
        for (i64 j = 0; j < n2; ++j) xs[j] = x[j];
        for (i64 l = 0; l < i; ++l) {
            double ha = h * TA[i * S + l];
            if (ha != 0.0)
                for (i64 j = 0; j < n2; ++j) xs[j] += ha * K[l * n2 + j];
        }
        double total = 0.0;
        for (i64 j = 0; j < n2; ++j) total += fabs(xs[j]);
        if (!isfinite(total)) return STATUS_DIVERGED; /* a stage left the finite numbers: divergence */
        rhs_ws(md, t + TC[i] * h, xs, p, G, G1, G2, K, i, w);
        const int kin = md->KN && (i == 0 || klo < KIN_WATCH);
        if (kin) w[md->ORC + 2] = kinematic_estimate(md, t + TC[i] * h, xs, p, w);
        if (md->ROBUST) {
            i64 code = robust_outcome(md, t + TC[i] * h, h, w, stats, order, solve_log, i == 0);
            if (code != STATUS_OK) return code;
        }
        double rc0 = w[md->ORC], rc1 = w[md->ORC + 1], rc2 = kin ? w[md->ORC + 2] : 1.0;
        if (rc0 <= rcond_min || rc1 <= rcond_min || rc2 <= rcond_min)
            if (!finite_work(md, w)) return STATUS_DIVERGED; /* not singular: the expressions are not defined here */
        if (rc0 < stats[STATS_RCOND_J2]) stats[STATS_RCOND_J2] = rc0;
        if (rc1 < stats[STATS_RCOND_T]) stats[STATS_RCOND_T] = rc1;
        if (rc2 < stats[STATS_RCOND_C]) stats[STATS_RCOND_C] = rc2;
        if (rc0 <= rcond_min) return STATUS_J2_SINGULAR;
        if (rc1 <= rcond_min) return STATUS_T_SINGULAR;
        if (rc2 <= rcond_min) return STATUS_C_SINGULAR;
        if (kin && rc2 < klo) klo = rc2;
        if (kin && rc2 > khi) khi = rc2;
        if (i == 0) w[md->OFLAG] = 0.0; /* the first stage has kept what the forces need */
    }
    if (md->KN && klo < KIN_NEAR && khi - klo > KIN_STEP_CHANGE * klo) return STATUS_C_UNRESOLVED;
    return STATUS_OK;
}

/* Diagnostics of an accepted state; running maxima in stats.  Returns E, or NaN (and leaves the
 * maxima untouched) when any diagnostic is not finite. */
static double record(const nmk_model *md, double t, const double *x, const double *p, double *viol,
                     double *stats, i64 nv) {
    double E = md->diagnostics(t, x, p, viol);
    double dE = E - stats[STATS_E0];
    if (!isfinite(dE)) return NAN;
    for (i64 i = 0; i < nv; ++i)
        if (!isfinite(viol[i])) return NAN;
    if (fabs(dE) > stats[STATS_MAX_DRIFT]) stats[STATS_MAX_DRIFT] = fabs(dE);
    stats[STATS_FINAL_DRIFT] = dE;
    for (i64 i = 0; i < nv; ++i) {
        double v = fabs(viol[i]);
        if (v > stats[STATS_VIOL + i]) stats[STATS_VIOL + i] = v;
    }
    return E;
}

/* Whether an accepted state (its energy E and violations, from record) is past the run's bounds:
 * |E − E0| above drift_limit or a violation above violation_limit (STATUS_DRIFTED). */
static int past_bounds(const nmk_model *md, double E, const double *viol, const double *stats, double drift_limit,
                       double violation_limit) {
    if (fabs(E - stats[STATS_E0]) > drift_limit) return 1;
    for (i64 i = 0; i < md->NV; ++i)
        if (fabs(viol[i]) > violation_limit) return 1;
    return 0;
}

/* The constraint forces of the state whose derivative is K[krow] (after rhs_ws with w[OFLAG]
 * set): F_c = Q u' - P into w[OFC] ([u_I, u_D] order) and the multipliers lambda of F_c =
 * J^T lambda into w[OLAM], from the dependent rows (F_c)_D = J2^T lambda.  u' is the run's own,
 * the Baumgarte terms included. */
static void forces(const nmk_model *md, double *w, const double *K, i64 krow) {
    if (robust_in_use(md, w))
        forces_robust(md, w, K, krow);
    else
        forces_paper(md, w, K, krow);
}

/* The forces in w (from forces()) as output row `row` (model order). */
static void store_forces(const nmk_model *md, const double *w, i64 row, double *out_F, double *out_L) {
    for (i64 r = 0; r < md->N; ++r) out_F[row * md->N + md->PERM[r]] = w[md->OFC + r];
    for (i64 a = 0; a < md->M; ++a) out_L[row * md->M + a] = w[md->OLAM + a];
}

/* The post-step projection of an accepted state; its status (a singular correction matrix; with
 * the rank-robust solve also: the motion left the constraints). */
static i64 project_step(const nmk_model *md, double t, double *x, const double *p, double *w, double *ps,
                        const i64 *proj, double *stats, double *viol, const i64 *perm) {
    i64 code = project(md, t, x, p, w, ps, proj, stats[STATS_E0], viol, perm);
    if (md->ROBUST && w[md->OSV + SV_LEAVE] > stats[STATS_MAX_LEAVE]) stats[STATS_MAX_LEAVE] = w[md->OSV + SV_LEAVE];
    if (code == 1) return STATUS_PROJECTION_FAILED;
    if (code == 2) return STATUS_LEFT_CONSTRAINTS;
    return STATUS_OK;
}

/* The projection of the step just taken: the run's (proj), or, without one, near_proj where the
 * step came near a singular position of the constraints (an evaluation saw a row of J shorter
 * than ROBUST_NEAR_SINGULAR of the longest, or used the robust solve: SV_NEAR) — there the
 * equations amplify any drift off the branch by 1/|J_i| (a velocity asymmetry of a four-bar
 * chain's cranks grows as 1/t² towards the passage), and the projection in the mass metric
 * removes it (the loops count such steps in stats[STATS_NEAR_PROJECTIONS]).  NULL: none. */
static const i64 *step_projection(const nmk_model *md, const double *w, const i64 *proj, const i64 *near_proj) {
    if (proj != NULL) return proj;
    if (near_proj == NULL || !robust_in_use(md, w) || w[md->OSV + SV_NEAR] == 0.0) return NULL;
    return near_proj;
}

/* The scratch arrays of one loop call, allocated once per call. */
typedef struct {
    double *K, *xs, *xn, *viol, *w, *ps;
} nmk_scratch;

static int scratch_alloc(const nmk_model *md, i64 S, nmk_scratch *s) {
    const i64 n2 = 2 * md->N;
    s->K = malloc((size_t)(S * n2 + 1) * sizeof(double));
    s->xs = malloc((size_t)(n2 + 1) * sizeof(double));
    s->xn = malloc((size_t)(n2 + 1) * sizeof(double));
    s->viol = malloc((size_t)(md->NV + 1) * sizeof(double));
    s->w = malloc((size_t)(md->WSIZE + 1) * sizeof(double));
    s->ps = calloc((size_t)(md->PS_SIZE + 1), sizeof(double));
    if (!s->K || !s->xs || !s->xn || !s->viol || !s->w || !s->ps) return 0;
    init_workspace(md, s->w);
    return 1;
}

static void scratch_free(nmk_scratch *s) {
    free(s->K);
    free(s->xs);
    free(s->xn);
    free(s->viol);
    free(s->w);
    free(s->ps);
}

/* The rank-robust solve's settings into w, in kernels that have it. */
static void loop_solve_setup(const nmk_model *md, double *w, i64 solve, double rank_tol, i64 max_rank,
                             double consistency_tol, double rcond_robust, double rcond_min, const i64 *order,
                             int projected) {
    if (md->ROBUST)
        solve_setup(md, w, solve, rank_tol, max_rank, consistency_tol, rcond_robust, rcond_min, order, projected);
}

/* The work arrays of a loop call with the solve's settings in them; 0 when they could not be
 * allocated.  A macro: the two loops' argument records are two types with these fields in common. */
#define LOOP_SCRATCH(md, a, S, s)                                                                               \
    (scratch_alloc((md), (S), (s)) &&                                                                            \
     (loop_solve_setup((md), (s)->w, (a)->solve, (a)->rank_tol, (a)->max_rank, (a)->consistency_tol,            \
                       (a)->rcond_robust, (a)->rcond_min, (a)->order, (a)->proj != NULL),                        \
      1))

/* An accepted state as output row `row` (its time, state, energy and violations). */
static void write_row(const nmk_model *md, i64 row, double t, const double *x, double E, const double *viol,
                      double *out_t, double *out_x, double *out_E, double *out_V) {
    const i64 n2 = 2 * md->N;
    out_t[row] = t;
    memcpy(out_x + row * n2, x, (size_t)n2 * sizeof(double));
    out_E[row] = E;
    for (i64 j = 0; j < md->NV; ++j) out_V[row * md->NV + j] = viol[j];
}

/* Steps k0 ... k1-1 of a fixed-step run of nsteps steps; x is advanced in place.  Row r of the
 * outputs holds the state after step r*every (and the final state), and its constraint forces
 * (out_F, out_L; none when they have no rows): those of a row come with the first stage of the
 * step that starts from it, so the row written by a call's last step is returned as pending
 * (-1: none) for the next call, or the driver, to fill.  ret = (steps done so far, next free row,
 * pending row); returns the status. */
static i64 integrate_fixed(const nmk_model *md, const nmk_fixed_args *a, double *ret) {
    const i64 N = md->N, n2 = 2 * N, S = a->TC_n0, nsteps = a->nsteps, every = a->every;
    const i64 *proj = a->proj;
    double *x = a->x;
    nmk_log log = {a->solve_log, a->solve_log_n0, a->solve_log_n1};
    i64 row = a->row, pending = a->pending, k = a->k0;
    i64 status = STATUS_OK;
    nmk_scratch s;
    if (!LOOP_SCRATCH(md, a, S, &s)) {
        scratch_free(&s);
        ret[0] = (double)k, ret[1] = (double)row, ret[2] = (double)pending;
        return STATUS_FAILED;
    }
    double *K = s.K, *xn = s.xn, *w = s.w;
    const int with_forces = a->out_F_n0 > 0;
    for (; k < a->k1; ++k) {
        double t = a->t0 + (double)k * a->dt;
        double h = k < nsteps - 1 ? a->dt : a->t_final - t;
        w[md->OFLAG] = pending >= 0 ? 1.0 : 0.0;
        if (md->ROBUST) w[md->OSV + SV_NEAR] = 0.0;
        status = stages(md, t, h, x, a->p, a->G, a->G1, a->G2, a->TA, a->TC, S, K, s.xs, w, a->rcond_min, a->stats,
                        a->order, &log);
        if (status != STATUS_OK) break;
        if (pending >= 0) { /* the forces of the row this step started from (its first stage) */
            forces(md, w, K, 0);
            store_forces(md, w, pending, a->out_F, a->out_L);
            pending = -1;
        }
        for (i64 j = 0; j < n2; ++j) xn[j] = x[j];
        for (i64 i = 0; i < S; ++i) {
            double hb = h * a->TB[i];
            if (hb != 0.0)
                for (i64 j = 0; j < n2; ++j) xn[j] += hb * K[i * n2 + j];
        }
        double total = 0.0;
        for (i64 j = 0; j < n2; ++j) total += fabs(xn[j]);
        if (!isfinite(total)) {
            status = STATUS_DIVERGED;
            break;
        }
        double tn = k < nsteps - 1 ? a->t0 + (double)(k + 1) * a->dt : a->t_final;
        const i64 *pj = step_projection(md, w, proj, a->near_proj);
        if (pj != NULL) {
            if (pj != proj) a->stats[STATS_NEAR_PROJECTIONS] += 1.0;
            status = project_step(md, tn, xn, a->p, w, s.ps, pj, a->stats, s.viol, md->PERM);
            if (status != STATUS_OK) break;
        }
        double E = record(md, tn, xn, a->p, s.viol, a->stats, md->NV);
        if (!isfinite(E)) {
            status = STATUS_DIVERGED;
            break;
        }
        if (past_bounds(md, E, s.viol, a->stats, a->drift_limit, a->violation_limit)) {
            status = STATUS_DRIFTED;
            break;
        }
        for (i64 j = 0; j < n2; ++j) x[j] = xn[j];
        if ((k + 1) % every == 0 || k + 1 == nsteps) {
            write_row(md, row, tn, x, E, s.viol, a->out_t, a->out_x, a->out_E, a->out_V);
            if (with_forces) pending = row;
            ++row;
        }
    }
    scratch_free(&s);
    if (status == STATUS_OK) k = a->k1;
    ret[0] = (double)k, ret[1] = (double)row, ret[2] = (double)pending;
    return status;
}

/* The embedded step's new state into xn and its scaled RMS error estimate h sum TE_i K_i
 * (returns inf and *finite = 0 when the new state is not finite).  With the robust solve and a
 * projection, without the error's components along the constraint normals (the projection's
 * business): the estimate is kept at w[ODX] for tangent() in robust_projection.c; otherwise in
 * dx (2N entries of scratch). */
static double step_error(const nmk_model *md, double t, double h, const double *x, double *xn, const double *p,
                         const double *K, i64 S, const double *TB, const double *TE, double *w, const i64 *proj,
                         double atol, double rtol, double *dx, int *finite) {
    const i64 n2 = 2 * md->N;
    const int tangential = md->ROBUST && proj != NULL;
    double *d = tangential ? w + md->ODX : dx;
    *finite = 1;
    for (i64 j = 0; j < n2; ++j) {
        double acc = 0.0, accE = 0.0;
        for (i64 i = 0; i < S; ++i) {
            acc += TB[i] * K[i * n2 + j];
            accE += TE[i] * K[i * n2 + j];
        }
        xn[j] = x[j] + h * acc;
        d[j] = h * accE;
        if (!isfinite(xn[j])) {
            *finite = 0;
            return INFINITY;
        }
    }
    if (tangential) tangent(md, t + h, xn, p, w, proj);
    double errsum = 0.0;
    for (i64 j = 0; j < n2; ++j) {
        double sc = atol + rtol * nmk_max(fabs(x[j]), fabs(xn[j]));
        double e = d[j] / sc;
        errsum += e * e;
    }
    return sqrt(errsum / (double)n2);
}

/* Adaptive embedded-RK run from t until t_final, the output buffer is full, or max_steps attempts;
 * error = h sum TE_i K_i, step control with exponent err_exp.  Constraint forces of the rows as in
 * integrate_fixed (pending: a row that receives the forces of the starting state, or -1).
 * ret = (t, h, rows written, accepted steps, attempted steps, pending row); returns the status. */
static i64 integrate_adaptive(const nmk_model *md, const nmk_adaptive_args *a, double *ret) {
    const i64 N = md->N, n2 = 2 * N, S = a->TC_n0, every = a->every, cap = a->out_t_n0;
    const i64 *proj = a->proj;
    const double t_final = a->t_final;
    double *x = a->x;
    nmk_log log = {a->solve_log, a->solve_log_n0, a->solve_log_n1};
    double t = a->t, h = a->h;
    i64 row = 0, attempts = 0, accepted = a->accepted, pending = a->pending;
    i64 status = STATUS_OK;
    nmk_scratch s;
    if (!LOOP_SCRATCH(md, a, S, &s)) {
        scratch_free(&s);
        status = STATUS_FAILED;
        goto done;
    }
    double *K = s.K, *xn = s.xn, *w = s.w;
    const int with_forces = a->out_F_n0 > 0;
    while (t < t_final && row < cap) {
        if (attempts >= a->max_steps) {
            status = STATUS_BUDGET;
            break;
        }
        ++attempts;
        int last = 0;
        if (t + h >= t_final || (t_final - t - h) < STEP_LAST_REL * fabs(t_final)) {
            h = t_final - t;
            last = 1;
        }
        w[md->OFLAG] = pending >= 0 ? 1.0 : 0.0;
        if (md->ROBUST) w[md->OSV + SV_NEAR] = 0.0;
        i64 code = stages(md, t, h, x, a->p, a->G, a->G1, a->G2, a->TA, a->TC, S, K, s.xs, w, a->rcond_min, a->stats,
                          a->order, &log);
        if (pending >= 0 && w[md->OFLAG] == 0.0) { /* the first stage came through: the row's forces */
            forces(md, w, K, 0);
            store_forces(md, w, pending, a->out_F, a->out_L);
            pending = -1;
        }
        /* a stage that left the finite numbers (a trial step past a point where the model's
         * expressions are not defined), or a step too long for the kinematics near a singular
         * chart, is rejected like an infinite error: the step shrinks, and the run fails only
         * below hmin */
        int finite = code == STATUS_OK;
        int unresolved = code == STATUS_C_UNRESOLVED;
        if (code != STATUS_OK && code != STATUS_DIVERGED && !unresolved) {
            status = code;
            break;
        }
        double err = INFINITY;
        /* near a singular position without a projection: the step is projected (step_projection),
         * so its error is judged along the constraints, as with a projection */
        const i64 *pj = finite ? step_projection(md, w, proj, a->near_proj) : proj;
        if (finite)  /* the stages are done with xs: it holds the error estimate */
            err = step_error(md, t, h, x, xn, a->p, K, S, a->TB, a->TE, w, pj, a->atol, a->rtol, s.xs, &finite);
        int nonfinite = !finite && !unresolved;
        double fac;
        if (err <= 1.0) {
            double tn = last ? t_final : t + h;
            if (pj != NULL) {
                if (pj != proj) a->stats[STATS_NEAR_PROJECTIONS] += 1.0;
                code = project_step(md, tn, xn, a->p, w, s.ps, pj, a->stats, s.viol, md->PERM);
                if (code != STATUS_OK) {
                    status = code;
                    break;
                }
            }
            double E = record(md, tn, xn, a->p, s.viol, a->stats, md->NV);
            if (!isfinite(E)) {
                status = STATUS_DIVERGED;
                break;
            }
            if (past_bounds(md, E, s.viol, a->stats, a->drift_limit, a->violation_limit)) {
                status = STATUS_DRIFTED;
                break;
            }
            t = tn;
            for (i64 j = 0; j < n2; ++j) x[j] = xn[j];
            ++accepted;
            if (accepted % every == 0 || t >= t_final) {
                write_row(md, row, t, x, E, s.viol, a->out_t, a->out_x, a->out_E, a->out_V);
                if (with_forces) pending = row;
                ++row;
            }
            if (err == 0.0)
                fac = STEP_FAC_MAX;
            else
                fac = nmk_min(STEP_FAC_MAX, nmk_max(STEP_FAC_MIN, STEP_SAFETY * pow(err, -a->err_exp)));
        } else {
            fac = !isfinite(err) ? STEP_FAC_MIN : nmk_max(STEP_FAC_MIN, STEP_SAFETY * pow(err, -a->err_exp));
        }
        h = nmk_min(h * fac, a->hmax);
        if (h < a->hmin && t < t_final) { /* non-finite trial steps down to hmin: the state cannot go on finite */
            status = unresolved ? STATUS_C_UNRESOLVED : nonfinite ? STATUS_DIVERGED : STATUS_FAILED;
            break;
        }
    }
    scratch_free(&s);
done:
    ret[0] = t, ret[1] = h, ret[2] = (double)row, ret[3] = (double)accepted, ret[4] = (double)attempts;
    ret[5] = (double)pending;
    return status;
}
