/* The entry points Python calls (kernel/cmodel.py declares them; kernel/core.py their types):
 * the loops, and what Python callers evaluate at given states: the right-hand side, diagnostics,
 * outputs and constraint forces over many rows, the constraint quantities that complete and check
 * initial states, and the projection of one state. */

#define NMK_EXPORT __attribute__((visibility("default")))

/* The specialised build (kernel/special.py) compiles this core with one model in the same unit:
 * NMK_MODEL is then a constant record with the model's sizes and functions, every entry point
 * works on it (the record passed from Python is the same model's), and the compiler folds the
 * sizes into the loops and inlines the model's functions.  The same arithmetic in the same order:
 * the same bits as the generic build. */
#ifdef NMK_SPECIAL
#define MODEL(md) ((void)(md), &NMK_MODEL)
#else
#define MODEL(md) (md)
#endif

NMK_EXPORT i64 nmk_integrate_fixed(const nmk_model *md, const nmk_fixed_args *a, double *ret) {
    md = MODEL(md);
    return integrate_fixed(md, a, ret);
}

NMK_EXPORT i64 nmk_integrate_adaptive(const nmk_model *md, const nmk_adaptive_args *a, double *ret) {
    md = MODEL(md);
    return integrate_adaptive(md, a, ret);
}

/* A fresh work array (WSIZE entries) for rhs_ws. */
NMK_EXPORT void nmk_make_workspace(const nmk_model *md, double *w) { init_workspace(MODEL(md), w); }

/* x' into K[row] at one state, the estimates at w[ORC ...] (the kinematics' too, where C varies). */
NMK_EXPORT void nmk_rhs_ws(const nmk_model *md, double t, const double *x, const double *p, const double *G,
                           const double *G1, const double *G2, double *K, i64 row, double *w) {
    md = MODEL(md);
    rhs_ws(md, t, x, p, G, G1, G2, K, row, w);
    if (md->KN) w[md->ORC + 2] = kinematic_estimate(md, t, x, p, w);
}

NMK_EXPORT double nmk_diagnostics(const nmk_model *md, double t, const double *x, const double *p, double *viol) {
    md = MODEL(md);
    return md->diagnostics(t, x, p, viol);
}

/* Energy and violations of many states (rows of 2N). */
NMK_EXPORT void nmk_diagnostics_rows(const nmk_model *md, i64 rows, const double *ts, const double *xs,
                                     const double *p, double *E, double *V) {
    md = MODEL(md);
    double *viol = malloc((size_t)(md->NV + 1) * sizeof(double));
    if (!viol) return;
    for (i64 r = 0; r < rows; ++r) {
        E[r] = md->diagnostics(ts[r], xs + r * 2 * md->N, p, viol);
        for (i64 j = 0; j < md->NV; ++j) V[r * md->NV + j] = viol[j];
    }
    free(viol);
}

/* The model's outputs at many states. */
NMK_EXPORT void nmk_outputs_rows(const nmk_model *md, i64 rows, const double *ts, const double *xs, const double *p,
                                 double *O) {
    md = MODEL(md);
    for (i64 r = 0; r < rows; ++r) md->outputs(ts[r], xs + r * 2 * md->N, p, O + r * md->NO);
}

/* Constraint forces (F_c = Q u' - P, model order) and multipliers of many states, for the drivers
 * whose steps are not the loops' (the scipy adapter): one right-hand side each. */
NMK_EXPORT void nmk_forces_rows(const nmk_model *md, i64 rows, const double *ts, const double *xs, const double *p,
                                const double *G, const double *G1, const double *G2, double *F, double *L) {
    md = MODEL(md);
    double *w = malloc((size_t)(md->WSIZE + 1) * sizeof(double));
    double *K = malloc((size_t)(2 * md->N + 1) * sizeof(double));
    if (w && K) {
        init_workspace(md, w);
        for (i64 r = 0; r < rows; ++r) {
            w[md->OFLAG] = 1.0;
            rhs_ws(md, ts[r], xs + r * 2 * md->N, p, G, G1, G2, K, 0, w);
            forces(md, w, K, 0);
            store_forces(md, w, r, F, L);
        }
    }
    free(w);
    free(K);
}

