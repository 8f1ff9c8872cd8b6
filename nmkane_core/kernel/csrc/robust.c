/* nmkane's compiled core, part 4: the rank-robust constraint solve (docs/closed-loops.md §2, §7);
 * the C form of kernel/source/robust.py.
 *
 * Where J2 of the current partition is well-conditioned the paper's T u' = V̂ is solved as in
 * rhs_ws (block elimination on A1's identity block), with the partition a run-time column order
 * of J (w[OORD]).  Its condition is measured scale-free: the smallest LU pivot of J2 after each
 * row of J = [J1 J2] is divided by its largest entry (0 where a whole row vanishes).  Below the
 * threshold solve = 2 ("auto") re-picks the partition by Gaussian elimination with complete
 * pivoting on the equilibrated J (Wehage & Haug 1982) and, where no partition is
 * well-conditioned (J has lost rank, or the equations are redundant), solves Gauss's principle
 * in the mass metric: Q = L Lᵀ, K = L⁻¹Jᵀ with its columns equilibrated, Householder QR with
 * column pivoting stopped at the rank (at most max_rank steps), u' = L⁻ᵀ(â + Z_r y).
 *
 * The solve's settings and state live in the work array at w[OSV + SV_*]; the loops copy their
 * arguments there (solve_setup) and read back the partition and what changed (log_solve).
 */

/* The settings a work array starts with (make_workspace): auto, the codegen's defaults, the
 * kernel's own column order, nothing used yet. */
static void solve_defaults(const nmk_model *md, double *w) {
    w[md->OSV + SV_MODE] = 2.0;
    w[md->OSV + SV_RANK_TOL] = md->RANK_TOL_DEFAULT;
    w[md->OSV + SV_MAX_RANK] = (double)md->MAX_RANK_DEFAULT;
    w[md->OSV + SV_CONSISTENCY_TOL] = md->CONSISTENCY_TOL_DEFAULT;
    w[md->OSV + SV_RCOND_ROBUST] = md->RCOND_ROBUST_DEFAULT;
    w[md->OSV + SV_RCOND_MIN] = 0.0;
    w[md->OSV + SV_USED] = -1.0;
    w[md->OSV + SV_FADE] = 0.0;
    for (i64 i = 0; i < md->N; i++)
        w[md->OORD + i] = (double)i;
}

/* A loop's solve arguments into the work array; order = the column order [u_I, u_D] of J, then
 * the solve in use (SV_USED); projected: the loop projects each step onto the constraints, so
 * that the Baumgarte terms of vanishing rows may fade (SV_FADE). */
static void solve_setup(const nmk_model *md, double *w, i64 solve, double rank_tol, i64 max_rank,
                        double consistency_tol, double rcond_robust, double rcond_min, const i64 *order,
                        int projected) {
    w[md->OSV + SV_MODE] = (double)solve;
    w[md->OSV + SV_FADE] = (projected && solve != 0) ? 1.0 : 0.0;
    w[md->OSV + SV_RANK_TOL] = rank_tol;
    w[md->OSV + SV_MAX_RANK] = (double)max_rank;
    w[md->OSV + SV_CONSISTENCY_TOL] = consistency_tol;
    w[md->OSV + SV_RCOND_ROBUST] = rcond_robust;
    w[md->OSV + SV_RCOND_MIN] = rcond_min;
    for (i64 i = 0; i < md->N; i++)
        w[md->OORD + i] = (double)order[i];
    w[md->OSV + SV_USED] = (double)order[md->N];
}

/* After an evaluation that changed the solve (or found the constraints inconsistent): the
 * partition and the solve in use back into order, a record into solve_log (the last row is kept
 * for an inconsistent stop), its count in stats[STATS_SOLVE_LOG]. */
