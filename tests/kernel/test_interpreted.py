"""The first tier: a new kernel's generated module run by Python while numba compiles it
(nmkane_core.kernel.interpreted; the run layer's choice: nmkane_core.run.plan._interpret)."""

import dataclasses
import os
import subprocess
import sys

import numpy as np
import pytest

from nmkane_core.kernel import interpreted as tier
from nmkane_core.kernel import precompile
from nmkane_core.run.plan import resolve
from nmkane_core.run.simulate import kernel_for, simulate


@pytest.mark.parametrize(
    "settings",
    [
        {"system": "appell-hamel", "t_final": 0.5},  # the paper's solve
        {"system": "appell-hamel", "model": "linear", "t_final": 0.5, "integrator": "rk4"},
        {"system": "iftomm-a03", "t_final": 0.01},  # the rank-robust solve (a closed loop)
        {"system": "rolling-disk", "t_final": 0.5},
        {"system": "appell-hamel", "t_final": 0.5, "projection": "yoon"},
    ],
    ids=lambda s: "-".join([s["system"], s.get("model", "default"), s.get("projection", "")]).rstrip("-"),
)
def test_the_interpreted_kernel_runs_what_the_compiled_one_runs(settings):
    """The same run, once compiled and once interpreted: the same rows to rounding (the
    compiled code fuses multiply–adds), the same summary."""
    plan = resolve(settings)
    assert not plan.interpret  # a compiled kernel (the warm cache): no reason to interpret
    compiled = simulate(plan)
    run = simulate(dataclasses.replace(plan, interpret=True))
    assert run.summary["kernel_tier"] == "interpreted" and compiled.summary["kernel_tier"] == "compiled"
    assert run.summary["status"] == compiled.summary["status"] == "ok"
    assert run.summary["steps"] == compiled.summary["steps"]
    np.testing.assert_array_equal(run.t, compiled.t)
    for name, values in compiled.state.items():
        np.testing.assert_allclose(run.state[name], values, rtol=1e-9, atol=1e-11, err_msg=name)
    for name, values in compiled.multipliers.items():
        np.testing.assert_allclose(run.multipliers[name], values, rtol=1e-7, atol=1e-9, err_msg=name)


def test_a_short_fixed_step_run_of_an_uncompiled_kernel_is_interpreted(monkeypatch):
    """Only a kernel this process has not compiled, only a short fixed-step run without a
    projection; its summary says how it ran."""
    short = {"system": "appell-hamel", "t_final": 1.0}
    assert not resolve(short).interpret  # compiled: never
    monkeypatch.setattr(precompile, "uncompiled", lambda module: True)
    plan = resolve(short)
    assert plan.interpret
    assert tier.is_interpreted(plan.job().module)
    assert not resolve({**short, "t_final": 500.0, "dt": 0.001}).interpret  # 2.5 million evaluations
    assert not resolve({**short, "integrator": "kutta-merson-adaptive"}).interpret  # its work is not known ahead
    assert not resolve({**short, "integrator": "radau"}).interpret
    assert resolve({**short, "projection": "yoon"}).interpret
    assert simulate(plan).summary["kernel_tier"] == "interpreted"


def test_a_few_evaluations_now_use_the_interpreter_only_while_the_kernel_is_uncompiled(monkeypatch):
    plan = resolve({"system": "sliding-particle"})
    module = kernel_for(plan.system, plan.variant)
    assert tier.at_once(module) is module
    monkeypatch.setattr(precompile, "uncompiled", lambda m: True)
    py = tier.at_once(module)
    assert tier.is_interpreted(py) and py is tier.interpreted(module)  # made once
    assert not hasattr(py.diagnostics_rows, "signatures")  # plain Python functions
    assert 0 < tier.seconds_per_evaluation(module, plan.x0, plan.p, plan.G, plan.G1, plan.G2) < 0.1


def test_a_first_run_after_install_is_interpreted_while_the_child_compiles(tmp_path):
    """An empty cache: the first short run runs at once in Python and compiles nothing in its
    process; the background child fills the cache, and the next long run loads its loop."""
    code = (
        "from nmkane_core.run.simulate import simulate, kernel_for\n"
        "from nmkane_core import get_system\n"
        "r = simulate({'system': 'sliding-particle', 't_final': 0.1})\n"
        "m = kernel_for(get_system('sliding-particle'), 'nonminimal')\n"
        "compiled = sum(len(f.signatures) for f in vars(m).values() if hasattr(f, 'signatures'))\n"
        "r2 = simulate({'system': 'sliding-particle', 't_final': 1.0, 'dt': 1e-5})\n"
        "hits = sum(m.integrate_fixed.stats.cache_hits.values())\n"
        "print(r.summary['kernel_tier'], r.summary['status'], compiled, r2.summary['kernel_tier'], hits)\n"
    )
    env = {**os.environ, "NMKANE_CACHE_DIR": str(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path), "NMKANE_PRECOMPILE": "1"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    first, status, compiled, second, hits = out.stdout.split()
    assert (first, status, compiled, second) == ("interpreted", "ok", "0", "compiled")
    if (os.cpu_count() or 1) >= 2:
        assert int(hits) == 1  # loaded what the child compiled
