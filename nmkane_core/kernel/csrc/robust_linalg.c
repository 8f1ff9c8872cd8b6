/* nmkane's compiled core, part 4b (the C form of kernel/source/robust_linalg.py): the rank-robust
 * solve's dense linear algebra with run-time sizes (Cholesky of Q, triangular solves, Householder
 * QR with column pivoting stopped at the rank).  Included by core.c after nmk.h. */

/* ------------------------------------------------------------------ dense kernels, run-time sizes */

/* A = L Lᵀ (Cholesky–Banachiewicz) for the n×n A at `oa`, L (n×n, lower) at `ol`;
 * returns 1, or 0 when A is not positive definite. */
static i64 chol(double *w, i64 oa, i64 ol, i64 n)
{
    for (i64 j = 0; j < n; j++) {
        double d = w[oa + j * n + j];
        for (i64 k = 0; k < j; k++)
            d -= w[ol + j * n + k] * w[ol + j * n + k];
        if (!(d > 0.0))
            return 0;
        double ljj = sqrt(d);
        w[ol + j * n + j] = ljj;
        double inv = 1.0 / ljj;
        for (i64 i = j + 1; i < n; i++) {
            double s = w[oa + i * n + j];
            for (i64 k = 0; k < j; k++)
                s -= w[ol + i * n + k] * w[ol + j * n + k];
            w[ol + i * n + j] = s * inv;
        }
        for (i64 i = 0; i < j; i++)
            w[ol + i * n + j] = 0.0;
    }
    return 1;
}

/* L X = B in place, B n×k (row stride k) at `ob`. */
static void fwd(double *w, i64 ol, i64 n, i64 ob, i64 k)
{
    for (i64 i = 0; i < n; i++) {
        double inv = 1.0 / w[ol + i * n + i];
        for (i64 c = 0; c < k; c++) {
            double s = w[ob + i * k + c];
            for (i64 l = 0; l < i; l++)
                s -= w[ol + i * n + l] * w[ob + l * k + c];
            w[ob + i * k + c] = s * inv;
        }
    }
}

/* Lᵀ x = b in place, b (n) at `ob`. */
static void bwd_t(double *w, i64 ol, i64 n, i64 ob)
{
    for (i64 i = n - 1; i > -1; i--) {
        double s = w[ob + i];
        for (i64 l = i + 1; l < n; l++)
            s -= w[ol + l * n + i] * w[ob + l];
        w[ob + i] = s / w[ol + i * n + i];
    }
}

/* The heart of the robust solve, steps 3–5 of docs/closed-loops.md §7: for K (n×m, row
 * stride m) at `ok` and e (m) at OEE, the smallest z with Kᵀz = e on the independent
 * equations, z = Z_r R11⁻ᵀ e[piv] at OZZ.  Columns shorter than `tol` times the longest are
 * dropped, the others scaled to unit length; then Householder QR with column pivoting until the
 * pivot falls to `tol` times the first one or `max_rank` steps.  Leaves the smallest kept pivot
 * at w[OSV + SV_PIVOT] and the largest residual of the dropped equations at
 * w[OSV + SV_RESIDUAL]; returns the rank. */
static i64 qr_min_norm(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, double tol, i64 max_rank)
{
    i64 kept = scale_columns(md, w, ok, n, m, tol);
    i64 rank = pivoted_qr(md, w, ok, n, m, kept, tol, max_rank);
    w[md->OSV + SV_PIVOT] = solve_r11_t(md, w, ok, m, rank);
    w[md->OSV + SV_RESIDUAL] = dropped_residual(md, w, ok, m, rank, kept);
    apply_reflectors(md, w, ok, n, m, rank);
    return rank;
}

/* Column norms at ONRM; columns longer than `tol` times the longest scaled to unit
 * length (with their e) and listed first at OPIV, the vanishing ones after them (ODROP
 * 1.0); returns how many are kept. */
static i64 scale_columns(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, double tol)
{
    double big = 0.0;
    for (i64 col = 0; col < m; col++) {
        double s = 0.0;
        for (i64 i = 0; i < n; i++)
            s += w[ok + i * m + col] * w[ok + i * m + col];
        double nr = sqrt(s);
        w[md->ONRM + col] = nr;
        w[md->ODROP + col] = 1.0;
        if (nr > big)
            big = nr;
    }
    i64 kept = 0;
    for (i64 col = 0; col < m; col++) {
        double nr = w[md->ONRM + col];
        if (big > 0.0 && nr > tol * big) {
            double inv = 1.0 / nr;
            for (i64 i = 0; i < n; i++)
                w[ok + i * m + col] *= inv;
            w[md->OEE + col] *= inv;
            w[md->OPIV + kept] = (double)col;
            w[md->ODROP + col] = 0.0;
            kept += 1;
        }
    }
    i64 pos = kept;
    for (i64 col = 0; col < m; col++) { /* the vanishing ones after the kept ones */
        if (w[md->ODROP + col] == 1.0) {
            w[md->OPIV + pos] = (double)col;
            pos += 1;
        }
    }
    return kept;
}