static void log_solve(const nmk_model *md, double t, double *w, double *stats, i64 *order, nmk_log *solve_log) {
    for (i64 i = 0; i < md->N; i++)
        order[i] = (i64)w[md->OORD + i];
    order[md->N] = (i64)w[md->OSV + SV_USED];
    i64 cap = solve_log->rows;
    i64 k = (i64)stats[STATS_SOLVE_LOG];
    stats[STATS_SOLVE_LOG] = (double)(k + 1);
    int bad = w[md->OSV + SV_STATUS] == 2.0;
    if (cap == 0 || (k >= cap && !bad))
        return;
    i64 r = nmk_imin(k, cap - 1);
    solve_log->a[r * solve_log->cols] = t;
    i64 width = solve_log->cols - LOG_HEAD;
    for (i64 j = 0; j < width; j++)
        solve_log->a[r * solve_log->cols + LOG_HEAD + j] = 0.0;
    if (w[md->OSV + SV_USED] == 0.0) {
        solve_log->a[r * solve_log->cols + 1] = LOG_PAPER;
        solve_log->a[r * solve_log->cols + 2] = w[md->ORC];
        solve_log->a[r * solve_log->cols + 3] = (double)md->M;
        for (i64 j = 0; j < nmk_imin(md->N, width); j++)
            solve_log->a[r * solve_log->cols + LOG_HEAD + j] = w[md->OORD + j];
    } else {
        solve_log->a[r * solve_log->cols + 1] = bad ? LOG_INCONSISTENT : LOG_ROBUST;
        solve_log->a[r * solve_log->cols + 2] = bad ? w[md->OSV + SV_RESIDUAL] : w[md->OSV + SV_ESTIMATE];
        solve_log->a[r * solve_log->cols + 3] = w[md->OSV + SV_RANK];
        for (i64 j = 0; j < nmk_imin(md->M, width); j++)
            solve_log->a[r * solve_log->cols + LOG_HEAD + j] = w[md->ODROP + j];
    }
}

/* ------------------------------------------------------------------ the right-hand side */

/* c = −b + s, s = [Γφ; Γ1ψ' + Γ2ψ] (105), (112) at OCV (s at OSS), and the row norms |J_i|∞ at
 * ORN; with SV_FADE, s faded on the rows that vanish (BAUMGARTE_FADE). */
static void constraint_rhs(const nmk_model *md, double *w, const double *G, const double *G1, const double *G2,
                           i64 m) {
    for (i64 i = 0; i < m; i++) {
        double s = 0.0;
        if (i < md->MNH) {
            for (i64 k = 0; k < md->MNH; k++)
                s += G[i * md->MNH + k] * w[md->OPHIN + k];
        } else {
            i64 ih = i - md->MNH;
            for (i64 k = 0; k < md->MH; k++)
                s += G1[ih * md->MH + k] * w[md->OPSID + k] + G2[ih * md->MH + k] * w[md->OPSI + k];
        }
        w[md->OCV + i] = -w[md->OB + i] + s;
        w[md->OSS + i] = s;
        double big = 0.0;
        /* the row's structural nonzeros (the rest are exact zeros) */
        for (i64 kk = md->JPTR[i]; kk < md->JPTR[i + 1]; kk++) {
            double a = fabs(w[md->OJ + i * md->N + md->JIDX[kk]]);
            if (a > big || !isfinite(a))
                big = a;
        }
        w[md->ORN + i] = big;
    }
    /* with a projection (SV_FADE) the Baumgarte terms of rows whose gradient vanishes fade out
     * (BAUMGARTE_FADE): near a singular position they would ask accelerations of order Γψ/|J_i|,
     * and the projection keeps the positions on the constraints anyway */
    if (w[md->OSV + SV_FADE] == 0.0)
        return;
    double longest = 0.0;
    for (i64 i = 0; i < m; i++)
        longest = nmk_max(longest, w[md->ORN + i]);
    for (i64 i = 0; i < m; i++) {
        double share = longest > 0.0 ? w[md->ORN + i] / longest : 1.0;
        if (share < md->BAUMGARTE_FADE) {
            double f = (share / md->BAUMGARTE_FADE) * (share / md->BAUMGARTE_FADE);
            w[md->OSS + i] *= f;
            w[md->OCV + i] = -w[md->OB + i] + w[md->OSS + i];
        }
    }
}

/* The paper's solve for the partition whose column order is at oord: J2 X = R with
 * R = [−J1 | c | s], rows equilibrated, then T u' = V̂ by block elimination (as rhs_ws; the
 * Baumgarte terms' part of u' beside it, at OUS).  w[ORC] receives J2's estimate (smallest pivot
 * of the equilibrated LU; 0 where a row of J vanishes); "auto" below its threshold returns 0
 * without solving, else returns 1. */
