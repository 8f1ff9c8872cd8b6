"""Kinematic singularities (issue 45, item 2): the Suslov body through gimbal lock, twice.

The body of ``examples/suslov_body.py`` turns about a fixed point and may not turn about its axis
e2 (ω·e2 = 0); with the product of inertia I12 its spin about e3 reverses, in closed form:
ω3 = −Ω tanh(k(t − t0)), ω1 = √(I33/I11) Ω sech(k(t − t0)), k = Ω I12/I11, Ω² = (I11 ω1² + I33 ω3²)/I33.
Started with e3 horizontal, its x-axis sweeps through the vertical twice a turn, where the ZYX
angles' pitch is θ = ±π/2 and their kinematics q̇ = C(q)u blow up (1/cos θ).  The two starts here,
e3 along −y and along +y, sweep it over the vertical in opposite senses ("both ways").

The reference: the closed-form ω and the quaternion kinematics q̇ = ½ q ⊗ (0, ω) integrated by
scipy's DOP853 at rtol 1e-13 — nothing of nmkane — compared as rotation matrices (the orientation,
whatever the coordinates).
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from nmkane_core import simulate
from nmkane_core.declare.rotation import (
    quaternion_from_axis_angle,
    quaternion_from_matrix,
    quaternion_from_zyx,
)
from nmkane_core.run.plugins import load_systems

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "suslov_body.py"
I11, I22, I33, I12 = 1.0, 1.2, 1.0, 0.3  # the example's defaults
SPIN, NUDGE, T = 2 * math.pi, 0.01, 8.0
STARTS = {"e3 along -y": 1, "e3 along +y": -1}  # a quarter turn about x, one way or the other


@pytest.fixture(autouse=True)
def systems():
    """The example's two systems, registered for each test (the registry is reset after each)."""
    load_systems([str(EXAMPLE)], strict=True)


# ----------------------------------------------------------------------------- the reference


def omega(t):
    """The closed-form body rates (ω1, ω3) of the default start (ω1 = NUDGE, ω3 = SPIN at t = 0)."""
    big = math.sqrt((I11 * NUDGE**2 + I33 * SPIN**2) / I33)
    k = big * I12 / I11
    t0 = math.atanh(SPIN / big) / k
    t = np.asarray(t, float)
    return math.sqrt(I33 / I11) * big / np.cosh(k * (t - t0)), -big * np.tanh(k * (t - t0))


def _qmul(a, b):
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return np.array(
        [
            a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
        ]
    )


def matrix(q):
    q0, q1, q2, q3 = np.asarray(q) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (q2 * q2 + q3 * q3), 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
            [2 * (q1 * q2 + q0 * q3), 1 - 2 * (q1 * q1 + q3 * q3), 2 * (q2 * q3 - q0 * q1)],
            [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), 1 - 2 * (q1 * q1 + q2 * q2)],
        ]
    )


@functools.cache
def reference(sign: int):
    """The orientation over T from the start ``sign`` (dense output of q)."""
    from scipy.integrate import solve_ivp

    def f(t, q):
        w1, w3 = omega(t)
        return 0.5 * _qmul(q, (0.0, float(w1), 0.0, float(w3)))

    start = quaternion_from_axis_angle((1.0, 0.0, 0.0), sign * math.pi / 2)
    return solve_ivp(f, (0.0, T), start, method="DOP853", rtol=1e-13, atol=1e-14, dense_output=True)


def passages(sign: int):
    """(t, which pole: +1 for θ = +π/2 (x-axis down), −1 for θ = −π/2, distance δ from it (rad),
    the x-axis' velocity there) of each passage of the reference near the vertical."""
    sol = reference(sign)
    ts = np.linspace(0.0, T, 80001)
    r31 = np.array([matrix(q)[2, 0] for q in sol.sol(ts).T])
    out = []
    for i in range(1, ts.size - 1):
        a = abs(r31[i])
        if a > 0.99 and a >= abs(r31[i - 1]) and a >= abs(r31[i + 1]):
            R = matrix(sol.sol(ts[i]))
            w1, w3 = omega(ts[i])
            e1dot = np.cross(R @ np.array([float(w1), 0.0, float(w3)]), R[:, 0])
            out.append((ts[i], -int(np.sign(r31[i])), math.acos(min(1.0, a)), e1dot))
    return out