/* Householder QR with column pivoting of the kept columns, until the pivot falls to
 * `tol` times the first or `max_rank` steps: R and the reflectors in K, β at OBETA;
 * returns the rank. */
static i64 pivoted_qr(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, i64 kept, double tol, i64 max_rank)
{
    i64 rank = 0;
    double first = 0.0;
    i64 steps = nmk_imin(nmk_imin(n, kept), max_rank);
    for (i64 k = 0; k < steps; k++) {
        double best = -1.0;
        i64 jbest = k;
        for (i64 jj = k; jj < kept; jj++) {
            i64 col = (i64)w[md->OPIV + jj];
            double s = 0.0;
            for (i64 i = k; i < n; i++)
                s += w[ok + i * m + col] * w[ok + i * m + col];
            if (s > best) {
                best = s;
                jbest = jj;
            }
        }
        double nk = sqrt(best);
        if (k == 0)
            first = nk;
        if (nk <= tol * first || nk == 0.0)
            break;
        double tmp = w[md->OPIV + k];
        w[md->OPIV + k] = w[md->OPIV + jbest];
        w[md->OPIV + jbest] = tmp;
        reflect(md, w, ok, n, m, k, kept, nk);
        rank = k + 1;
    }
    return rank;
}

/* Step k of the QR: the reflector of pivot column OPIV[k] (norm `nk` below row k),
 * applied to the kept columns after it. */
static void reflect(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, i64 k, i64 kept, double nk)
{
    i64 col = (i64)w[md->OPIV + k];
    double x0 = w[ok + k * m + col];
    double alpha = x0 >= 0.0 ? -nk : nk;
    double v0 = x0 - alpha;
    double inv = 1.0 / v0;
    for (i64 i = k + 1; i < n; i++)
        w[ok + i * m + col] *= inv;
    double beta = -v0 / alpha;
    w[md->OBETA + k] = beta;
    w[ok + k * m + col] = alpha;
    for (i64 jj = k + 1; jj < kept; jj++) {
        i64 c2 = (i64)w[md->OPIV + jj];
        double d = w[ok + k * m + c2];
        for (i64 i = k + 1; i < n; i++)
            d += w[ok + i * m + col] * w[ok + i * m + c2];
        d *= beta;
        w[ok + k * m + c2] -= d;
        for (i64 i = k + 1; i < n; i++)
            w[ok + i * m + c2] -= d * w[ok + i * m + col];
    }
}

/* R11ᵀ y = e[piv[:r]] into OYY; returns the smallest |pivot| (at most 1). */
static double solve_r11_t(const nmk_model *md, double *w, i64 ok, i64 m, i64 rank)
{
    double pmin = 1.0;
    for (i64 k = 0; k < rank; k++) {
        i64 col = (i64)w[md->OPIV + k];
        double s = w[md->OEE + col];
        for (i64 i = 0; i < k; i++)
            s -= w[ok + i * m + col] * w[md->OYY + i];
        double rkk = w[ok + k * m + col];
        w[md->OYY + k] = s / rkk;
        if (fabs(rkk) < pmin)
            pmin = fabs(rkk);
    }
    return pmin;
}

/* ODROP 1.0 for every equation beyond the rank; returns their largest residual, in e's units. */
static double dropped_residual(const nmk_model *md, double *w, i64 ok, i64 m, i64 rank, i64 kept)
{
    double res = 0.0;
    for (i64 jj = rank; jj < m; jj++) {
        i64 col = (i64)w[md->OPIV + jj];
        w[md->ODROP + col] = 1.0;
        double s = w[md->OEE + col];
        if (jj < kept) {
            for (i64 i = 0; i < rank; i++)
                s -= w[ok + i * m + col] * w[md->OYY + i];
            s *= w[md->ONRM + col];
        }
        if (fabs(s) > res || !isfinite(s))
            res = fabs(s);
    }
    return res;
}

/* z = H_0 … H_{r−1} [y; 0] into OZZ. */
static void apply_reflectors(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, i64 rank)
{
    for (i64 i = 0; i < n; i++)
        w[md->OZZ + i] = i < rank ? w[md->OYY + i] : 0.0;
    for (i64 k = rank - 1; k > -1; k--) {
        i64 col = (i64)w[md->OPIV + k];
        double d = w[md->OZZ + k];
        for (i64 i = k + 1; i < n; i++)
            d += w[ok + i * m + col] * w[md->OZZ + i];
        d *= w[md->OBETA + k];
        w[md->OZZ + k] -= d;
        for (i64 i = k + 1; i < n; i++)
            w[md->OZZ + i] -= d * w[ok + i * m + col];
    }
}
