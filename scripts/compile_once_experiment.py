"""Would compiling the generic loops once (for every model) pay?  An experiment, not the product.

Every model's kernel module carries its own copy of the generic code (nmkane_core/kernel/source),
with the model's dimensions and work-array offsets as constants, so numba compiles the loops again
for each model (5-8 s a loop, docs/performance.md).  The alternative: the loops compiled once, the
dimensions read at run time and the model's ``terms`` passed in as a first-class function.  This
script measures both on the paper's Appell–Hamel model (nonlinear, 5 coordinates, 3 constraints):
the paper's solve (nmkane_core/kernel/source/paper.py, ``lu_solve_flat``, ``_rhs_paper`` without
the force records and the row scaling, ``_reduced_solve``) under a plain fixed-step Kutta–Merson
loop, 500 000 steps (the paper's 500 s at Δt = 0.001), in three builds:

- ``per-model``: as the kernels are now (constants, ``terms`` called directly);
- ``once``: dimensions from an int64 array at run time, ``terms`` a ``FunctionType`` argument;
- ``once, direct``: dimensions at run time, ``terms`` called directly (which of the two costs).

Each build runs in a fresh process twice: first on an empty numba cache (compile), then cached.

    .venv/bin/python scripts/compile_once_experiment.py [steps]
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1] / "nmkane_core" / "kernel" / "source" / "paper.py"
LOOPS = SOURCE.with_name("loops.py")
DIMS = ("N", "M", "MNH", "MH", "PI", "OJ", "OB", "OPHIN", "OPSID", "OPSI", "OQ", "OP", "OQD", "OR", "OW", "OMR")
DIMS += ("OY", "OUI", "ORC")
HEAD = 'import math\nimport numpy as np\nfrom numba import njit, types\nFM = {"contract"}\nBAND_MIN = 8\n'
JIT = '@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")\n'
LOOP_HEAD = """def km(t0, h, steps, x, p, G, G1, G2, TA, TC, TB, K, xs, w):
    t = t0
    for s in range(steps):
"""
LOOP_TAIL = """            rhs(t + TC[i] * h, xs, p, G, G1, G2, K, i, w)
            if w[ORC] <= 1e-12 or w[ORC + 1] <= 1e-12:
                return -1
        for j in range(n2):
            acc = 0.0
            for i in range(S):
                acc += TB[i] * K[i, j]
            x[j] += h * acc
        t += h
    return 0
"""
DRIVE = """
import json, sys, time
t0 = time.perf_counter()
import numpy as np
build, steps = sys.argv[1], int(sys.argv[2])
from nmkane_core.integrate.methods import KUTTA_MERSON as KM
TA, TB, TC = KM.A, KM.b, KM.c
x0 = np.array([0.1, 0.2, 0.0, 0.0, -0.3, 1.0, 0.5, 0.2, 0.3, 0.1])
p = np.array([0.5, 0.1, 0.6, 1.0, 2.0, 0.3, 9.81, 0.0])
G, G1, G2 = np.zeros((2, 2)), np.zeros((1, 1)), np.zeros((1, 1))
K, xs, w = np.zeros((5, 10)), np.zeros(10), np.zeros(200)
import importlib
m = importlib.import_module("build_" + build)
if build == "per_model":
    extra = ()
else:
    import model_terms
    extra = (np.array(json.load(open("dims.json")), dtype=np.int64), np.arange(5), model_terms.terms)
t1 = time.perf_counter()
m.km(*extra, 0.0, 0.001, 1, x0.copy(), p, G, G1, G2, TA, TC, TB, K, xs, w)
t2 = time.perf_counter()
x = x0.copy()
status = m.km(*extra, 0.0, 0.001, steps, x, p, G, G1, G2, TA, TC, TB, K, xs, w)
t3 = time.perf_counter()
print(json.dumps({"ready_s": t2 - t0, "run_s": t3 - t2, "status": int(status), "x": x.tolist()}))
"""


def _paper_parts() -> tuple[str, str, str]:
    """lu_solve_flat, _rhs_paper (renamed rhs; no force records, no row scaling), _reduced_solve."""
    src = SOURCE.read_text()

    def function(name: str) -> str:
        start = src.index(f"def {name}(")
        ends = [i for i in (src.find("\n@njit", start), src.find("\n#: ", start)) if i > 0]
        return src[start : min(ends) + 1]

    rhs = function("_rhs_paper").replace("_rhs_paper", "rhs")
    rhs = re.sub(r"    if w\[OFLAG\] != 0\.0:.*?\n(?=    if M > 0:)", "", rhs, flags=re.S)
    rhs = re.sub(r"        if SCALE_ROWS or NORM_ROWS:.*?\n(?=        # J2 X = R)", "", rhs, flags=re.S)
    rhs = re.sub(r"        if NORM_ROWS:\n.*?\n.*?\n", "", rhs)
    rhs = re.sub(r"  # INLINE.*", "", rhs)
    return function("lu_solve_flat"), rhs, function("_reduced_solve")


def _loop() -> str:
    """A fixed-step loop around the stage states of loops.py's ``_stages`` (their lines, not a copy)."""
    src = LOOPS.read_text()
    stages = src[src.index("def _stages(") :]
    lines = stages[stages.index("    S = TC.shape[0]") : stages.index("        total = 0.0")]
    return LOOP_HEAD + "".join("    " + line + "\n" for line in lines.splitlines()) + LOOP_TAIL


