"""The compiled loops' constants, defined once: status codes, the ``stats`` layout, step control.

Plain literals in a plain module: every generated kernel imports them (numba compiles them in
as constants), and the Python side — the loop drivers, the run result — imports the same
names.  Changing a value changes every kernel's cache key (:mod:`nmkane_core.kernel.codegen`
hashes this file), so no stale compiled code can use an old one.
"""

# status codes returned by the loops
STATUS_OK = 0
STATUS_J2_SINGULAR = 1  # J2 ill-conditioned: rcond ≤ rcond_min
STATUS_T_SINGULAR = 2  # T ill-conditioned: rcond ≤ rcond_min
STATUS_DIVERGED = 3  # the state (or a diagnostic) stopped being finite
STATUS_FAILED = 4  # step size underflow (adaptive); Python drivers: any other failure
STATUS_BUDGET = 5  # the step budget of this call is used up (adaptive): call again
STATUS_PROJECTION_FAILED = 6  # a projection's correction matrix was singular

# stats = [E0, max|ΔE|, last ΔE, min rcond J2, min rcond T, max|viol_i| for each violation]
STATS_E0 = 0
STATS_MAX_DRIFT = 1
STATS_FINAL_DRIFT = 2
STATS_RCOND_J2 = 3
STATS_RCOND_T = 4
STATS_VIOL = 5  # first of the NV running maxima of |violation|

# adaptive step control: h ← h · clamp(STEP_SAFETY · err^(−1/(q+1)), STEP_FAC_MIN, STEP_FAC_MAX)
STEP_SAFETY = 0.9
STEP_FAC_MIN = 0.2  # the most a step shrinks at once (also after a non-finite error)
STEP_FAC_MAX = 5.0  # the most a step grows at once (also after a zero error)
STEP_LAST_REL = 1e-12  # a remainder below this fraction of t_final joins the current step

#: every name above, for the generated kernels' import line
NAMES = tuple(k for k in tuple(globals()) if k.startswith(("STATUS_", "STATS_", "STEP_")))
