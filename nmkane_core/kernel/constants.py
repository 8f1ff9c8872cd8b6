"""The compiled loops' constants, defined once: status codes, the ``stats`` layout, step control.

Plain literals in a plain module: the compiled core's header is generated from them
(:func:`nmkane_core.kernel.core.header`: ``#define`` lines), and the Python side — the loop
drivers, the run result — imports the same names.  Changing a value changes the core's cache key
and every kernel's (:mod:`nmkane_core.kernel.loader` hashes this file), so no stale compiled code
can use an old one.
"""

# status codes returned by the loops
STATUS_OK = 0
STATUS_J2_SINGULAR = 1  # J2 ill-conditioned: rcond ≤ rcond_min
STATUS_T_SINGULAR = 2  # T ill-conditioned: rcond ≤ rcond_min
STATUS_DIVERGED = 3  # the state (or a diagnostic) stopped being finite
STATUS_FAILED = 4  # step size underflow (adaptive); Python drivers: any other failure
STATUS_BUDGET = 5  # the step budget of this call is used up (adaptive): call again
STATUS_PROJECTION_FAILED = 6  # a projection's correction matrix was singular
# the rank-robust solve (kernels generated with it: kernel.codegen ROBUST) — each ends a run "singular"
STATUS_INCONSISTENT = 7  # J u̇ = c has no solution: the dependent equations miss (solve log: rank, names, residual)
STATUS_Q_SINGULAR = 8  # Q is not positive definite (its Cholesky factorization failed)
STATUS_LEFT_CONSTRAINTS = 9  # a step's constraint correction (the projection's, or the Baumgarte terms') carried
# more than ROBUST_LEAVE_KE of the kinetic energy: the motion left its branch near a singular position
STATUS_DRIFTED = 10  # the energy drift or a constraint violation passed the run's bound (drift_limit,
# violation_limit): the state that passed it is not kept
# the kinematics q̇ = C u + D of a model whose C varies (kernel.codegen KN > 0) — each ends a run "singular"
STATUS_C_SINGULAR = 11  # C's estimate (the volume of its normalized rows) ≤ rcond_min: the coordinates degenerate
STATUS_C_UNRESOLVED = 12  # a fixed step near such a position changed C's estimate by more than KIN_STEP_CHANGE
# of itself: the step does not resolve the coordinates' fast swing there (an adaptive step is shrunk instead)

# stats = [E0, max|ΔE|, last ΔE, min rcond J2, min rcond T, the robust solve's counters, min estimate of C,
#          max|viol_i| for each violation]
STATS_E0 = 0
STATS_MAX_DRIFT = 1
STATS_FINAL_DRIFT = 2
STATS_RCOND_J2 = 3
STATS_RCOND_T = 4
STATS_ROBUST_EVALS = 5  # evaluations that used the rank-robust solve
STATS_MIN_PIVOT = 6  # smallest kept pivot |R_kk| of those (the constraint normals' conditioning)
STATS_MIN_RANK = 7  # smallest rank of J they found
STATS_SOLVE_LOG = 8  # solve-log records written by this call (the driver reads and resets it)
STATS_MAX_LEAVE = 9  # largest kinetic-energy share of a projection's speed correction
STATS_MAX_STAB = 10  # largest kinetic-energy share of the velocity change the Baumgarte terms make in a step
STATS_NEAR_PROJECTIONS = 11  # steps projected because they came near a singular position (near_proj)
STATS_RCOND_C = 12  # smallest estimate of the kinematics' C (1 where C is constant: not computed)
STATS_VIOL = 13  # first of the NV running maxima of |violation|

# the solve log (the loops' ``solve_log`` argument): one row per change of the constraint solve,
# [t, kind, value, rank, entries...] with entries the column order (kind paper) or 1.0 for each
# dropped equation (kinds robust, inconsistent); the last row is kept for an inconsistent stop
LOG_PAPER = 0  # the paper's solve with a partition (value: its J2 estimate; entries: the column order)
LOG_ROBUST = 1  # the rank-robust solve (value: smallest kept pivot; entries: the dropped equations)
LOG_INCONSISTENT = 2  # the robust solve found J u̇ = c inconsistent (value: relative residual)
LOG_HEAD = 4  # t, kind, value, rank

# the rank-robust solve's run-time decisions (docs/closed-loops.md)
ROBUST_LEAVE_KE = 1e-6  # a step's constraint correction above this share of T: the run left the constraints
ROBUST_NEAR_SINGULAR = 1e-2  # ... judged for the Baumgarte terms only near a singular position: a row of J
# shorter than this share of the longest (the rows that vanish there), or the rank-robust solve in use

# the kinematics' conditioning (csrc/kinematics.c): where C's estimate is below KIN_NEAR, a step may change it
# by at most KIN_STEP_CHANGE of its smallest value over the step's stages (near a singular chart the estimate
# falls like the distance to it, and the coordinates' rates grow like its inverse: a step longer than this
# misses their swing, and the run goes on with a wrong configuration)
KIN_NEAR = 0.1
KIN_STEP_CHANGE = 0.1
# ... and it is made at a step's start only where it is above KIN_WATCH there: to reach a singular chart within
# the step from such a state, the step would have to turn the chart by about half a radian (ZYX angles: |cos θ|)
KIN_WATCH = 0.5

# adaptive step control: h ← h · clamp(STEP_SAFETY · err^(−1/(q+1)), STEP_FAC_MIN, STEP_FAC_MAX)
STEP_SAFETY = 0.9
STEP_FAC_MIN = 0.2  # the most a step shrinks at once (also after a non-finite error)
STEP_FAC_MAX = 5.0  # the most a step grows at once (also after a zero error)
STEP_LAST_REL = 1e-12  # a remainder below this fraction of t_final joins the current step

#: every name above, for the generated kernels' import line
NAMES = tuple(k for k in tuple(globals()) if k.startswith(("STATUS_", "STATS_", "STEP_", "LOG_", "ROBUST_", "KIN_")))
