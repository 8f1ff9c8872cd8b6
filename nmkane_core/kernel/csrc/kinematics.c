/* The kinematics' conditioning: for a model whose C in q' = C u + D varies (KN > 0), an estimate of
 * how far C is from singular, monitored beside J2's and T's (docs/how-it-works.md §7): at each
 * step's start, and at every stage of a step that starts below KIN_WATCH (loops.c stages()).  Where C degenerates the coordinates do: Euler angles at gimbal lock, where C has entries
 * like 1/cos(theta) and two of its rows blow up together — q' grows without bound for finite
 * speeds, and a run that steps across it goes on with a wrong configuration.
 *
 * The estimate is the volume spanned by C's rows scaled to unit length, |det C| / prod_i |C_i|_2
 * (Hadamard's ratio, in [0, 1]): 1 where the rows are orthogonal (a quaternion's kinematics, at
 * any state), 0 where C is singular or rows become parallel as they blow up (ZYX angles: exactly
 * |cos(theta)|).  Scaling a row — the unit of a coordinate — does not change it.  It is computed
 * on the block of C that varies (kernel/codegen.py kinematic_block: KN x KN, written at w[OCK] by
 * the model's `kinematics`; the rest of C is a signed permutation, of estimate 1): one LU with
 * partial pivoting of the normalized rows, in place, the product of its pivots. */
static double kinematic_estimate(const nmk_model *md, double t, const double *x, const double *p, double *w) {
    const i64 n = md->KN, O = md->OCK;
    md->kinematics(t, x, p, w);
    for (i64 i = 0; i < n; ++i) { /* each row to unit length (scaled by its largest entry first) */
        double *r = w + O + i * n;
        double big = 0.0;
        for (i64 j = 0; j < n; ++j) big = nmk_max(big, fabs(r[j]));
        if (!(big > 0.0) || !isfinite(big)) /* a zero row: singular; not finite: the loops' finiteness */
            return 0.0;                     /* checks (q' is not finite either) */
        double inv = 1.0 / big, ss = 0.0;
        for (i64 j = 0; j < n; ++j) {
            r[j] *= inv;
            ss += r[j] * r[j];
        }
        inv = 1.0 / sqrt(ss);
        for (i64 j = 0; j < n; ++j) r[j] *= inv;
    }
    double vol = 1.0;
    for (i64 c = 0; c < n; ++c) {
        i64 piv = c;
        double big = fabs(w[O + c * n + c]);
        for (i64 i = c + 1; i < n; ++i) {
            double v = fabs(w[O + i * n + c]);
            if (v > big) {
                big = v;
                piv = i;
            }
        }
        if (!(big > 0.0))
            return 0.0;
        if (piv != c)
            for (i64 j = c; j < n; ++j) {
                double tmp = w[O + c * n + j];
                w[O + c * n + j] = w[O + piv * n + j];
                w[O + piv * n + j] = tmp;
            }
        vol *= big;
        double inv = 1.0 / w[O + c * n + c];
        for (i64 i = c + 1; i < n; ++i) {
            double f = w[O + i * n + c] * inv;
            if (f != 0.0)
                for (i64 j = c + 1; j < n; ++j) w[O + i * n + j] -= f * w[O + c * n + j];
        }
    }
    return nmk_min(vol, 1.0); /* Hadamard: at most 1, up to rounding */
}
