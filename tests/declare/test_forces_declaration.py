"""Declaring forces at points: checked when written (names, components, routes), compiled once
into numpy source (every symbol must be a name of the model, a multiplier of one of its
constraints, a speed's F_c or a rate), cached so that a fresh process evaluates them without
sympy."""

import os
import subprocess
import sys

import numpy as np
import pytest

from nmkane_core import InputError, Parameter, System
from nmkane_core.declare.forces import Forces, PointForce, constraint_force, generalized, multiplier, rate
from nmkane_core.kernel.forces import compile_forces


def test_point_force_checks_its_name_components_labels_and_route():
    ok = PointForce("contact", at=(0, 0, 0), components=(1, 2))
    assert ok.labels == ("x", "y") and ok.columns == ("contact.x", "contact.y") and ok.route == "multipliers"
    with pytest.raises(InputError, match=r"forces\.name"):
        PointForce("a contact", at=(0, 0, 0), components=(1,))
    with pytest.raises(InputError, match=r"forces\.c\.at"):
        PointForce("c", at=(0, 0), components=(1,))
    with pytest.raises(InputError, match="1 to 3"):
        PointForce("c", at=(0, 0, 0), components=(1, 2, 3, 4))
    with pytest.raises(InputError, match="labels"):
        PointForce("c", at=(0, 0, 0), components=(1, 2), labels=("normal",))
    with pytest.raises(InputError, match="route"):
        PointForce("c", at=(0, 0, 0), components=(1,), route="magic")
    assert PointForce("c", at=(0, 0, 0), components=(1,), route="multipliers+newton").route == "multipliers + newton"
    with pytest.raises(InputError, match="declared twice"):
        Forces(forces=(ok, ok))
    with pytest.raises(InputError, match=r"x: forces"):
        System(name="x", variants=lambda: None, forces=3)


def test_constraint_force_is_the_sum_of_multipliers_times_gradients():
    R = constraint_force({"a": (1, 0), "b": (2, 3)}, components=2)
    want = (multiplier("a") + 2 * multiplier("b"), 3 * multiplier("b"))
    assert want == R
    with pytest.raises(InputError, match="gradient of a"):
        constraint_force({"a": (1, 0, 0)}, components=2)


def _blade(forces):
    """The knife edge's model with other force declarations (not registered: compiled directly)."""
    from nmkane_core.systems.knife_edge import _model

    return System(
        name="test-blade-forces",
        variants=_model,
        parameters={"m": Parameter(1.0, 0.0, 10.0), "I": Parameter(0.1, 0.0, 10.0)},
        default_initial={"u1": 1.0, "u3": 0.5},
        forces=forces,
    )


def test_unknown_names_in_a_declaration_are_refused_naming_the_force():
    import sympy as sp

    def bad_symbol():
        return Forces(forces=(PointForce("blade", at=(0, 0, 0), components=(sp.Symbol("mass"),)),))

    def bad_constraint():
        return Forces(forces=(PointForce("blade", at=(0, 0, 0), components=(multiplier("slip"),)),))

    def state_in_point_ok_but_multiplier_not():
        return Forces(forces=(PointForce("blade", at=(multiplier("no_side_slip"), 0, 0), components=(1,)),))

    with pytest.raises(InputError, match=r"forces\.blade\.components.*mass"):
        compile_forces(_blade(bad_symbol))
    with pytest.raises(InputError, match=r"slip.*no_side_slip"):
        compile_forces(_blade(bad_constraint))
    with pytest.raises(InputError, match=r"forces\.blade\.at"):
        compile_forces(_blade(state_in_point_ok_but_multiplier_not))


def test_two_declarations_in_one_file_for_one_system_name_do_not_share_their_cache():
    """The compiled forces are cached by the system's kernel key and the declaring file; two
    declarations of one file under one name shared a file, and the second got the first's
    forces (a shuffled run: the refusals above passed only when they ran first)."""
    import sympy as sp

    def good():
        return Forces(forces=(PointForce("blade", at=(0, 0, 0), components=(multiplier("no_side_slip"),)),))

    def bad():
        return Forces(forces=(PointForce("blade", at=(0, 0, 0), components=(sp.Symbol("mass"),)),))

    assert compile_forces(_blade(good)).columns == ["blade.x"]
    with pytest.raises(InputError, match=r"forces\.blade\.components.*mass"):
        compile_forces(_blade(bad))


def test_generalized_forces_rates_and_dynamicsymbol_derivatives_compile():
    import sympy as sp
    from sympy.physics import mechanics as me

    u1 = me.dynamicsymbols("u1")

    def declared(variant):
        assert variant == "default"
        return Forces(
            forces=(
                PointForce(
                    "probe",
                    at=(sp.Symbol("x"), 0, 0),
                    components=(generalized("u2"), rate("u1"), u1.diff(me.dynamicsymbols._t) - rate("u1")),
                    labels=("fc", "rate", "zero"),
                    route="generalized",
                ),
            )
        )

    compiled = compile_forces(_blade(declared))
    assert compiled.generalized == ["u2"] and compiled.rates == ["u1"] and compiled.multipliers == []
    n = 4
    states = {k: np.linspace(0, 1, n) for k in ("x", "y", "theta", "u1", "u2", "u3")}
    out = compiled.components(states, {"m": 1.0, "I": 0.1}, {}, {"u2": np.arange(n)}, {"u1": np.full(n, 2.0)})
    np.testing.assert_array_equal(out["probe.fc"], np.arange(n))
    np.testing.assert_array_equal(out["probe.rate"], 2.0)
    np.testing.assert_array_equal(out["probe.zero"], 0.0)
    point, axes = compiled.geometry(states, {"m": 1.0, "I": 0.1})["probe"]
    assert point.shape == (n, 3) and axes.shape == (n, 3, 3)
    np.testing.assert_array_equal(axes[0], np.eye(3))


def test_cached_forces_are_evaluated_in_a_fresh_process_without_sympy(tmp_path):
    env = {**os.environ, "NMKANE_CACHE_DIR": str(tmp_path)}
    probe = (
        "import sys\nfrom nmkane_core import simulate\n"
        "r = simulate({'system': 'knife-edge', 't_final': 0.1})\n"
        "print(round(float(r.point_forces['blade.lateral'][-1]), 9), 'sympy' in sys.modules)"
    )
    first = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, check=True)
    assert first.stdout.split() == ["0.5", "True"]  # built: sympy was needed
    assert list((tmp_path / "forces").glob("*.json"))
    again = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, check=True)
    assert again.stdout.split() == ["0.5", "False"]