static i64 paper_ordered(const nmk_model *md, double *w, double *K, i64 row, i64 oord, i64 n, i64 m) {
    i64 pi = n - m;
    i64 ld = pi + 2;
    double big = 0.0;
    for (i64 i = 0; i < m; i++)
        big = nmk_max(big, w[md->ORN + i]);
    int vanishing = !(big > 0.0);
    for (i64 i = 0; i < m; i++) {
        if (!(w[md->ORN + i] > w[md->OSV + SV_RANK_TOL] * big))
            vanishing = 1;
    }
    for (i64 i = 0; i < n; i++) /* OPOS: each column's position in this order (reduced_ordered uses it too) */
        w[md->OPOS + (i64)w[oord + i]] = (double)i;
    double rc = 0.0;
    if (!vanishing && isfinite(big)) {
        for (i64 i = 0; i < m; i++) { /* J2 into OJE, −J1 into R: zeros, then J's structural nonzeros in place */
            double inv = 1.0 / w[md->ORN + i];
            for (i64 j = 0; j < m; j++)
                w[md->OJE + i * m + j] = 0.0;
            for (i64 j = 0; j < pi; j++)
                w[md->OR + i * ld + j] = 0.0;
            for (i64 kk = md->JPTR[i]; kk < md->JPTR[i + 1]; kk++) {
                i64 j = md->JIDX[kk];
                i64 pos = (i64)w[md->OPOS + j];
                if (pos >= pi)
                    w[md->OJE + i * m + pos - pi] = w[md->OJ + i * md->N + j] * inv;
                else
                    w[md->OR + i * ld + pos] = -w[md->OJ + i * md->N + j] * inv;
            }
            w[md->OR + i * ld + pi] = w[md->OCV + i] * inv;
            w[md->OR + i * ld + pi + 1] = w[md->OSS + i] * inv;
        }
        if (lu_solve_flat(w, md->OJE, m, md->OR, ld, m, ld) > 0.0) {
            rc = 1.0;
            for (i64 i = 0; i < m; i++)
                rc = nmk_min(rc, fabs(w[md->OJE + i * m + i]));
        }
    }
    w[md->ORC] = rc;
    double thr = w[md->OSV + SV_RCOND_MIN];
    if (w[md->OSV + SV_MODE] == 2.0) {
        thr = nmk_max(thr, w[md->OSV + SV_RCOND_ROBUST]);
        if (!(rc > thr))
            return 0;
    }
    if (!(rc > 0.0)) { /* the paper's solve asked for, J2 singular: no u' (the loops stop on the estimate) */
        w[md->ORC + 1] = 0.0;
        return 1;
    }
    if (w[md->OFLAG] != 0.0) { /* J2 as it is, for the multipliers (forces_robust) */
        for (i64 i = 0; i < m; i++)
            for (i64 j = 0; j < m; j++)
                w[md->OJ2C + i * m + j] = w[md->OJ + i * md->N + (i64)w[oord + pi + j]];
    }
    reduced_ordered(md, w, K, row, oord, n, m);
    return 1;
}

/* reduced_solve for a run-time column order: (A2 Q A2ᵀ) u'_I = A2 (P − Q_{·D} B̂),
 * u'_D = A u'_I + B̂ (106), (111), indices through oord; beside it (the second column of each
 * right-hand side) the Baumgarte terms' part u'_s (B̂ → J2⁻¹s, P → 0) into OUS. */
