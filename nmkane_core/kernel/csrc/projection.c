/* The post-step projections (Blajer 2002; Yoon, Howe & Greenwood 1994) onto the constraint
 * manifold.  integrate/projection.py describes the options (the proj array's layout). */

/* delta = W^-1 G^T (G W^-1 G^T)^-1 r for G (mrows x n) and r stored at ps[PS_OG:].  metric 0:
 * W = I (Moore-Penrose); 1: the kinetic-energy metric for a speed correction, W = Q; 2: the same
 * for a coordinate correction, W = C^-T Q C^-1 (so W^-1 = C Q^-1 C^T).  Needs Q (terms) and C
 * (positions) in w when weighted.  delta is left at ps[PS_OD:PS_OD + N]; returns the pivot-ratio
 * rcond of G W^-1 G^T. */
static double weighted_correction(const nmk_model *md, const double *w, double *ps, i64 mrows, i64 metric,
                                  const i64 *perm) {
    const i64 N = md->N, OY = md->PS_OY, OZ = md->PS_OZ, OS = md->PS_OS, OZR = md->PS_OZR, OD = md->PS_OD;
    const i64 OG = md->PS_OG, OR_ = OG + mrows * N;
    for (i64 i = 0; i < N; ++i)
        for (i64 r = 0; r < mrows; ++r) ps[OY + i * mrows + r] = ps[OG + r * N + i]; /* Y = G^T */
    if (metric > 0) {
        for (i64 i = 0; i < N; ++i) /* Q, model order */
            for (i64 j = 0; j < N; ++j) ps[perm[i] * N + perm[j]] = w[md->OQ + i * N + j];
        if (metric == 2) {
            for (i64 i = 0; i < N; ++i) /* Z = C^T G^T */
                for (i64 r = 0; r < mrows; ++r) {
                    double acc = 0.0;
                    for (i64 k = 0; k < N; ++k) acc += w[md->OC + k * N + i] * ps[OY + k * mrows + r];
                    ps[OZ + i * mrows + r] = acc;
                }
            lu_solve_flat(ps, 0, N, OZ, mrows, N, mrows); /* Z = Q^-1 C^T G^T */
            for (i64 i = 0; i < N; ++i) /* Y = C Z */
                for (i64 r = 0; r < mrows; ++r) {
                    double acc = 0.0;
                    for (i64 k = 0; k < N; ++k) acc += w[md->OC + i * N + k] * ps[OZ + k * mrows + r];
                    ps[OY + i * mrows + r] = acc;
                }
        } else {
            lu_solve_flat(ps, 0, N, OY, mrows, N, mrows); /* Y = Q^-1 G^T */
        }
    }
    for (i64 a = 0; a < mrows; ++a) {
        for (i64 b = 0; b < mrows; ++b) {
            double acc = 0.0;
            for (i64 i = 0; i < N; ++i) acc += ps[OG + a * N + i] * ps[OY + i * mrows + b];
            ps[OS + a * mrows + b] = acc;
        }
        ps[OZR + a] = ps[OR_ + a];
    }
    double rc = lu_solve_flat(ps, OS, mrows, OZR, 1, mrows, 1);
    for (i64 i = 0; i < N; ++i) {
        double acc = 0.0;
        for (i64 a = 0; a < mrows; ++a) acc += ps[OY + i * mrows + a] * ps[OZR + a];
        ps[OD + i] = acc;
    }
    return rc;
}

/* Post-step correction of positions, then speeds (geometric elimination).
 * (P) psi(q) = 0: q <- q - W^-1 Psi_q^T (Psi_q W^-1 Psi_q^T)^-1 psi, up to pos_iters Newton steps,
 *     the Jacobian updated each step (newton) or frozen at the uncorrected point;
 * (V) [phi; psi'](q, u) = 0 at the corrected q: u <- u - W^-1 J^T (J W^-1 J^T)^-1 [phi; psi'],
 *     Newton in u (one step is exact for constraints linear in u; up to 3 for nonlinear ones);
 * (E) optionally u <- lambda u with lambda^2 = (E0 - E(q,0)) / (E(q,u) - E(q,0)), restoring the
 *     initial energy.
 * Returns 0, or 1 when a correction matrix was singular. */
