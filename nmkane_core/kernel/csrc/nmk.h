/* nmkane's generic compiled core: the declarations every part of it shares.
 *
 * The core is compiled once (kernel/core.py: `cc -O2 -ffp-contract=off`, no fast-math) as one
 * translation unit, core.c, which includes the parts below; every function but the exported
 * entry points (core.c) is static.  The model is a run-time record, `nmk_model` (generated into
 * nmk_gen.h from kernel/interface.py's tables: its sizes, the work arrays' offsets, its
 * permutation and sparsity, and pointers to its straight-line functions), so no loop is compiled
 * per model.  Each part is the C form of the algorithm documented in docs/how-it-works.md; the
 * arithmetic is written in the order of the numpy reference (nmkane_core/symbolic), with no
 * contraction into fused multiply-adds, so every x86-64 machine gives the same bits.
 *
 * Conventions: `md` is the model; `w` the right-hand side's flat work array (offsets md->O*);
 * `K` the stage derivatives, S rows of 2N; matrices are row-major and contiguous; Γ is MNH×MNH,
 * Γ1 and Γ2 MH×MH.  Sizes are int64 (`i64`).
 */
#ifndef NMK_H
#define NMK_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef int64_t i64;

/* the model's straight-line functions (kernel/native.py prints them) */
typedef void (*nmk_fill)(double t, const double *x, const double *p, double *w);
typedef double (*nmk_diag)(double t, const double *x, const double *p, double *viol);

#include "nmk_gen.h" /* nmk_model, nmk_fixed_args, nmk_adaptive_args, STATUS_*, STATS_*, LOG_*, STEP_* */

/* the rank-robust solve's settings and state, at w[md->OSV + SV_*] */
#define SV_MODE 0 /* asked for: 0 the paper's solve, 1 rank-robust, 2 auto */
#define SV_RANK_TOL 1
#define SV_MAX_RANK 2
#define SV_CONSISTENCY_TOL 3
#define SV_RCOND_ROBUST 4
#define SV_RCOND_MIN 5
#define SV_USED 6     /* what the last evaluation used: 0 the paper's solve (w[OORD]), 1 robust, -1 none yet */
#define SV_CHANGED 7  /* 1.0: the last evaluation changed the solve or the partition */
#define SV_STATUS 8   /* 0 ok, 1 Q not positive definite, 2 J u' = c inconsistent */
#define SV_RANK 9     /* rank found by the last robust solve */
#define SV_RESIDUAL 10 /* relative residual of the equations it dropped */
#define SV_PIVOT 11   /* its smallest kept pivot */
#define SV_ESTIMATE 12 /* the J2 estimate of the partition left (or taken) */
#define SV_FORCES 13  /* 1.0: the robust solve has put F_c and lambda into w (with OFLAG) */
#define SV_LEAVE 14   /* kinetic-energy share of the last projection's speed correction */
#define SV_STAB 15    /* the Baumgarte terms' share of the kinetic energy (per step: x h^2) */
#define SV_FADE 16    /* 1.0: the Baumgarte terms of vanishing rows fade */
#define SV_NEAR 17    /* 1.0: an evaluation since the loop reset it was near a singular position */

/* Whether a work array's evaluations go through the rank-robust machinery (robust.c, the
 * robust projection): in kernels with it, unless the paper's solve is asked for on a declared,
 * non-redundant partition (DECLARED) — that is the paper's own path (rhs_paper, forces_paper,
 * project_paper: its bits and its condition estimate). */
static inline int robust_in_use(const nmk_model *md, const double *w) {
    return md->ROBUST && !(md->DECLARED && w[md->OSV + SV_MODE] == 0.0);
}

/* The right-hand side's own functions: pasted into their caller in the specialised build (its
 * sizes constant, so the small loops unroll), called in the generic one. */
#ifdef NMK_SPECIAL
#define NMK_HOT __attribute__((always_inline)) inline
#else
#define NMK_HOT
#endif

/* matrices larger than this are treated as banded by lu_solve_flat (paper.c) */
#define BAND_MIN 8

/* Python's max/min of two floats (the first unless the second is strictly larger/smaller):
 * the same choice on NaN as the reference code */
static inline double nmk_max(double a, double b) { return b > a ? b : a; }
static inline double nmk_min(double a, double b) { return b < a ? b : a; }
static inline i64 nmk_imin(i64 a, i64 b) { return b < a ? b : a; }

/* the solve log: rows of [t, kind, value, rank, entries...] */
typedef struct {
    double *a;
    i64 rows, cols;
} nmk_log;