static void reduced_ordered(const nmk_model *md, double *w, double *K, i64 row, i64 oord, i64 n, i64 m) {
    i64 pi = n - m;
    i64 ld = pi + 2;
    /* W = Q A2ᵀ with A2ᵀ = [I; A], and y = P − Q_{·D} B̂ (and −Q_{·D} J2⁻¹s), over Q's structural
     * nonzeros (QPTR, QIDX), each column's position from OPOS (paper_ordered) */
    for (i64 i = 0; i < n; i++) {
        i64 oi = (i64)w[oord + i];
        for (i64 r = 0; r < pi; r++)
            w[md->OW + i * pi + r] = 0.0;
        double acc = w[md->OP + oi];
        double acc_s = 0.0;
        for (i64 kk = md->QPTR[oi]; kk < md->QPTR[oi + 1]; kk++) {
            i64 j = md->QIDX[kk];
            double q = w[md->OQ + oi * md->N + j];
            i64 pos = (i64)w[md->OPOS + j];
            if (pos < pi) {
                w[md->OW + i * pi + pos] += q;
            } else {
                i64 k = pos - pi;
                for (i64 r = 0; r < pi; r++)
                    w[md->OW + i * pi + r] += q * w[md->OR + k * ld + r];
                acc -= q * w[md->OR + k * ld + pi];
                acc_s -= q * w[md->OR + k * ld + pi + 1];
            }
        }
        w[md->OY + 2 * i] = acc;
        w[md->OY + 2 * i + 1] = acc_s;
    }
    for (i64 r = 0; r < pi; r++) { /* A2 Q A2ᵀ */
        for (i64 c = 0; c < pi; c++) {
            double acc = w[md->OW + r * pi + c];
            for (i64 k = 0; k < m; k++)
                acc += w[md->OR + k * ld + r] * w[md->OW + (pi + k) * pi + c];
            w[md->OMR + r * pi + c] = acc;
        }
    }
    for (i64 r = 0; r < pi; r++) {
        for (i64 c = 0; c < 2; c++) {
            double acc = w[md->OY + 2 * r + c];
            for (i64 k = 0; k < m; k++)
                acc += w[md->OR + k * ld + r] * w[md->OY + 2 * (pi + k) + c];
            w[md->OUI + 2 * r + c] = acc;
        }
    }
    i64 two = 2;
    w[md->ORC + 1] = lu_solve_flat(w, md->OMR, pi, md->OUI, two, pi, two);
    for (i64 r = 0; r < pi; r++) {
        i64 j = (i64)w[oord + r];
        K[row * 2 * md->N + md->N + md->PERM[j]] = w[md->OUI + 2 * r];
        w[md->OUS + j] = w[md->OUI + 2 * r + 1];
    }
    for (i64 k = 0; k < m; k++) {
        double acc = w[md->OR + k * ld + pi];
        double acc_s = w[md->OR + k * ld + pi + 1];
        for (i64 r = 0; r < pi; r++) {
            acc += w[md->OR + k * ld + r] * w[md->OUI + 2 * r];
            acc_s += w[md->OR + k * ld + r] * w[md->OUI + 2 * r + 1];
        }
        i64 j = (i64)w[oord + pi + k];
        K[row * 2 * md->N + md->N + md->PERM[j]] = acc;
        w[md->OUS + j] = acc_s;
    }
}

/* Wehage & Haug's partition: Gaussian elimination with complete pivoting on J with its rows
 * equilibrated (a row shorter than the rank threshold times the longest is left out); the pivot
 * columns are u_D.  The new column order (u_I ascending, then u_D ascending) goes to OORD2;
 * returns the rank found (partition_by_pivoting). */
static i64 repick(const nmk_model *md, double *w, i64 n, i64 m) {
    double tol = w[md->OSV + SV_RANK_TOL];
    double big = 0.0;
    for (i64 i = 0; i < m; i++)
        big = nmk_max(big, w[md->ORN + i]);
    for (i64 i = 0; i < m; i++) {
        int active = big > 0.0 && w[md->ORN + i] > tol * big;
        w[md->OROWS + i] = active ? 1.0 : 0.0;
        double inv = active ? 1.0 / w[md->ORN + i] : 0.0;
        for (i64 j = 0; j < n; j++)
            w[md->OJE + i * n + j] = w[md->OJ + i * md->N + j] * inv;
    }
    for (i64 j = 0; j < n; j++)
        w[md->ODX + j] = 1.0; /* column still free */
    i64 rank = 0;
    for (i64 step = 0; step < nmk_imin(m, n); step++) {
        double best = 0.0;
        i64 ib = -1;
        i64 jb = -1;
        for (i64 i = 0; i < m; i++) {
            if (w[md->OROWS + i] == 1.0) {
                for (i64 j = 0; j < n; j++) {
                    if (w[md->ODX + j] == 1.0) {
                        double a = fabs(w[md->OJE + i * n + j]);
                        if (a > best) {
                            best = a;
                            ib = i;
                            jb = j;
                        }
                    }
                }
            }
        }
        if (ib < 0 || !(best > tol))
            break;
        double piv = w[md->OJE + ib * n + jb];
        for (i64 i = 0; i < m; i++) {
            if (w[md->OROWS + i] == 1.0 && i != ib) {
                double f = w[md->OJE + i * n + jb] / piv;
                if (f != 0.0) {
                    for (i64 j = 0; j < n; j++) {
                        if (w[md->ODX + j] == 1.0)
                            w[md->OJE + i * n + j] -= f * w[md->OJE + ib * n + j];
                    }
                }
            }
        }
        w[md->OROWS + ib] = 0.0;
        w[md->ODX + jb] = 0.0;
        rank += 1;
    }
    i64 pos = 0;
    for (i64 j = 0; j < n; j++) { /* u_I first, then u_D, each ascending */
        if (w[md->ODX + j] == 1.0) {
            w[md->OORD2 + pos] = (double)j;
            pos += 1;
        }
    }
    for (i64 j = 0; j < n; j++) {
        if (w[md->ODX + j] == 0.0) {
            w[md->OORD2 + pos] = (double)j;
            pos += 1;
        }
    }
    return rank;
}

