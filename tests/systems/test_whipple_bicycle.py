"""The Carvallo–Whipple bicycle against the published benchmark numbers.

References (numbers copied here with their source):

* Meijaard, Papadopoulos, Ruina & Schwab (2007), "Linearized dynamics equations for the
  balance and steer of a bicycle: a benchmark and review", Proc. R. Soc. A 463:1955–1982 —
  the linearized matrices M, C1, K0, K2 (eq. 2.2 and appendix A), the eigenvalue table
  (Table 2), the weave and capsize speeds.
* Basu-Mandal, Chatterjee & Papadopoulos (2007), "Hands-free circular motions of a
  benchmark bicycle", Proc. R. Soc. A 463:1983–2003 — Table 1: a state of the nonlinear
  bicycle and its accelerations (their coordinates; converted to Moore's below).

The model derives once per machine (the kernel is cached on disk); each test then runs in
milliseconds.
"""

import math

import numpy as np
import pytest

from nmkane_core import accelerations, get_system, linearize, simulate
from nmkane_core.kernel.built import built
from nmkane_core.run.initial import default_state, initial_state

NAME = "whipple-bicycle"
KEEP = ("q4", "q7", "u4", "u7")  # roll, steer and their rates
LAM = math.pi / 10
RR = 0.3

# Meijaard et al. (2007), eq. (A 20)–(A 23): M q̈ + v C1 q̇ + (g K0 + v² K2) q = 0, q = [φ, δ]
M = np.array([[80.81722, 2.31941332208709], [2.31941332208709, 0.29784188199686]])
C1 = np.array([[0.0, 33.86641391492494], [-0.85035641456978, 1.68540397397560]])
K0 = np.array([[-80.95, -2.59951685249872], [-2.59951685249872, -0.80329488458618]])
K2 = np.array([[0.0, 76.59734589573222], [0.0, 2.65431523794604]])

# Meijaard et al. (2007) Table 2: eigenvalues of the benchmark bicycle at speeds v [m/s]
EIGENVALUES = {
    0: [3.13164324790656, -3.13164324790656, 5.53094371765393, -5.53094371765393],
    1: [
        -3.13423125066578,
        complex(3.52696170990070, 0.80774027519930),
        complex(3.52696170990070, -0.80774027519930),
        -7.11008014637442,
    ],
    2: [
        -3.07158645641514,
        complex(2.68234517512745, 1.68066296590675),
        complex(2.68234517512745, -1.68066296590675),
        -8.67387984831735,
    ],
    3: [
        -2.63366137253667,
        complex(1.70675605663975, 2.31582447384325),
        complex(1.70675605663975, -2.31582447384325),
        -10.35101467245920,
    ],
    4: [
        -1.42944427361326,
        complex(0.41325331521125, 3.07910818603206),
        complex(0.41325331521125, -3.07910818603206),
        -12.15861426576450,
    ],
    5: [
        -0.32286642900409,
        complex(-0.77534188219585, 4.46486771378823),
        complex(-0.77534188219585, -4.46486771378823),
        -14.07838969279820,
    ],
    6: [
        -0.00406690076970,
        complex(-1.52644486584142, 5.87673060598709),
        complex(-1.52644486584142, -5.87673060598709),
        -16.08537123098030,
    ],
    7: [
        0.10268170574766,
        complex(-2.13875644258362, 7.19525913329805),
        complex(-2.13875644258362, -7.19525913329805),
        -18.15788466125262,
    ],
    8: [
        0.14327879765713,
        complex(-2.69348683581097, 8.46037971396931),
        complex(-2.69348683581097, -8.46037971396931),
        -20.27940894394569,
    ],
    9: [
        0.15790184030917,
        complex(-3.21675402252485, 9.69377351531791),
        complex(-3.21675402252485, -9.69377351531791),
        -22.43788559040858,
    ],
    10: [
        0.16105338653172,
        complex(-3.72016840437287, 10.90681139476287),
        complex(-3.72016840437287, -10.90681139476287),
        -24.62459635017404,
    ],
}
WEAVE_SPEED = 4.29238253634111  # Meijaard et al. (2007) §5
CAPSIZE_SPEED = 6.02426201538837

# Basu-Mandal et al. (2007) Table 1, in their coordinates: rear wheel centre (x, y, z), yaw θ,
# lean ψ (from horizontal), pitch φ, steer ψf, wheel rotations βr, βf; rates; accelerations
BM_STATE = {
    "x": 0.0,
    "y": 0.0,
    "z": 0.2440472102925,
    "th": 0.0,
    "psi": 0.9501292851472,
    "phi": 3.1257073014894,
    "psf": 0.2311385135743,
    "br": 0.0,
    "bf": 0.0,
}
BM_RATES = {
    "x": -2.8069345714545,
    "y": -0.1480982396001,
    "z": 0.1058778746261,
    "th": 0.7830033527065,
    "psi": 0.6068425835418,
    "phi": -0.0119185528069,
    "psf": 0.4859824687093,
    "br": 8.9129896614890,
    "bf": 8.0133620584155,
}
BM_ACC = {
    "x": -0.5041626315047,
    "y": -0.3449706619454,
    "z": -1.4604528332980,
    "th": 0.8353281706379,
    "psi": -7.8555281128244,
    "phi": 0.1205543897884,
    "psf": -4.6198904039403,
    "br": 1.8472554144217,
    "bf": 2.4548072904550,
}


