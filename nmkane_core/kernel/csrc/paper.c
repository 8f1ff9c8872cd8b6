/* The paper's numeric solve T u' = V^ (block elimination on A1's identity block, (20),
 * (42)-(46)), its LU with the rcond estimate, and the multipliers from J2^T lambda = (F_c)_D. */

/* Solve A X = B in place in the flat work array w (LU with partial pivoting).  A is n x n at
 * offset oa with row stride lda; B is n x k at ob with row stride ldb and receives X.  Returns
 * min|pivot|/max|pivot| (0 when singular): the reciprocal-condition estimate the kernels compare
 * with rcond_min.  Matrices larger than BAND_MIN are treated as banded: each row's elimination
 * and back substitution stop at its last nonzero (a chain's J2). */
static NMK_HOT double lu_solve_flat(double *w, i64 oa, i64 lda, i64 ob, i64 ldb, i64 n, i64 k) {
    double pmax = 0.0, pmin = 1e308;
    int singular = 0;
    for (i64 c = 0; c < n; ++c) {
        i64 piv = c;
        double big = fabs(w[oa + c * lda + c]);
        for (i64 i = c + 1; i < n; ++i) {
            double v = fabs(w[oa + i * lda + c]);
            if (v > big) {
                big = v;
                piv = i;
            }
        }
        if (!(big > 0.0)) { /* zero or NaN pivot */
            singular = 1;
            break;
        }
        if (piv != c) {
            for (i64 j = 0; j < n; ++j) {
                double tmp = w[oa + c * lda + j];
                w[oa + c * lda + j] = w[oa + piv * lda + j];
                w[oa + piv * lda + j] = tmp;
            }
            for (i64 j = 0; j < k; ++j) {
                double tmp = w[ob + c * ldb + j];
                w[ob + c * ldb + j] = w[ob + piv * ldb + j];
                w[ob + piv * ldb + j] = tmp;
            }
        }
        if (big > pmax) pmax = big;
        if (big < pmin) pmin = big;
        i64 hi = n; /* one past the pivot row's last nonzero (BAND_MIN) */
        if (n > BAND_MIN)
            while (hi > c + 1 && w[oa + c * lda + hi - 1] == 0.0) --hi;
        double inv = 1.0 / w[oa + c * lda + c];
        for (i64 i = c + 1; i < n; ++i) {
            double f = w[oa + i * lda + c] * inv;
            if (f != 0.0) {
                for (i64 j = c + 1; j < hi; ++j) w[oa + i * lda + j] -= f * w[oa + c * lda + j];
                for (i64 j = 0; j < k; ++j) w[ob + i * ldb + j] -= f * w[ob + c * ldb + j];
            }
        }
    }
    double rc = 1.0;
    if (singular) {
        rc = 0.0;
    } else if (n > 0) {
        for (i64 c = n - 1; c >= 0; --c) {
            i64 hi = n; /* U's row c ends there: the rest are zeros */
            if (n > BAND_MIN)
                while (hi > c + 1 && w[oa + c * lda + hi - 1] == 0.0) --hi;
            double inv = 1.0 / w[oa + c * lda + c];
            for (i64 j = 0; j < k; ++j) {
                double acc = w[ob + c * ldb + j];
                for (i64 l = c + 1; l < hi; ++l) acc -= w[oa + c * lda + l] * w[ob + l * ldb + j];
                w[ob + c * ldb + j] = acc * inv;
            }
        }
        rc = pmin / pmax;
    }
    return rc;
}

/* The paper's solve with the declared partition (rhs_ws of kernels without the robust solve). */
static NMK_HOT void rhs_paper(const nmk_model *md, double t, const double *x, const double *p, const double *G,
                      const double *G1, const double *G2, double *K, i64 row, double *w) {
    const i64 N = md->N, M = md->M, PI = md->PI, MNH = md->MNH, MH = md->MH;
    double *Kr = K + row * 2 * N;
    md->terms(t, x, p, w);
    for (i64 i = 0; i < N; ++i) Kr[i] = w[md->OQD + i];
    w[md->ORC] = 1.0;
    if (w[md->OFLAG] != 0.0) { /* this evaluation's forces are wanted: J2 before its LU, Q and P */
        keep_for_forces(md, w);
        for (i64 i = 0; i < M; ++i)
            for (i64 j = 0; j < M; ++j) w[md->OJ2C + i * M + j] = w[md->OJ + i * N + PI + j];
    }
    if (M > 0) {
        const i64 OR = md->OR, OJ = md->OJ, ld = PI + 1;
        double share = 1.0;
        /* R = [-J1 | -b + s], s = [G phi; G1 psi' + G2 psi]   (105), (112) */
        for (i64 i = 0; i < M; ++i) {
            for (i64 j = 0; j < PI; ++j) w[OR + i * ld + j] = -w[OJ + i * N + j];
            double s = 0.0;
            if (i < MNH) {
                for (i64 k = 0; k < MNH; ++k) s += G[i * MNH + k] * w[md->OPHIN + k];
            } else {
                i64 ih = i - MNH;
                for (i64 k = 0; k < MH; ++k) s += G1[ih * MH + k] * w[md->OPSID + k] + G2[ih * MH + k] * w[md->OPSI + k];
            }
            w[OR + i * ld + PI] = -w[md->OB + i] + s;
        }
        if (md->SCALE_ROWS || md->NORM_ROWS) {
            /* rows of J (and R: same solution) scaled for the condition estimate: degree k > 1 in u
             * by 1/max(1, |u|inf)^(k-1); not polynomial (ROWDEG 0) by 1/max_j |J_ij|, and the
             * estimate is at most the row's share on u_D, max_j |J2_ij| / max_j |J_ij| */
            double un = 1.0;
            for (i64 j = 0; j < N; ++j) un = nmk_max(un, fabs(x[N + j]));
            double inv = 1.0 / un;
            for (i64 i = 0; i < M; ++i) {
                double sc = 1.0;
                if (md->ROWDEG[i] > 1) {
                    sc = inv;
                    for (i64 r = 0; r < md->ROWDEG[i] - 2; ++r) sc *= inv;
                } else if (md->ROWDEG[i] == 0) {
                    double big = 0.0, big_d = 0.0;
                    for (i64 j = 0; j < N; ++j) {
                        double a = fabs(w[OJ + i * N + j]);
                        if (a > big) big = a;
                        if (j >= PI && a > big_d) big_d = a;
                    }
                    if (big > 0.0 && big < INFINITY) { /* a zero row is left to the LU (zero pivot), a */
                        sc = 1.0 / big;                  /* non-finite one to the loops' finiteness checks */
                        share = nmk_min(share, big_d * sc);
                    }
                }
                if (sc != 1.0) {
                    for (i64 j = 0; j < N; ++j) w[OJ + i * N + j] *= sc;
                    for (i64 j = 0; j < PI + 1; ++j) w[OR + i * ld + j] *= sc;
                }
            }
        }
        /* J2 X = R  ->  X = [A | B^]   (20), (108), (113) */
        w[md->ORC] = lu_solve_flat(w, OJ + PI, N, OR, PI + 1, M, PI + 1);
        if (md->NORM_ROWS && share < w[md->ORC]) w[md->ORC] = share;
    }
    if (w[md->ORC] == 0.0) /* J2 singular: no u' (the loops stop on the rcond) */
        w[md->ORC + 1] = 0.0;
    else
        reduced_solve(md, w, K, row);
}

