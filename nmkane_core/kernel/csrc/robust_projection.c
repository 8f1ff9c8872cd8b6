/* nmkane's compiled core, part 4c (the C form of kernel/source/robust_projection.py): the
 * rank-robust solve's post-step projections (the smallest correction in the projection's metric
 * on the independent rows) and the adaptive steps' error estimate on the tangent space.  Included
 * by core.c after nmk.h. */

/* ------------------------------------------------------------------ projections and the tangent space */

/* Q in the model's speed order at OQM (the projections work in the model's order). */
static void model_q(const nmk_model *md, double *w, i64 n)
{
    for (i64 i = 0; i < n; i++)
        for (i64 j = 0; j < n; j++)
            w[md->OQM + md->PERM[i] * n + md->PERM[j]] = w[md->OQ + i * md->N + j];
}

/* δ = B z with z the smallest solution of (G B)z = e on the independent rows — the smallest
 * correction in the metric W = (B Bᵀ)⁻¹ with G δ = e (the robust pseudo-inverse of the
 * projections): B = I, or L⁻ᵀ with L at OLL (W = Q), or C L⁻ᵀ (W = C⁻ᵀQC⁻¹, `with_c`).
 * G (mrows×n, model order) at `og`, e at OEE; δ at OZZ. */
static i64 correction(const nmk_model *md, double *w, i64 n, i64 mrows, i64 og, int weighted, int with_c, i64 cap)
{
    for (i64 i = 0; i < n; i++) { /* K = Bᵀ Gᵀ */
        for (i64 a = 0; a < mrows; a++) {
            double acc;
            if (with_c) {
                acc = 0.0;
                for (i64 k = 0; k < n; k++)
                    acc += w[md->OC + k * n + i] * w[og + a * n + k];
            } else {
                acc = w[og + a * n + i];
            }
            w[md->OKK + i * mrows + a] = acc;
        }
    }
    if (weighted)
        fwd(w, md->OLL, n, md->OKK, mrows);
    i64 rank = qr_min_norm(md, w, md->OKK, n, mrows, w[md->OSV + SV_RANK_TOL], cap);
    if (weighted)
        bwd_t(w, md->OLL, n, md->OZZ);
    if (with_c) {
        for (i64 i = 0; i < n; i++)
            w[md->OAH + i] = w[md->OZZ + i];
        for (i64 i = 0; i < n; i++) {
            double acc = 0.0;
            for (i64 k = 0; k < n; k++)
                acc += w[md->OC + i * n + k] * w[md->OAH + k];
            w[md->OZZ + i] = acc;
        }
    }
    return rank;
}

/* J = ∂[φ; ψ̇]/∂u in the model's speed order at OJE (`terms` has run). */
static void speed_rows(const nmk_model *md, double *w, i64 n, i64 m)
{
    for (i64 a = 0; a < m; a++)
        for (i64 j = 0; j < n; j++)
            w[md->OJE + a * n + md->PERM[j]] = w[md->OJ + a * md->N + j];
}

/* `project` with the robust pseudo-inverse (redundant equations and singular positions
 * need nothing else): positions by Newton steps δq = −W⁻¹ψ_qᵀ(ψ_q W⁻¹ψ_qᵀ)⁺ψ, speeds by
 * δu = −Q⁻¹Jᵀ(J Q⁻¹Jᵀ)⁺[φ; ψ̇] (`proj[0]`: 1 the mass metric, 0 the identity), each capped at
 * the model's rank.  Returns 0; 1 when Q is not positive definite; 2 when the first speed
 * correction carries more than ROBUST_LEAVE_KE of the kinetic energy (the motion left the
 * constraints: w[OSV + SV_LEAVE] holds the share). */
