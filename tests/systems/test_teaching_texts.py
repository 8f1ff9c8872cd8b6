"""The teaching texts say what the systems do: the rolling disk's stability threshold is
computed from its parameters and its own runs change behaviour there; every built-in system
has a description and a "what to try"; initial values are labelled with what they are."""

import math
import re

import numpy as np
import pytest

from nmkane_core.kernel.built import built
from nmkane_core.run.registry import get_system
from nmkane_core.run.simulate import simulate
from nmkane_core.systems import BUILTIN
from nmkane_core.systems.rolling_disk import upright_threshold

UPRIGHT = {"x": 0.0, "y": 0.0, "psi": 0.0, "theta": 0.0, "phi": 0.0, "u3": 0.0, "u4": 0.05}


def test_rolling_disk_threshold_in_the_text_is_sqrt_g_over_3r_at_the_defaults():
    disk = get_system("rolling-disk")
    p = {q.name: q.default for q in disk.parameters}
    want = math.sqrt(p["g"] / (3 * p["r"]))
    assert upright_threshold() == pytest.approx(want) and want == pytest.approx(3.30, abs=5e-3)
    said = re.search(r"√\(g/\(3r\)\) = ([\d.]+) rad/s for r = ([\d.]+) m", disk.what_to_try)
    assert said is not None, disk.what_to_try
    assert float(said[1]) == pytest.approx(want, abs=5e-3) and float(said[2]) == p["r"]


@pytest.mark.parametrize("r", [0.3, 0.2])
def test_rolling_disk_stays_up_just_above_the_threshold_and_wobbles_large_just_below(r):
    """The text's claim against the system's own runs (the teacher saw large wobbles below, a
    settled disk above): 5 % above the threshold the lean stays under 0.1 rad; 5 % below, the
    tiny lean rate u4 = 0.05 rad/s grows into a lean of more than 0.25 rad."""
    w = upright_threshold(r=r)
    lean = {}
    for factor in (0.95, 1.05):
        run = simulate(
            {"system": "rolling-disk", "t_final": 10.0, "params": {"r": r}, "initial": {**UPRIGHT, "u5": factor * w}},
            progress=False,
        )
        assert run.summary["status"] == "ok"
        lean[factor] = float(np.max(np.abs(run.state["theta"])))
    assert lean[1.05] < 0.1 and lean[0.95] > 0.25, lean


@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_every_builtin_system_says_what_it_is_and_what_to_try(name):
    system = get_system(name)
    assert len(system.description) > 40 and len(system.what_to_try) > 80, name


@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_initial_speeds_are_labelled_with_what_they_are(name):
    """A slider of an initial speed names it and says what it is (u4 = θ̇ (lean rate)), not just u4(0)."""
    system = get_system(name)
    shown = system.initial_controls or dict.fromkeys(built(system).independent)
    for key, declared in shown.items():
        assert declared is not None, f"{name}: {key} has no label"
        lo, hi, label = declared
        assert lo < hi and "(" in label, (name, key, label)
        if key in built(system).speeds:
            assert label.startswith(f"{key} "), (name, key, label)