def _at_run_time(src: str, name: str, extra: str) -> str:
    """A function of the generic code with ``d`` (the dimensions) and ``perm`` as its first arguments."""
    head, rest = src.split("\n", 1)
    args = head[head.index("(") + 1 : head.index(")")]
    unpack = "".join(f"    {k} = d[{i}]\n" for i, k in enumerate(DIMS)) + "    PERM = perm\n"
    return f"def {name}(d, perm, {extra}{args}):\n" + unpack + rest


def write_builds(folder: Path, module_file: str) -> None:
    """The three builds of the loop, the model's ``terms`` alone, and its dimensions."""
    text = Path(module_file).read_text()
    consts = {k: int(re.search(rf"^{k} = (\d+)", text, re.M).group(1)) for k in DIMS}
    terms = re.search(r"@njit\(.*?\)\ndef terms\(.*?(?=\n\n\n|\n@njit)", text, re.S).group(0) + "\n"
    defs = "".join(f"{k} = {v}\n" for k, v in consts.items())
    lu, rhs, reduced = _paper_parts()
    (folder / "build_per_model.py").write_text(
        HEAD + defs + "PERM = np.arange(N)\n" + terms + "".join("\n" + JIT + f for f in (lu, rhs, reduced, _loop()))
    )
    signature = "types.void(types.float64, types.float64[::1], types.float64[::1], types.float64[::1])"
    arrays = "A1 = types.float64[::1]\nA2 = types.float64[:, ::1]\nI1 = types.int64[::1]\n"
    rhs_sig = "types.void(I1, I1, FT, types.float64, A1, A1, A2, A2, A2, A2, types.int64, A1)"
    loop_sig = (
        "types.int64(I1, I1, FT, types.float64, types.float64, types.int64, A1, A1, A2, A2, A2, A2, A1, A1, A2, A1, A1)"
    )
    typed = 'cache=True, nogil=True, fastmath=FM, error_model="numpy")\n'
    once = _at_run_time(rhs, "rhs", "terms, ").replace(
        "_reduced_solve(w, K, row)", "_reduced_solve(d, perm, w, K, row)"
    )
    loop = _at_run_time(_loop(), "km", "terms, ").replace("rhs(t + TC[i]", "rhs(d, perm, terms, t + TC[i]")
    body = HEAD + f"FT = types.FunctionType({signature})\n" + arrays + JIT + lu + JIT
    body += _at_run_time(reduced, "_reduced_solve", "")
    body += f"@njit({rhs_sig}, " + typed + once + f"@njit({loop_sig}, " + typed + loop
    (folder / "build_once.py").write_text(body)
    direct = body.replace(
        "from numba import njit, types\n",
        "from numba import njit, types\nfrom model_terms import terms as TERMS\n",
    )
    (folder / "build_once_direct.py").write_text(direct.replace("    terms(t, x, p, w)\n", "    TERMS(t, x, p, w)\n"))
    terms_typed = terms.replace("@njit(", f"@njit({signature}, ", 1)
    (folder / "model_terms.py").write_text(HEAD + defs + terms_typed)
    (folder / "dims.json").write_text(json.dumps([consts[k] for k in DIMS]))
    (folder / "drive.py").write_text(DRIVE)


def main(argv: list[str]) -> None:
    steps = int(argv[0]) if argv else 500_000
    from nmkane_core.run.registry import get_system
    from nmkane_core.run.simulate import kernel_for

    module = kernel_for(get_system("appell-hamel"), "nonlinear")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        write_builds(folder, module.__file__)
        print(f"{'build':<16} {'first process: ready':>21} {'cached: ready':>14} {'run, ' + str(steps) + ' steps':>20}")
        results = {}
        for build in ("per_model", "once", "once_direct"):
            env = dict(os.environ, NUMBA_CACHE_DIR=str(folder / f"cache_{build}"), PYTHONPATH=str(folder))
            runs = []
            for _ in range(2):
                out = subprocess.run(
                    [sys.executable, "drive.py", build, str(steps)], cwd=folder, env=env, capture_output=True, text=True
                )
                if out.returncode:
                    sys.exit(out.stderr[-3000:])
                runs.append(json.loads(out.stdout.splitlines()[-1]))
            results[build] = runs
            first, cached = runs
            run_s = min(first["run_s"], cached["run_s"])
            print(f"{build:<16} {first['ready_s']:>20.2f}s {cached['ready_s']:>13.2f}s {run_s:>19.3f}s")
        same = all(r[1]["x"] == results["per_model"][1]["x"] for r in results.values())
        print("final states equal across builds:", same)


if __name__ == "__main__":
    main(sys.argv[1:])