static i64 project_robust(const nmk_model *md, double t, double *x, const double *p, double *w, const i64 *proj,
                          double E0, double *viol)
{
    i64 weight = proj[0], pos_iters = proj[1], newton = proj[2], energy_fix = proj[3];
    i64 n = md->N, m = md->M, mh = md->MH;
    i64 cap = (i64)w[md->OSV + SV_MAX_RANK];
    int with_c = weight == 1 && !md->C_IS_I;
    double tol = 1e-15;
    for (i64 it = 0; it < (md->MH > 0 ? pos_iters : 0); it++) {
        md->positions(t, x, p, w);
        double big = 0.0;
        for (i64 a = 0; a < md->MH; a++)
            big = nmk_max(big, fabs(w[md->OPSI + a]));
        if (big <= tol)
            break;
        if (weight == 1) {
            md->terms(t, x, p, w);
            model_q(md, w, n);
            if (chol(w, md->OQM, md->OLL, n) == 0)
                return 1;
        }
        i64 og = md->OPSQ;
        if (newton == 0) { /* simplified Newton: the Jacobian of the uncorrected point */
            og = md->OJE;
            if (it == 0)
                for (i64 k = 0; k < md->MH * md->N; k++)
                    w[md->OJE + k] = w[md->OPSQ + k];
        }
        for (i64 a = 0; a < md->MH; a++)
            w[md->OEE + a] = -w[md->OPSI + a];
        correction(md, w, n, mh, og, weight == 1, with_c, md->MNH == 0 ? cap : mh);
        for (i64 i = 0; i < md->N; i++)
            x[i] += w[md->OZZ + i];
    }
    double leave = 0.0;
    for (i64 it = 0; it < 3; it++) {
        md->terms(t, x, p, w);
        double big = 0.0;
        for (i64 a = 0; a < md->MNH; a++)
            big = nmk_max(big, fabs(w[md->OPHIN + a]));
        for (i64 a = 0; a < md->MH; a++)
            big = nmk_max(big, fabs(w[md->OPSID + a]));
        if (big <= tol)
            break;
        model_q(md, w, n);
        i64 pd = chol(w, md->OQM, md->OLL, n);
        if (weight == 1 && pd == 0)
            return 1;
        speed_rows(md, w, n, m);
        for (i64 a = 0; a < md->MNH; a++)
            w[md->OEE + a] = -w[md->OPHIN + a];
        for (i64 a = 0; a < md->MH; a++)
            w[md->OEE + md->MNH + a] = -w[md->OPSID + a];
        correction(md, w, n, m, md->OJE, weight == 1, 0, cap);
        if (it == 0) { /* the correction's share of the kinetic energy: δuᵀQδu / uᵀQu */
            double dke = 0.0, ke = 0.0;
            for (i64 i = 0; i < md->N; i++) {
                for (i64 j = 0; j < md->N; j++) {
                    double q = w[md->OQM + i * md->N + j];
                    dke += w[md->OZZ + i] * q * w[md->OZZ + j];
                    ke += x[md->N + i] * q * x[md->N + j];
                }
            }
            if (dke > 0.0)
                leave = ke > 0.0 ? dke / ke : INFINITY;
        }
        for (i64 i = 0; i < md->N; i++)
            x[md->N + i] += w[md->OZZ + i];
    }
    w[md->OSV + SV_LEAVE] = leave;
    if (leave > ROBUST_LEAVE_KE)
        return 2;
    if (energy_fix) {
        for (i64 i = 0; i < md->N; i++) {
            w[md->OAH + i] = x[md->N + i];
            x[md->N + i] = 0.0;
        }
        double V0 = md->diagnostics(t, x, p, viol);
        for (i64 i = 0; i < md->N; i++)
            x[md->N + i] = w[md->OAH + i];
        double kin = md->diagnostics(t, x, p, viol) - V0;
        if (kin > 0.0 && E0 > V0) {
            double lam = sqrt((E0 - V0) / kin);
            for (i64 i = 0; i < md->N; i++)
                x[md->N + i] *= lam;
        }
    }
    return 0;
}

/* The error estimate at w[ODX] (2N, model order) without its components along the
 * constraint normals, in the projection's metric (ReferenceKernel.tangent): the part the
 * post-step projection does not remove.  Near a singular position the estimate is dominated
 * by those components: an error control that sees them shrinks the step onto the singular
 * point. */
static void tangent(const nmk_model *md, double t, double *x, const double *p, double *w, const i64 *proj)
{
    i64 weight = proj[0];
    i64 n = md->N, m = md->M, mh = md->MH;
    i64 cap = (i64)w[md->OSV + SV_MAX_RANK];
    md->terms(t, x, p, w);
    model_q(md, w, n);
    int weighted = weight == 1 && chol(w, md->OQM, md->OLL, n) == 1;
    if (md->MH > 0) {
        md->positions(t, x, p, w);
        for (i64 a = 0; a < md->MH; a++) { /* e = −ψ_q δq */
            double acc = 0.0;
            for (i64 j = 0; j < md->N; j++)
                acc += w[md->OPSQ + a * md->N + j] * w[md->ODX + j];
            w[md->OEE + a] = -acc;
        }
        correction(md, w, n, mh, md->OPSQ, weighted, weighted && !md->C_IS_I, md->MNH == 0 ? cap : mh);
        for (i64 i = 0; i < md->N; i++)
            w[md->ODX + i] += w[md->OZZ + i];
    }
    speed_rows(md, w, n, m);
    for (i64 a = 0; a < md->M; a++) { /* e = −J δu */
        double acc = 0.0;
        for (i64 j = 0; j < md->N; j++)
            acc += w[md->OJE + a * md->N + j] * w[md->ODX + md->N + j];
        w[md->OEE + a] = -acc;
    }
    correction(md, w, n, m, md->OJE, weighted, 0, cap);
    for (i64 i = 0; i < md->N; i++)
        w[md->ODX + md->N + i] += w[md->OZZ + i];
}