/* ---- paper.c: the paper's solve */
static NMK_HOT double lu_solve_flat(double *w, i64 oa, i64 lda, i64 ob, i64 ldb, i64 n, i64 k);
static NMK_HOT void rhs_paper(const nmk_model *md, double t, const double *x, const double *p, const double *G,
                      const double *G1, const double *G2, double *K, i64 row, double *w);
static NMK_HOT void reduced_solve(const nmk_model *md, double *w, double *K, i64 row);
static void forces_paper(const nmk_model *md, double *w, const double *K, i64 krow);

/* ---- kinematics.c: the kinematics' conditioning (models whose C varies) */
static double kinematic_estimate(const nmk_model *md, double t, const double *x, const double *p, double *w);

/* ---- loops.c: the right-hand side and the integrator loops */
static void init_workspace(const nmk_model *md, double *w);
static NMK_HOT void rhs_ws(const nmk_model *md, double t, const double *x, const double *p, const double *G,
                   const double *G1, const double *G2, double *K, i64 row, double *w);
static NMK_HOT void keep_for_forces(const nmk_model *md, double *w);
static i64 robust_outcome(const nmk_model *md, double t, double h, double *w, double *stats, i64 *order,
                          nmk_log *solve_log, int start);
static int finite_work(const nmk_model *md, const double *w);
static double record(const nmk_model *md, double t, const double *x, const double *p, double *viol,
                     double *stats, i64 nv);
static void forces(const nmk_model *md, double *w, const double *K, i64 krow);
static void store_forces(const nmk_model *md, const double *w, i64 row, double *out_F, double *out_L);

/* ---- projection.c: the post-step projections */
static i64 project(const nmk_model *md, double t, double *x, const double *p, double *w, double *ps,
                   const i64 *proj, double E0, double *viol, const i64 *perm);

/* ---- robust.c: the rank-robust solve */
static void solve_defaults(const nmk_model *md, double *w);
static void solve_setup(const nmk_model *md, double *w, i64 solve, double rank_tol, i64 max_rank,
                        double consistency_tol, double rcond_robust, double rcond_min, const i64 *order,
                        int projected);
static void log_solve(const nmk_model *md, double t, double *w, double *stats, i64 *order, nmk_log *solve_log);
static void constraint_rhs(const nmk_model *md, double *w, const double *G, const double *G1, const double *G2,
                           i64 m);
static i64 paper_ordered(const nmk_model *md, double *w, double *K, i64 row, i64 oord, i64 n, i64 m);
static void reduced_ordered(const nmk_model *md, double *w, double *K, i64 row, i64 oord, i64 n, i64 m);
static i64 repick(const nmk_model *md, double *w, i64 n, i64 m);
static void robust_rhs(const nmk_model *md, double *w, double *K, i64 row, i64 n, i64 m);
static void robust_stab(const nmk_model *md, double *w, i64 n, i64 m, i64 rank);
static void stab_share(const nmk_model *md, const double *x, double *w, int paper);
static void rhs_robust(const nmk_model *md, double t, const double *x, const double *p, const double *G,
                       const double *G1, const double *G2, double *K, i64 row, double *w);
static void forces_robust(const nmk_model *md, double *w, const double *K, i64 krow);

/* ---- robust_linalg.c: dense linear algebra with run-time sizes */
static i64 chol(double *w, i64 oa, i64 ol, i64 n);
static void fwd(double *w, i64 ol, i64 n, i64 ob, i64 k);
static void bwd_t(double *w, i64 ol, i64 n, i64 ob);
static i64 qr_min_norm(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, double tol, i64 max_rank);
static i64 scale_columns(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, double tol);
static i64 pivoted_qr(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, i64 kept, double tol, i64 max_rank);
static void reflect(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, i64 k, i64 kept, double nk);
static double solve_r11_t(const nmk_model *md, double *w, i64 ok, i64 m, i64 rank);
static double dropped_residual(const nmk_model *md, double *w, i64 ok, i64 m, i64 rank, i64 kept);
static void apply_reflectors(const nmk_model *md, double *w, i64 ok, i64 n, i64 m, i64 rank);

/* ---- robust_projection.c: the robust solve's projections and tangent space */
static void model_q(const nmk_model *md, double *w, i64 n);
static i64 correction(const nmk_model *md, double *w, i64 n, i64 mrows, i64 og, int weighted, int with_c, i64 cap);
static void speed_rows(const nmk_model *md, double *w, i64 n, i64 m);
static i64 project_robust(const nmk_model *md, double t, double *x, const double *p, double *w, const i64 *proj,
                          double E0, double *viol);
static void tangent(const nmk_model *md, double t, double *x, const double *p, double *w, const i64 *proj);

#endif