/* Gauss's principle in the mass metric (robust_solve): u' into K[row]; with OFLAG set, F_c and
 * lambda (the basic solution: 0 on the dropped equations) into OFC, OLAM. */
static void robust_rhs(const nmk_model *md, double *w, double *K, i64 row, i64 n, i64 m) {
    if (chol(w, md->OQ, md->OLL, n) == 0) {
        w[md->OSV + SV_STATUS] = 1.0;
        w[md->ORC + 1] = 0.0;
        for (i64 i = 0; i < md->N; i++)
            K[row * 2 * md->N + md->N + i] = 0.0;
        return;
    }
    for (i64 i = 0; i < n; i++) { /* â = L⁻¹P, K = L⁻¹Jᵀ */
        w[md->OAH + i] = w[md->OP + i];
        for (i64 col = 0; col < m; col++)
            w[md->OKK + i * m + col] = w[md->OJ + col * md->N + i];
    }
    i64 one = 1;
    fwd(w, md->OLL, n, md->OAH, one);
    fwd(w, md->OLL, n, md->OKK, m);
    double scale = 1e-300;
    for (i64 col = 0; col < m; col++) { /* e = c − Kᵀâ */
        double ka = 0.0;
        for (i64 i = 0; i < n; i++)
            ka += w[md->OKK + i * m + col] * w[md->OAH + i];
        w[md->OEE + col] = w[md->OCV + col] - ka;
        scale = nmk_max(nmk_max(scale, fabs(w[md->OCV + col])), fabs(ka));
    }
    i64 rank = qr_min_norm(md, w, md->OKK, n, m, w[md->OSV + SV_RANK_TOL], (i64)w[md->OSV + SV_MAX_RANK]);
    w[md->OSV + SV_RANK] = (double)rank;
    w[md->OSV + SV_RESIDUAL] = w[md->OSV + SV_RESIDUAL] / scale;
    if (!(w[md->OSV + SV_RESIDUAL] <= w[md->OSV + SV_CONSISTENCY_TOL]))
        w[md->OSV + SV_STATUS] = 2.0;
    robust_stab(md, w, n, m, rank);
    for (i64 i = 0; i < n; i++) /* u' = L⁻ᵀ(â + z) */
        w[md->OZZ + i] += w[md->OAH + i];
    bwd_t(w, md->OLL, n, md->OZZ);
    for (i64 i = 0; i < n; i++)
        K[row * 2 * md->N + md->N + md->PERM[i]] = w[md->OZZ + i];
    if (w[md->OFLAG] != 0.0) {
        for (i64 k = rank - 1; k > -1; k--) { /* R11 lambda~ = y, in place */
            double s = w[md->OYY + k];
            for (i64 j = k + 1; j < rank; j++)
                s -= w[md->OKK + k * m + (i64)w[md->OPIV + j]] * w[md->OYY + j];
            w[md->OYY + k] = s / w[md->OKK + k * m + (i64)w[md->OPIV + k]];
        }
        for (i64 col = 0; col < m; col++)
            w[md->OLAM + col] = 0.0;
        for (i64 k = 0; k < rank; k++) {
            i64 col = (i64)w[md->OPIV + k];
            w[md->OLAM + col] = w[md->OYY + k] / w[md->ONRM + col];
        }
        w[md->OSV + SV_FORCES] = 1.0;
    }
}

/* |u'_s|²_Q of the robust solve into w[OSV + SV_STAB] (to be divided by uᵀQu): u'_s the part the
 * Baumgarte terms s make, = L⁻ᵀ z_s with z_s = Z_r R11⁻ᵀ (D s)[piv] (so |u'_s|_Q = |z_s|); the
 * QR of qr_min_norm is in OKK. */