def orientation_error(run, sign: int, t_offset: float = 0.0) -> np.ndarray:
    """max |R − R_ref| over each row of a run (its R outputs), the reference at t + t_offset."""
    sol = reference(sign)
    R = np.stack([np.stack([np.asarray(run.state[f"R{i}{j}"]) for j in (1, 2, 3)], -1) for i in (1, 2, 3)], -2)
    ref = np.array([matrix(q) for q in sol.sol(np.asarray(run.t) + t_offset).T])
    return np.abs(R - ref).max(axis=(1, 2))


def zyx(R) -> dict[str, float]:
    return {
        "psi": math.atan2(R[1, 0], R[0, 0]),
        "theta": math.asin(-R[2, 0]),
        "phi": math.atan2(R[2, 1], R[2, 2]),
    }


@functools.cache
def _run(key: str):
    return simulate(json.loads(key), progress=False)


def run(**settings):
    return _run(json.dumps(settings, sort_keys=True))


def quaternion_run(sign: int, **settings):
    q = quaternion_from_axis_angle((1.0, 0.0, 0.0), sign * math.pi / 2)
    initial = {"q1": q[1], "q2": q[2], "q3": q[3], "w1": NUDGE, "w3": SPIN}  # q0 completed from |q| = 1
    return run(system="suslov-body", t_final=T, initial=initial, **settings)


def euler_run(sign: int, t_start: float = 0.0, **settings):
    """The ZYX model from the reference's orientation and rates at ``t_start``."""
    w1, w3 = omega(t_start)
    initial = {**zyx(matrix(reference(sign).sol(t_start))), "w1": float(w1), "w3": float(w3)}
    return run(system="suslov-body-zyx", t_final=T - t_start, initial=initial, **settings)


# ----------------------------------------------------------------------------- the motion


@pytest.mark.parametrize("start", STARTS)
def test_the_reference_goes_through_gimbal_lock_both_ways(start):
    """Both starts come within 7e-3 rad of θ = +π/2 and of θ = −π/2 in their first 0.8 s (the
    first passage at 0.25 s, within 1.9e-3 rad), within 1e-4 rad again after the reversal (at
    6.20 s), and the x-axis passes straight down moving +x from one start, −x from the other."""
    sign = STARTS[start]
    found = passages(sign)
    assert len(found) >= 10
    first = {pole: min(d for t, p, d, _ in found if p == pole and t < 0.8) for pole in (1, -1)}
    assert max(first.values()) < 7e-3, first
    assert min(d for t, p, d, _ in found if t > 6.0) < 1e-4
    down = [v for t, p, d, v in found if p == 1]
    assert all(np.sign(v[0]) == sign for v in down)
    assert abs(passages(1)[0][0] - 0.25) < 1e-3 and abs(passages(-1)[0][0] - 0.25) < 1e-3


@pytest.mark.parametrize("start", STARTS)
def test_the_quaternion_body_goes_through_every_passage_ok_and_right(start):
    """Kutta–Merson at Δt = 1e-3, 8 s, 32 passages near gimbal lock (one within 5.5e-5 rad): ends
    ``ok``, the orientation within 1e-9 of the reference (measured 7.2e-12, 3.7e-13 at Δt/2:
    the method's fourth-order error), |q| = 1 to 1e-12 without stabilization, the rates on the
    closed form to 1e-9 and the kinematics' estimate 1 throughout (C's rows stay orthogonal)."""
    sign = STARTS[start]
    r = quaternion_run(sign)
    s = r.summary
    assert s["status"] == "ok", s["message"]
    assert r.t[-1] == T
    assert orientation_error(r, sign).max() < 1e-9
    q = np.stack([np.asarray(r.state[k]) for k in ("q0", "q1", "q2", "q3")])
    assert np.abs(np.linalg.norm(q, axis=0) - 1.0).max() < 1e-12
    assert s["max_abs_violation"]["unit"] < 1e-12 and s["max_abs_violation"]["suslov"] == 0.0
    w1, w3 = omega(r.t)
    assert np.abs(np.asarray(r.state["w1"]) - w1).max() < 1e-9
    assert np.abs(np.asarray(r.state["w3"]) - w3).max() < 1e-9
    assert s["min_rcond"]["C"] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("start", STARTS)
