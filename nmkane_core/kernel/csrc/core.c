/* nmkane's compiled core: one translation unit (kernel/core.py compiles this file once).
 * The parts are included here, each the C form of one part of the algorithm; the entry points
 * called from Python (kernel/cmodel.py) are at the end, in api.c. */
#include "nmk.h"

#include "paper.c"
#include "kinematics.c"
#include "loops.c"
#include "projection.c"
#include "robust.c"
#include "robust_linalg.c"
#include "robust_projection.c"
#include "api.c"
