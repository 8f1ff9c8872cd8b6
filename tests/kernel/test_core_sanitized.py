"""The compiled core under AddressSanitizer: every entry point, on models of every kind, with no
read or write outside an array (kernel.core builds the core with ``-fsanitize=address`` when
``NMKANE_CORE_CFLAGS=-fsanitize=address``; the runtime is preloaded into a fresh Python process)."""

import os
import subprocess
import sys

import pytest

from tests._helpers import require_compiler

require_compiler()

pytestmark = pytest.mark.slow

#: runs that reach every entry point of csrc/api.c: both loops, the paper's and the rank-robust
#: solve, both projections, constraint forces, the scipy adapter (rhs_ws, forces_rows, the robust
#: bookkeeping), state completion (state_terms), the initial projection (project_state), the
#: kinematics' estimate of a model whose C varies (rattleback: its ZXY angles)
PROBE = """
from nmkane_core import simulate
cases = [
    {"system": "appell-hamel", "t_final": 0.5, "dt": 0.01},
    {"system": "appell-hamel", "t_final": 0.5, "integrator": "kutta-merson-adaptive", "projection": "yoon"},
    {"system": "appell-hamel", "model": "linear", "t_final": 0.5, "dt": 0.01, "projection": "blajer",
     "projection_weight": "mass", "projection_energy": True},
    {"system": "sliding-particle", "t_final": 0.5, "integrator": "rk45"},
    {"system": "iftomm-a02", "t_final": 0.5, "dt": 0.001, "projection": "yoon", "solve": "robust"},
    {"system": "iftomm-a02", "t_final": 0.5, "integrator": "kutta-merson-adaptive", "projection": "yoon"},
    {"system": "iftomm-a02", "t_final": 0.2, "integrator": "rk45", "solve": "auto"},
    {"system": "whipple-bicycle", "t_final": 0.2, "dt": 0.001, "project_initial": True},
    {"system": "rolling-disk", "t_final": 0.2, "dt": 0.001, "projection": "blajer"},
    {"system": "rattleback", "t_final": 0.2, "dt": 0.001},
    {"system": "rattleback", "t_final": 0.2, "integrator": "rk45"},
]
for c in cases:
    r = simulate(c, progress=False)
    print(c["system"], r.status)
"""


def _asan_runtime() -> str:
    out = subprocess.run(["cc", "-print-file-name=libasan.so"], capture_output=True, text=True)
    path = out.stdout.strip()
    if not (os.path.isabs(path) and os.path.exists(path)):  # gcc prints the bare name when it has none
        if os.environ.get("CI") == "true":
            raise RuntimeError("CI=true but no AddressSanitizer runtime: .ci/run must install gcc (libasan)")
        pytest.skip("no AddressSanitizer runtime (libasan) with this C compiler")
    return path


def test_every_entry_point_of_the_core_runs_clean_under_address_sanitizer():
    env = {
        **os.environ,
        "NMKANE_CORE_CFLAGS": "-fsanitize=address -fno-omit-frame-pointer -g",
        "LD_PRELOAD": _asan_runtime(),
        "ASAN_OPTIONS": "detect_leaks=0:abort_on_error=1:halt_on_error=1",
    }
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, timeout=900)
    assert out.returncode == 0 and "ERROR: AddressSanitizer" not in out.stderr, out.stderr[-4000:]
    statuses = dict(line.split() for line in out.stdout.splitlines())
    assert len(statuses) == 6 and all(s in ("ok", "singular") for s in statuses.values()), out.stdout