/* Constraint quantities at one state, for completing and checking initial states: J =
 * d[phi; psi']/du (M x N, the model's speed order), c = [phi; psi'], psi, dpsi/dq (MH x N) and the
 * reported violations. */
NMK_EXPORT void nmk_state_terms(const nmk_model *md, double t, const double *x, const double *p, double *J,
                                double *c, double *psi, double *psi_q, double *viol) {
    md = MODEL(md);
    const i64 N = md->N, M = md->M;
    double *w = malloc((size_t)(md->WSIZE + 1) * sizeof(double));
    if (!w) return;
    init_workspace(md, w);
    md->constraint_terms(t, x, p, w); /* J, phi, psi' only (no Q, P) */
    md->positions(t, x, p, w);
    for (i64 a = 0; a < M; ++a)
        for (i64 j = 0; j < N; ++j) J[a * N + md->PERM[j]] = w[md->OJ + a * N + j];
    for (i64 a = 0; a < md->MNH; ++a) c[a] = w[md->OPHIN + a];
    for (i64 a = 0; a < md->MH; ++a) c[md->MNH + a] = w[md->OPSID + a];
    memcpy(psi, w + md->OPSI, (size_t)md->MH * sizeof(double));
    memcpy(psi_q, w + md->OPSQ, (size_t)(md->MH * N) * sizeof(double));
    md->diagnostics(t, x, p, viol);
    free(w);
}

/* Project one state (y, in place) onto the constraint manifold (initial states); max_rank >= 0
 * sets the rank of the model's constraints and asks for the robust projection (kernels with the
 * robust solve), −1 the paper's (on a declared partition: project_paper).  Returns the
 * projection's code (0 ok, 1 a singular correction matrix, 2 left the constraints; -1 no memory). */
NMK_EXPORT i64 nmk_project_state(const nmk_model *md, double t, double *y, const double *p, const i64 *proj,
                                 i64 max_rank) {
    md = MODEL(md);
    double *w = malloc((size_t)(md->WSIZE + 1) * sizeof(double));
    double *ps = calloc((size_t)(md->PS_SIZE + 1), sizeof(double));
    double *viol = malloc((size_t)(md->NV + 1) * sizeof(double));
    i64 code = -1;
    if (w && ps && viol) {
        init_workspace(md, w);
        if (md->ROBUST && max_rank >= 0) w[md->OSV + SV_MAX_RANK] = (double)max_rank;
        if (md->ROBUST && max_rank < 0) w[md->OSV + SV_MODE] = 0.0;
        code = project(md, t, y, p, w, ps, proj, 0.0, viol, md->PERM);
    }
    free(w);
    free(ps);
    free(viol);
    return code;
}

NMK_EXPORT void nmk_solve_setup(const nmk_model *md, double *w, i64 solve, double rank_tol, i64 max_rank,
                                double consistency_tol, double rcond_robust, double rcond_min, const i64 *order,
                                i64 projected) {
    md = MODEL(md);
    solve_setup(md, w, solve, rank_tol, max_rank, consistency_tol, rcond_robust, rcond_min, order, projected != 0);
}

/* The loops' bookkeeping of the rank-robust solve after one right-hand side (the scipy adapter
 * calls it between scipy's steps). */
NMK_EXPORT i64 nmk_robust_outcome(const nmk_model *md, double t, double h, double *w, double *stats, i64 *order,
                                  double *log_a, i64 log_rows, i64 log_cols, i64 start) {
    md = MODEL(md);
    nmk_log log = {log_a, log_rows, log_cols};
    return robust_outcome(md, t, h, w, stats, order, &log, start != 0);
}