def test_the_euler_angles_stop_singular_before_gimbal_lock_never_ok_and_wrong(start):
    """The ZYX model, Kutta–Merson at Δt = 1e-3: ends ``singular`` at 0.24 s, before the first
    passage (0.25 s, within 1.9e-3 rad of the lock: the angles ψ and φ swing by π in about
    δ/Ω = 0.3 ms there, a third of a step), the message naming the kinematics, every row kept
    right (1e-9).  Without the step check it ends ``ok`` with the orientation 5e-3 off."""
    sign = STARTS[start]
    r = euler_run(sign)
    s = r.summary
    assert s["status"] == "singular", s["message"]
    assert "kinematics q̇ = C(q) u + D" in s["message"]
    assert 0.2 <= s["t_end"] < passages(sign)[0][0]
    assert orientation_error(r, sign).max() < 1e-9
    assert s["min_rcond"]["C"] < 0.1


def test_after_the_reversal_the_euler_angles_stop_again():
    """Started at 6.0 s, after the spin reversed: stops before 6.2014 s, where the x-axis passes
    within 5.5e-5 rad of straight down."""
    r = euler_run(1, t_start=6.0)
    s = r.summary
    assert s["status"] == "singular", s["message"]
    assert 0.15 < s["t_end"] < 0.2014
    assert orientation_error(r, 1, t_offset=6.0).max() < 1e-9


@pytest.mark.parametrize("integrator", ["kutta-merson-adaptive", "rk45"])
def test_an_adaptive_method_follows_the_euler_angles_swing(integrator):
    """With error control the steps shrink near each passage (the loops' adaptive steps are also
    shrunk where the estimate changes by more than a tenth within one): ``ok`` and right to 1e-7
    (measured 5e-9 and 1.4e-9), with the estimate down to 1.8e-5 — or ``singular``, never wrong."""
    r = euler_run(1, integrator=integrator)
    s = r.summary
    assert s["status"] in ("ok", "singular"), s["message"]
    assert orientation_error(r, 1).max() < 1e-7
    if s["status"] == "ok":
        assert s["min_rcond"]["C"] < 1e-4


@pytest.mark.parametrize("integrator", ["kutta-merson", "rk45"])
def test_at_gimbal_lock_itself_the_euler_angles_are_singular(integrator):
    """Started at θ = π/2 (cos θ = 6e-17 in floating point): C's estimate is below rcond_min at the
    first evaluation — status ``singular``, "became singular", the estimate in the message."""
    r = run(
        system="suslov-body-zyx",
        t_final=1.0,
        integrator=integrator,
        initial={"psi": 0.0, "theta": math.pi / 2, "phi": 0.0, "w1": NUDGE, "w3": SPIN},
    )
    s = r.summary
    assert s["status"] == "singular", s["message"]
    assert "kinematics q̇ = C(q) u + D became singular" in s["message"]
    assert s["t_end"] == 0.0
    assert s["min_rcond"]["C"] < 1e-15


# ----------------------------------------------------------------------------- the estimate


def _estimate(system: str, x) -> float:
    from nmkane_core import get_system
    from nmkane_core.kernel.built import built

    sysm = get_system(system)
    b = built(sysm)
    module, _ = b.kernel(sysm.default_variant)
    p = b.param_vector(sysm.default_variant, sysm.resolve_params({}))
    w = module.make_workspace()
    K = np.empty((1, 2 * module.N))
    G = [np.zeros((k, k)) for k in (module.MNH, module.MH, module.MH)]
    module.rhs_ws(0.0, np.asarray(x, float), p, *G, K, 0, w)
    return float(w[module.ORC + 2])