def _basu_mandal_in_moore():
    """Their state, rates and accelerations in Moore's q, u, u̇ (u_i = dq_i/dt): q1 = −rR sinθ cosψ − x,
    q2 = y − rR cosθ cosψ, q3 = −θ, q4 = π/2 − ψ, q5 = π − φ + λ, q6 = −βr, q7 = −ψf,
    q8 = −βf."""
    s, r, a = BM_STATE, BM_RATES, BM_ACC
    st, ct, sp, cp = math.sin(s["th"]), math.cos(s["th"]), math.sin(s["psi"]), math.cos(s["psi"])
    td, pd, tdd, pdd = r["th"], r["psi"], a["th"], a["psi"]
    q = {
        "q1": -RR * st * cp - s["x"],
        "q2": s["y"] - RR * ct * cp,
        "q3": -s["th"],
        "q4": math.pi / 2 - s["psi"],
        "q5": math.pi - s["phi"] + LAM,
        "q6": -s["br"],
        "q7": -s["psf"],
        "q8": -s["bf"],
    }
    u = {
        "u1": RR * pd * st * sp - RR * td * ct * cp - r["x"],
        "u2": r["y"] + RR * td * st * cp + RR * pd * ct * sp,
        "u3": -td,
        "u4": -pd,
        "u5": -r["phi"],
        "u6": -r["br"],
        "u7": -r["psf"],
        "u8": -r["bf"],
    }
    ud = {
        "u1": RR * (pdd * st * sp + pd * td * ct * sp + pd * pd * st * cp)
        - RR * (tdd * ct * cp - td * td * st * cp - td * pd * ct * sp)
        - a["x"],
        "u2": a["y"]
        + RR * (tdd * st * cp + td * td * ct * cp - td * pd * st * sp)
        + RR * (pdd * ct * sp - pd * td * st * sp + pd * pd * ct * cp),
        "u3": -tdd,
        "u4": -pdd,
        "u5": -a["phi"],
        "u6": -a["br"],
        "u7": -a["psf"],
        "u8": -a["bf"],
    }
    return q, u, ud


@pytest.fixture(scope="module")
def bicycle():
    s = get_system(NAME)
    built(s).kernel()  # derive and compile once (cached on disk)
    return s


def _upright(v):
    from nmkane_core.analysis.eigensweep import state_at

    return state_at(NAME, v)


def _eigenvalues(v):
    return linearize(NAME, _upright(v), keep=KEEP).eigenvalues


def _sorted(ev):
    return sorted((complex(z) for z in ev), key=lambda z: (round(z.real, 8), z.imag))


def test_declaration(bicycle):
    assert built(bicycle).coordinates == tuple(f"q{i}" for i in range(1, 9))
    assert built(bicycle).speeds == tuple(f"u{i}" for i in range(1, 9))
    assert set(built(bicycle).independent) == {"q1", "q2", "q3", "q4", "q6", "q7", "q8", "u4", "u6", "u7"}
    assert built(bicycle).constraint_names() == (
        "rear_longitudinal",
        "rear_lateral",
        "front_longitudinal",
        "front_lateral",
        "front_contact",
    )
    assert bicycle.parameter("lam").default == pytest.approx(LAM)


def test_default_state_is_upright_straight_running_at_5_m_per_s(bicycle):
    st = _upright(5.0)
    assert st == pytest.approx(default_state(bicycle), abs=1e-12)
    assert st["q5"] == pytest.approx(LAM, abs=1e-13) and st["u1"] == pytest.approx(5.0, rel=1e-13)
    assert st["u8"] == pytest.approx(-5.0 / 0.35, rel=1e-13)
    assert all(abs(a) < 1e-12 for a in accelerations(NAME, st).values())  # a steady motion


@pytest.mark.parametrize("v", [0.0, 3.0, 5.0, 8.0])
def test_linearized_state_matrix_is_meijaards(bicycle, v):
    """A = [[0, I], [−M⁻¹(g K0 + v² K2), −v M⁻¹ C1]] for (roll, steer, roll rate, steer rate)."""
    A = linearize(NAME, _upright(v), keep=KEEP).A
    Minv = np.linalg.inv(M)
    expected = np.block([[np.zeros((2, 2)), np.eye(2)], [-Minv @ (9.81 * K0 + v * v * K2), -v * Minv @ C1]])
    assert np.allclose(A, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max()), A - expected