static i64 project_paper(const nmk_model *md, double t, double *x, const double *p, double *w, double *ps,
                         const i64 *proj, double E0, double *viol, const i64 *perm) {
    const i64 weight = proj[0], pos_iters = proj[1], newton = proj[2], energy_fix = proj[3];
    const i64 N = md->N, M = md->M, MNH = md->MNH, MH = md->MH, OD = md->PS_OD, OG = md->PS_OG;
    const double tol = 1e-15;
    if (MH > 0) {
        for (i64 it = 0; it < pos_iters; ++it) {
            md->positions(t, x, p, w);
            double big = 0.0;
            for (i64 a = 0; a < MH; ++a) big = nmk_max(big, fabs(w[md->OPSI + a]));
            if (big <= tol) break;
            if (newton || it == 0)
                for (i64 a = 0; a < MH; ++a)
                    for (i64 j = 0; j < N; ++j) ps[OG + a * N + j] = w[md->OPSQ + a * N + j];
            for (i64 a = 0; a < MH; ++a) ps[OG + MH * N + a] = w[md->OPSI + a];
            if (weight == 1) md->terms(t, x, p, w);
            if (weighted_correction(md, w, ps, MH, 2 * weight, perm) == 0.0) return 1;
            for (i64 i = 0; i < N; ++i) x[i] -= ps[OD + i];
        }
    }
    if (M > 0) {
        for (i64 it = 0; it < 3; ++it) {
            md->terms(t, x, p, w);
            double big = 0.0;
            for (i64 a = 0; a < MNH; ++a) big = nmk_max(big, fabs(w[md->OPHIN + a]));
            for (i64 a = 0; a < MH; ++a) big = nmk_max(big, fabs(w[md->OPSID + a]));
            if (big <= tol) break;
            for (i64 a = 0; a < M; ++a) /* J = d[phi; psi']/du in model column order */
                for (i64 j = 0; j < N; ++j) ps[OG + a * N + perm[j]] = w[md->OJ + a * N + j];
            for (i64 a = 0; a < MNH; ++a) ps[OG + M * N + a] = w[md->OPHIN + a];
            for (i64 a = 0; a < MH; ++a) ps[OG + M * N + MNH + a] = w[md->OPSID + a];
            if (weighted_correction(md, w, ps, M, weight, perm) == 0.0) return 1;
            for (i64 i = 0; i < N; ++i) x[N + i] -= ps[OD + i];
        }
    }
    if (energy_fix) {
        for (i64 i = 0; i < N; ++i) {
            ps[OD + i] = x[N + i];
            x[N + i] = 0.0;
        }
        double V0 = md->diagnostics(t, x, p, viol);
        for (i64 i = 0; i < N; ++i) x[N + i] = ps[OD + i];
        double Kin = md->diagnostics(t, x, p, viol) - V0;
        if (Kin > 0.0 && E0 > V0) {
            double lam = sqrt((E0 - V0) / Kin);
            for (i64 i = 0; i < N; ++i) x[N + i] *= lam;
        }
    }
    return 0;
}

/* Post-step correction of positions, then speeds: 0, or 1 when a correction matrix was singular.
 * Kernels with the rank-robust solve use its pseudo-inverse (project_robust; 2: the motion left
 * the constraints). */
static i64 project(const nmk_model *md, double t, double *x, const double *p, double *w, double *ps,
                   const i64 *proj, double E0, double *viol, const i64 *perm) {
    if (robust_in_use(md, w)) return project_robust(md, t, x, p, w, proj, E0, viol);
    return project_paper(md, t, x, p, w, ps, proj, E0, viol, perm);
}