def test_the_estimate_is_cos_theta_for_the_angles_and_one_for_the_quaternion():
    """The volume of C's rows scaled to unit length: exactly |cos θ| for ZYX angles (whatever ψ, φ
    and the rates), 1 for the quaternion at any state, on the unit sphere or off it."""
    rng = np.random.default_rng(7)
    for theta in (0.0, 0.7, -1.2, 1.5, math.pi / 2 - 1e-6):
        psi, phi, w1, w3 = rng.uniform(-3, 3, 4)
        assert _estimate("suslov-body-zyx", [psi, theta, phi, w1, 0.0, w3]) == pytest.approx(
            abs(math.cos(theta)), rel=1e-9
        )
    for _ in range(5):
        q = rng.normal(size=4) * rng.uniform(0.5, 2.0)
        assert _estimate("suslov-body", [*q, *rng.normal(size=3), 0.0]) == pytest.approx(1.0, abs=1e-12)


# ----------------------------------------------------------------------------- the quaternion, end to end


def test_from_mechanics_builds_the_written_quaternion_model():
    """``from_mechanics`` with a frame of ``quaternion_frame`` and ``rotations=``: the same C, Q (the
    norm rate's fictitious inertia included), P and norm constraint as the model written out."""
    import runpy

    import sympy as sp
    import sympy.physics.mechanics as me

    from nmkane_core import MechanicalModel
    from nmkane_core.declare.rotation import quaternion_frame

    example = runpy.run_path(str(EXAMPLE))
    written = example["suslov_model"]("quaternion")
    (i11, i22, i33, i12), _ = example["_inertia"]()
    N = me.ReferenceFrame("N")
    B, rot = quaternion_frame(N, "B")
    O = me.Point("O")
    O.set_vel(N, 0)
    body = me.RigidBody("body", O, B, 1, (me.inertia(B, i11, i22, i33, i12, 0, 0), O))
    w1, w2, w3 = rot.rates
    model = MechanicalModel.from_mechanics(
        q=rot.coordinates,
        u=rot.speeds,
        kd_eqs=rot.kd_eqs,
        bodies=[body],
        loads=[],
        frame=N,
        params=(i11, i22, i33, i12),
        nonholonomic={"suslov": w2},
        holonomic=rot.holonomic,
        u_independent=(w1, w3),
        rotations=(rot,),
    )
    for name in ("C", "Q", "P"):
        assert sp.simplify(getattr(model, name) - getattr(written, name)).is_zero_matrix, name
    assert sp.simplify(model.holonomic["unit"] - written.holonomic["unit"]) == 0
    assert model.Q[3, 3] == (i11 + i22 + i33) / 3


def test_an_orientation_is_given_by_three_components_or_projected():
    """The quaternion's q0 is completed from q1, q2, q3 (|q| = 1) and s from the norm's rate; a
    full state off the unit sphere is projected onto it along q (``project_initial``): the same
    orientation.  The helpers' numbers agree with each other."""
    q = quaternion_from_zyx(0.4, -0.3, 1.1)
    R = matrix(q)
    assert np.allclose(quaternion_from_matrix(R), q, atol=1e-15)
    r = run(system="suslov-body", t_final=0.01, initial={"q1": q[1], "q2": q[2], "q3": q[3], "w1": 0.5, "w3": 1.0})
    assert r.state["q0"][0] == pytest.approx(q[0], abs=1e-15) and r.state["s"][0] == 0.0
    full = {"q0": 1.5 * q[0], "q1": 1.5 * q[1], "q2": 1.5 * q[2], "q3": 1.5 * q[3], "w1": 0.5, "w2": 0.0}
    r = run(system="suslov-body", t_final=0.01, initial={**full, "w3": 1.0, "s": 0.0}, project_initial=True)
    got = np.array([r.state[k][0] for k in ("q0", "q1", "q2", "q3")])
    np.testing.assert_allclose(got, q, atol=1e-15)
    assert set(r.summary["initial_correction"]) == {"q0", "q1", "q2", "q3"}