@pytest.mark.parametrize("v", sorted(EIGENVALUES))
def test_eigenvalues_match_meijaard_table_2(bicycle, v):
    got, ref = _sorted(_eigenvalues(v)), _sorted(EIGENVALUES[v])
    for g, r in zip(got, ref, strict=True):
        assert abs(g - r) <= 1e-10 * max(1.0, abs(r)), (v, got, ref)


def test_weave_and_capsize_speeds_by_root_finding(bicycle):
    from scipy.optimize import brentq

    def weave_real(v):  # real part of the oscillatory pair
        return max(z.real for z in _eigenvalues(v) if abs(z.imag) > 1e-6)

    def capsize(v):  # the real eigenvalue nearest zero
        return min((z.real for z in _eigenvalues(v) if abs(z.imag) < 1e-9), key=abs)

    vw = brentq(weave_real, 4.0, 4.6, xtol=1e-13, rtol=1e-14)
    vc = brentq(capsize, 5.8, 6.3, xtol=1e-13, rtol=1e-14)
    assert vw == pytest.approx(WEAVE_SPEED, rel=1e-8)
    assert vc == pytest.approx(CAPSIZE_SPEED, rel=1e-8)
    weave_pair = [z for z in _eigenvalues(vw) if abs(z.imag) > 1e-6]
    assert abs(weave_pair[0].imag) == pytest.approx(3.43503384866144, rel=1e-8)  # Meijaard §5


def test_basu_mandal_accelerations(bicycle):
    """Complete the state from q4, q7, u4, u6, u7 (q1, q2, q3, q6, q8 as given), then compare."""
    q, u, ud = _basu_mandal_in_moore()
    given = {k: v for k, v in {**q, **u}.items() if k in built(bicycle).independent}
    _, full = initial_state(bicycle, bicycle.default_variant, bicycle.resolve_params({}), given)
    for k in ("q5", "u1", "u2", "u3", "u5", "u8"):  # the completion finds their dependent values
        assert full[k] == pytest.approx({**q, **u}[k], abs=1e-12), k
    acc = accelerations(NAME, full)
    for k, ref in ud.items():
        assert acc[k] == pytest.approx(ref, rel=1e-10, abs=1e-10), (k, acc[k], ref)


def test_energy_is_conserved_in_a_nonlinear_run(bicycle):
    q, u, _ = _basu_mandal_in_moore()
    ini = {k: v for k, v in {**q, **u}.items() if k in built(bicycle).independent}
    run = simulate({"system": NAME, "initial": ini, "dt": 1e-3, "t_final": 0.25}, progress=False)
    assert run.summary["status"] == "ok"
    assert np.ptp(run.state["q4"]) > 0.05  # it moves (leans further)
    assert run.summary["max_abs_energy_drift"] < 1e-11 * abs(run.energy[0])
    assert max(run.summary["max_abs_violation"].values()) < 1e-10


def test_baumgarte_gains_hold_the_front_contact(bicycle):
    base = {
        "system": NAME,
        "dt": 0.01,
        "t_final": 30.0,
        "every": 100,
        "initial": {"q4": 0.2, "q7": 0.1, "u4": 0.5, "u6": -4.6 / RR},
    }  # self-stable speed
    free = simulate(base, progress=False).summary
    held = simulate({**base, "gamma1": -20.0, "gamma2": -100.0}, progress=False).summary
    assert free["status"] == held["status"] == "ok"
    d_free, d_held = free["max_abs_violation"]["front_contact"], held["max_abs_violation"]["front_contact"]
    assert d_held < 1e-9 and d_held < d_free / 20, (d_free, d_held)
    assert held["max_abs_energy_drift"] < free["max_abs_energy_drift"]


def test_self_stable_speed_range_in_the_nonlinear_model(bicycle):
    """A small roll-rate kick dies out above the weave speed (4.29 m/s) and grows below it."""

    def growth(v):
        r = simulate(
            {"system": NAME, "dt": 0.005, "t_final": 4.0, "every": 1, "initial": {"u4": 0.05, "u6": -v / RR}},
            progress=False,
        )
        assert r.summary["status"] == "ok"
        roll = np.abs(r.state["q4"])
        return roll[r.t >= 3.0].max() / roll[r.t <= 1.0].max()

    assert growth(5.0) < 0.3
    assert growth(4.0) > 2.0


def test_bicycle_eigenvalues_table(bicycle):
    from nmkane_core.analysis.eigensweep import sweep

    rows = sweep(NAME, [2.0, 6.0])
    assert [r["value"] for r in rows] == [2.0, 6.0]
    got = [complex(*z) for z in rows[1]["eigenvalues"]]
    assert np.allclose(_sorted(got), _sorted(EIGENVALUES[6]), atol=1e-9)


def test_bad_speed_is_refused_with_the_field_named(bicycle):
    from nmkane_core import InputError
    from nmkane_core.analysis.eigensweep import state_at

    with pytest.raises(InputError, match="speed"):
        state_at(NAME, float("nan"))
    with pytest.raises(InputError, match="rR"):
        state_at(NAME, 5.0, {"rR": -1.0})