/* The rest of rhs_ws once [A | B^] is known: T u' = V^ with T = [A1; A2 Q], V^ = [B^; A2 P]
 * (22), (40), (44), (110), solved by block elimination on the identity block of A1 = [-A I]:
 * u'_D = A u'_I + B^ (106), then (A2 Q A2^T) u'_I = A2 (P - Q [0; B^]) with A2^T = [I; A]:
 * exact, allocation-free, and p x p instead of n x n.  (With no constraints this is Q u' = P.) */
static NMK_HOT void reduced_solve(const nmk_model *md, double *w, double *K, i64 row) {
    const i64 N = md->N, M = md->M, PI = md->PI, ld = PI + 1;
    const i64 OQ = md->OQ, OR = md->OR, OW = md->OW, OY = md->OY, OUI = md->OUI;
    double *Kr = K + row * 2 * N;
    for (i64 i = 0; i < N; ++i) /* W = Q A2^T  (n x p) */
        for (i64 r = 0; r < PI; ++r) {
            double acc = w[OQ + i * N + r];
            for (i64 k = 0; k < M; ++k) acc += w[OQ + i * N + PI + k] * w[OR + k * ld + r];
            w[OW + i * PI + r] = acc;
        }
    for (i64 r = 0; r < PI; ++r) /* Mr = A2 W  (p x p) */
        for (i64 c = 0; c < PI; ++c) {
            double acc = w[OW + r * PI + c];
            for (i64 k = 0; k < M; ++k) acc += w[OR + k * ld + r] * w[OW + (PI + k) * PI + c];
            w[md->OMR + r * PI + c] = acc;
        }
    for (i64 i = 0; i < N; ++i) { /* y = P - Q_{.D} B^ */
        double acc = w[md->OP + i];
        for (i64 k = 0; k < M; ++k) acc -= w[OQ + i * N + PI + k] * w[OR + k * ld + PI];
        w[OY + i] = acc;
    }
    for (i64 r = 0; r < PI; ++r) { /* rhs = A2 y */
        double acc = w[OY + r];
        for (i64 k = 0; k < M; ++k) acc += w[OR + k * ld + r] * w[OY + PI + k];
        w[OUI + r] = acc;
    }
    /* (111): u'_I from the reduced system; its pivot ratio is the T condition estimate */
    w[md->ORC + 1] = lu_solve_flat(w, md->OMR, PI, OUI, 1, PI, 1);
    for (i64 r = 0; r < PI; ++r) Kr[N + md->PERM[r]] = w[OUI + r];
    for (i64 k = 0; k < M; ++k) {
        double acc = w[OR + k * ld + PI];
        for (i64 r = 0; r < PI; ++r) acc += w[OR + k * ld + r] * w[OUI + r];
        Kr[N + md->PERM[PI + k]] = acc;
    }
}

/* forces() of the paper's solve with the declared partition: F_c = Q u' - P, then
 * J2^T lambda = (F_c)_D. */
static void forces_paper(const nmk_model *md, double *w, const double *K, i64 krow) {
    const i64 N = md->N, M = md->M, PI = md->PI;
    const double *Kr = K + krow * 2 * N;
    for (i64 r = 0; r < N; ++r) {
        double acc = -w[md->OPC + r];
        for (i64 c = 0; c < N; ++c) acc += w[md->OQC + r * N + c] * Kr[N + md->PERM[c]];
        w[md->OFC + r] = acc;
    }
    if (M > 0) {
        const i64 O = md->OJ2C;
        for (i64 i = 0; i < M; ++i) /* J2^T, in place */
            for (i64 j = i + 1; j < M; ++j) {
                double a = w[O + i * M + j];
                w[O + i * M + j] = w[O + j * M + i];
                w[O + j * M + i] = a;
            }
        for (i64 a = 0; a < M; ++a) w[md->OLAM + a] = w[md->OFC + PI + a];
        lu_solve_flat(w, O, M, md->OLAM, 1, M, 1);
    }
}