@pytest.mark.parametrize(
    "settings",
    [{"solve": "robust"}, {"solve": "paper"}, {"projection": "yoon"}, {"projection": "blajer"},
     {"gamma1": -20.0, "gamma2": -100.0}],
    ids=lambda s: json.dumps(s),
)  # fmt: skip
def test_the_norm_rates_inertia_changes_nothing(settings):
    """The rank-robust solve (Gauss's principle in the mass metric: Q must be positive definite),
    the paper's, the mass-weighted projections and Baumgarte's terms all give the same motion."""
    r = quaternion_run(1, **settings)
    assert r.summary["status"] == "ok", r.summary["message"]
    assert orientation_error(r, 1).max() < 1e-9
    assert r.summary["max_abs_violation"]["unit"] < 1e-12


def test_the_scene_poses_the_body_by_its_quaternion():
    """The page's poses: the body frame's rotation is the run's R, orthonormal."""
    from nmkane_core import get_system
    from nmkane_core.kernel.visuals import compile_visuals

    cv = compile_visuals(get_system("suslov-body"))
    r = quaternion_run(1)
    frames, _ = cv.frame_poses(r.state, r.settings["params"])
    _, rot = frames["body"]
    R = np.stack([np.stack([np.asarray(r.state[f"R{i}{j}"]) for j in (1, 2, 3)], -1) for i in (1, 2, 3)], -2)
    np.testing.assert_allclose(rot, R, atol=1e-12)
    np.testing.assert_allclose(rot @ np.swapaxes(rot, 1, 2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12)


# ----------------------------------------------------------------------------- constant kinematics


#: final states of runs made before the kinematics' estimate existed (float.hex), and one of a model
#: whose C varies (the rattleback's ZXY angles): the estimate is computed beside the motion, never in it
BEFORE = {
    "sliding-particle": (
        {"t_final": 10.0},
        {"x": "0x1.bdde47b57b183p-2", "y": "0x1.9eee33544af1dp-1", "u1": "-0x1.80e8d5f5b028ap+1",
         "u2": "0x1.4f3178606b18cp+1"},
    ),
    "appell-hamel": (
        {"t_final": 5.0},
        {"theta": "0x1.176b685b3eefap+1", "phi": "0x1.e3c0e9bb0222bp+3", "x": "-0x1.443131f465ee2p+3",
         "y": "0x1.129abac21dd14p+4", "z": "0x1.670fc5913f780p+4", "u1": "0x1.06372561cf20fp-4",
         "u2": "0x1.25d5594a289fbp+2", "u3": "-0x1.733ae724fca0ep+1", "u4": "0x1.c9679dfed2536p+1",
         "u5": "-0x1.25d5594a289fbp+1"},
    ),
    "rattleback": (
        {"t_final": 1.0},
        {"x": "0x1.4a062f58d364ap-10", "y": "0x1.8544bd3928204p-10", "z": "0x1.58f890fcfe1bbp-7",
         "psi": "-0x1.1107f8721fe3ap+2", "theta": "-0x1.8980a3b4a8450p-8", "phi": "0x1.7b932c1f5ce4dp-6",
         "u1": "-0x1.786231242805ep-4", "u2": "-0x1.8f0e8c8f46390p-6", "u3": "0x1.3c6469a303ae7p-4",
         "u4": "0x1.42a06c8e235bcp+2", "u5": "0x1.c2ec929979afdp+0", "u6": "-0x1.8f0ba71020317p+1"},
    ),
}  # fmt: skip


@pytest.mark.parametrize("system", BEFORE)
def test_runs_keep_their_bits_and_constant_kinematics_report_no_estimate(system):
    """The same bits as before the estimate; ``min_rcond`` has no C for a constant C (the paper's
    systems: C = I), and the rattleback's (ZXY angles, tilted at most 0.15 rad) is cos of its tilt."""
    settings, final = BEFORE[system]
    r = run(system=system, **settings)
    assert r.summary["status"] == "ok"
    assert {k: float(r.state[k][-1]).hex() for k in final} == final
    if system == "rattleback":
        assert 0.98 < r.summary["min_rcond"]["C"] < 1.0
    else:
        assert set(r.summary["min_rcond"]) == {"J2", "T"}