static void robust_stab(const nmk_model *md, double *w, i64 n, i64 m, i64 rank) {
    for (i64 k = 0; k < rank; k++) { /* R11ᵀ y_s = D s, in place at OUS */
        i64 col = (i64)w[md->OPIV + k];
        double acc = w[md->OSS + col] / w[md->ONRM + col];
        for (i64 i = 0; i < k; i++)
            acc -= w[md->OKK + i * m + col] * w[md->OUS + i];
        w[md->OUS + k] = acc / w[md->OKK + k * m + col];
    }
    for (i64 i = rank; i < n; i++)
        w[md->OUS + i] = 0.0;
    for (i64 k = rank - 1; k > -1; k--) { /* z_s = Z_r [y_s; 0] */
        i64 col = (i64)w[md->OPIV + k];
        double d = w[md->OUS + k];
        for (i64 i = k + 1; i < n; i++)
            d += w[md->OKK + i * m + col] * w[md->OUS + i];
        d *= w[md->OBETA + k];
        w[md->OUS + k] -= d;
        for (i64 i = k + 1; i < n; i++)
            w[md->OUS + i] -= d * w[md->OKK + i * m + col];
    }
    double acc = 0.0;
    for (i64 i = 0; i < n; i++)
        acc += w[md->OUS + i] * w[md->OUS + i];
    w[md->OSV + SV_STAB] = acc;
}

/* u'_sᵀQu'_s / uᵀQu (0 at rest) into w[OSV + SV_STAB]: the Baumgarte terms' share of the kinetic
 * energy, per h² of a step (u'_s at OUS for the paper's solve; |u'_s|²_Q already there for the
 * robust one). */
static void stab_share(const nmk_model *md, const double *x, double *w, int paper) {
    double ke = 0.0;
    double ds = 0.0;
    for (i64 i = 0; i < md->N; i++) {
        double ui = x[md->N + md->PERM[i]];
        double acc_u = 0.0;
        double acc_s = 0.0;
        for (i64 kk = md->QPTR[i]; kk < md->QPTR[i + 1]; kk++) { /* Q's structural nonzeros */
            i64 j = md->QIDX[kk];
            double q = w[md->OQ + i * md->N + j];
            acc_u += q * x[md->N + md->PERM[j]];
            if (paper)
                acc_s += q * w[md->OUS + j];
        }
        ke += ui * acc_u;
        if (paper)
            ds += w[md->OUS + i] * acc_s;
    }
    if (!paper)
        ds = w[md->OSV + SV_STAB];
    w[md->OSV + SV_STAB] = ke > 0.0 ? ds / ke : 0.0;
}

/* Whether an evaluation is near a singular position, where the Baumgarte terms' share of the
 * kinetic energy is judged (ROBUST_LEAVE_KE): the robust solve was used (used = 1), or a row of J
 * is shorter than ROBUST_NEAR_SINGULAR of the longest (|J_i|∞ at ORN, from constraint_rhs).  Away
 * from one — a start from rest, say — the share is no sign of a motion leaving its branch. */
static int near_singular(const nmk_model *md, const double *w, i64 m, double used) {
    if (used == 1.0)
        return 1;
    double longest = 0.0, shortest = INFINITY;
    for (i64 i = 0; i < m; i++) {
        longest = nmk_max(longest, w[md->ORN + i]);
        shortest = nmk_min(shortest, w[md->ORN + i]);
    }
    return longest > 0.0 && shortest < ROBUST_NEAR_SINGULAR * longest;
}

/* rhs_ws of a kernel with the rank-robust solve: ẋ = [C u + D; u'] into K[row] by the paper's
 * solve with the current partition, another partition, or the robust solve (w[OSV]). */
static void rhs_robust(const nmk_model *md, double t, const double *x, const double *p, const double *G,
                       const double *G1, const double *G2, double *K, i64 row, double *w) {
    md->terms(t, x, p, w);
    for (i64 i = 0; i < md->N; i++)
        K[row * 2 * md->N + i] = w[md->OQD + i];
    i64 n = md->N;
    i64 m = md->M;
    double prev = w[md->OSV + SV_USED];
    w[md->OSV + SV_CHANGED] = 0.0;
    w[md->OSV + SV_STATUS] = 0.0;
    if (w[md->OFLAG] != 0.0) { /* this evaluation's forces are wanted (later ones leave SV_FORCES) */
        keep_for_forces(md, w);
        w[md->OSV + SV_FORCES] = 0.0;
    }
    w[md->ORC] = 1.0;
    w[md->ORC + 1] = 1.0;
    constraint_rhs(md, w, G, G1, G2, m);
    for (i64 i = 0; i < m; i++) {
        if (!isfinite(w[md->ORN + i]) || !isfinite(w[md->OCV + i])) {
            /* the constraints' expressions are not defined here (the end of a square root's branch,
             * a zero denominator): no partition or solve helps; u' is NaN, the estimates 0, and
             * the loops end the run diverged at the last good state, as with the paper's solve */
            for (i64 j = 0; j < n; j++)
                K[row * 2 * n + n + j] = NAN;
            w[md->ORC] = 0.0;
            w[md->ORC + 1] = 0.0;
            w[md->OSV + SV_STAB] = 0.0;
            return;
        }
    }
    double used = 1.0;
    if (w[md->OSV + SV_MODE] != 1.0 && w[md->OSV + SV_MAX_RANK] == (double)md->M && md->M <= md->N) {
        used = 0.0;
        if (paper_ordered(md, w, K, row, md->OORD, n, m) == 0) { /* auto: J2 ill-conditioned here */
            used = 1.0;
            w[md->OSV + SV_ESTIMATE] = w[md->ORC];
            if (repick(md, w, n, m) == m && paper_ordered(md, w, K, row, md->OORD2, n, m) == 1) {
                used = 0.0;
                for (i64 i = 0; i < md->N; i++) {
                    if (w[md->OORD + i] != w[md->OORD2 + i])
                        w[md->OSV + SV_CHANGED] = 1.0;
                    w[md->OORD + i] = w[md->OORD2 + i];
                }
            }
        }
    }
    if (used == 1.0) {
        w[md->ORC] = 1.0; /* no J2 in this solve */
        robust_rhs(md, w, K, row, n, m);
    }
    int near = near_singular(md, w, m, used);
    if (near)
        w[md->OSV + SV_NEAR] = 1.0;
    if (w[md->ORC + 1] > 0.0 && w[md->OSV + SV_STATUS] == 0.0 && near)
        stab_share(md, x, w, used == 0.0);
    else
        w[md->OSV + SV_STAB] = 0.0;
    if (prev >= 0.0 && used != prev)
        w[md->OSV + SV_CHANGED] = 1.0;
    w[md->OSV + SV_USED] = used;
    if (w[md->OFLAG] != 0.0) { /* the partition its J2 copy was taken in (a later stage may change it) */
        for (i64 i = 0; i < md->N; i++)
            w[md->OORDC + i] = w[md->OORD + i];
    }
}

/* forces of a kernel with the rank-robust solve: F_c = Q u' − P (J's column order) and lambda —
 * from the robust solve, or from J2ᵀ lambda = (F_c)_D of the partition in use. */
static void forces_robust(const nmk_model *md, double *w, const double *K, i64 krow) {
    for (i64 r = 0; r < md->N; r++) {
        double acc = -w[md->OPC + r];
        for (i64 c = 0; c < md->N; c++)
            acc += w[md->OQC + r * md->N + c] * K[krow * 2 * md->N + md->N + md->PERM[c]];
        w[md->OFC + r] = acc;
    }
    if (w[md->OSV + SV_FORCES] == 0.0 && md->M > 0 && md->M <= md->N) {
        i64 pi = md->N - md->M;
        for (i64 i = 0; i < md->M; i++) { /* J2ᵀ, in place */
            for (i64 j = i + 1; j < md->M; j++) {
                double a = w[md->OJ2C + i * md->M + j];
                w[md->OJ2C + i * md->M + j] = w[md->OJ2C + j * md->M + i];
                w[md->OJ2C + j * md->M + i] = a;
            }
        }
        for (i64 a = 0; a < md->M; a++)
            w[md->OLAM + a] = w[md->OFC + (i64)w[md->OORDC + pi + a]];
        i64 one = 1, m = md->M;
        lu_solve_flat(w, md->OJ2C, m, md->OLAM, one, m, one);
    }
}
