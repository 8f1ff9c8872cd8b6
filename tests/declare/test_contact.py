"""Rolling contact declared from a convex surface (nmkane_core.declare.contact): the contact
point against closed forms (a sphere: straight below its centre) and against a numerical
minimization of the height over the surface (an ellipsoid, a disk's rim, a torus), the height's
rate against the contact point's vertical velocity, the rolling disk's own constraints, and
the refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.optimize import minimize

from nmkane_core.declare.contact import (
    disk_edge,
    ellipsoid,
    implicit_surface,
    rolling_contact,
    sphere,
    support_surface,
    torus,
)
from nmkane_core.declare.forces import multiplier
from nmkane_core.declare.visuals import rot_x, rot_y, rot_z
from nmkane_core.errors import InputError

x, y, z, psi, th, ph = sp.symbols("x y z psi theta phi", real=True)
vx, vy, vz, w1, w2, w3 = sp.symbols("vx vy vz w1 w2 w3", real=True)
R = rot_z(psi) * rot_x(th) * rot_y(ph)
POSE = {x: 0.1, y: -0.2, z: 0.5, psi: 0.7, th: 0.3, ph: -0.4}
RATES = {vx: 0.3, vy: -0.1, vz: 0.2, w1: 1.1, w2: -0.6, w3: 2.3}


def contact_of(surface, **kw):
    return rolling_contact(surface, R, (x, y, z), (vx, vy, vz), body_angular_velocity=(w1, w2, w3), **kw)


def num(expr, values=POSE):
    return np.array(sp.Matrix(expr).evalf(subs={**values, **RATES}), dtype=float).ravel()


def lowest(point_of, starts):
    """The lowest world point of a parametrized body surface (body coordinates ``point_of(u, v)``)
    at POSE, by Nelder–Mead from several starts."""
    Rn = np.array(R.evalf(subs=POSE), dtype=float)
    origin = np.array([POSE[x], POSE[y], POSE[z]])

    def world(uv):
        return origin + Rn @ np.asarray(point_of(*uv), float)

    best = min(
        (
            minimize(lambda uv: world(uv)[2], s, method="Nelder-Mead", options={"xatol": 1e-13, "fatol": 1e-15})
            for s in starts
        ),
        key=lambda r: r.fun,
    )
    return world(best.x)


def test_a_sphere_touches_the_plane_straight_below_its_centre():
    r = sp.Symbol("r", positive=True)
    c = contact_of(sphere(r))
    assert sp.simplify(c.height["on_plane"] - (z - r)) == 0  # the support of a unit normal is r
    values = {**POSE, r: 1.0}
    np.testing.assert_allclose(num(c.point, values), [0.1, -0.2, -0.5], atol=1e-14)
    # the material point at the bottom moves with v + ω × (−r e_z), ω = R ω_B
    w_world = np.array(R.evalf(subs=POSE), dtype=float) @ np.array([RATES[w1], RATES[w2], RATES[w3]])
    want = np.array([RATES[vx], RATES[vy], RATES[vz]]) + np.cross(w_world, [0.0, 0.0, -1.0])
    np.testing.assert_allclose(num(c.slip_velocity, values), want, atol=1e-14)
    assert set(c.no_slip) == {"no_slip_x", "no_slip_y"}
    np.testing.assert_allclose(num(list(c.no_slip.values()), values), want[:2], atol=1e-14)


def test_an_ellipsoid_touches_where_a_numerical_minimization_of_its_height_says():
    a, b, cc, h = 0.2, 0.03, 0.02, 0.01
    c = contact_of(ellipsoid(a, b, cc, centre=(0, 0, h)))
    want = lowest(
        lambda lon, lat: (a * math.cos(lat) * math.cos(lon), b * math.cos(lat) * math.sin(lon), h + cc * math.sin(lat)),
        [(lon, lat) for lon in (0.0, 1.5, 3.0, 4.5) for lat in (-1.2, 1.2)],
    )
    np.testing.assert_allclose(num(c.point), want, atol=1e-8)
    # the height constraint is the lowest point's height: zero exactly when it is on the plane
    assert float(c.height["on_plane"].evalf(subs=POSE)) == pytest.approx(want[2], abs=1e-10)
    # and the same point from the surface written implicitly, (x/a)² + (y/b)² + ((z − h)/c)² = 1
    s = sp.symbols("s1:4", real=True)
    f = (s[0] / a) ** 2 + (s[1] / b) ** 2 + ((s[2] - h) / cc) ** 2 - 1
    np.testing.assert_allclose(num(contact_of(implicit_surface(f, s)).point), want, atol=1e-8)


def test_an_implicit_quadric_turned_and_moved_in_the_body_touches_where_the_minimization_says():
    a, b, cc, turn, shift = 0.2, 0.05, 0.03, 0.6, (0.02, -0.01, 0.04)
    s = sp.symbols("s1:4", real=True)
    d = sp.Matrix(s) - sp.Matrix(shift)
    e = rot_z(turn).T * d  # the ellipsoid's own axes, turned by 0.6 rad about the body z
    c = contact_of(implicit_surface((e[0] / a) ** 2 + (e[1] / b) ** 2 + (e[2] / cc) ** 2 - 1, s))
    Rt = np.array(rot_z(turn).evalf(), dtype=float)

    def point(lon, lat):
        own = (a * math.cos(lat) * math.cos(lon), b * math.cos(lat) * math.sin(lon), cc * math.sin(lat))
        return np.asarray(shift) + Rt @ np.asarray(own)

    want = lowest(point, [(lon, lat) for lon in (0.0, 1.5, 3.0, 4.5) for lat in (-1.2, 1.2)])
    np.testing.assert_allclose(num(c.point), want, atol=1e-8)
    assert float(c.height["on_plane"].evalf(subs=POSE)) == pytest.approx(want[2], abs=1e-10)


def test_a_disk_rim_and_a_torus_touch_where_the_minimization_says():
    r, R0, tube = 0.3, 0.25, 0.05
    rim = lowest(lambda a, _: (r * math.cos(a), 0.0, r * math.sin(a)), [(k, 0.0) for k in (0.0, 2.0, 4.0)])
    np.testing.assert_allclose(num(contact_of(disk_edge(r, axis="y")).point), rim, atol=1e-8)
    tyre = lowest(
        lambda a, b: (
            (R0 + tube * math.cos(b)) * math.cos(a),
            tube * math.sin(b),
            (R0 + tube * math.cos(b)) * math.sin(a),
        ),
        [(k, 0.0) for k in (0.0, 2.0, 4.0)],
    )
    np.testing.assert_allclose(num(contact_of(torus(R0, tube, axis="y")).point), tyre, atol=1e-8)


def test_the_contact_points_vertical_velocity_is_the_heights_rate_frames_and_vectors_in():
    """The envelope property (the contact point slides on the surface perpendicular to its normal),
    through the sympy.physics.mechanics route: a ReferenceFrame, Vectors and dynamicsymbols."""
    from sympy.physics import mechanics as me

    q = me.dynamicsymbols("q1:4")
    p = me.dynamicsymbols("p1:4")
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Body", q, "ZXY")
    O = me.Point("O")
    G = O.locatenew("G", p[0] * N.x + p[1] * N.y + p[2] * N.z)
    c = rolling_contact(
        ellipsoid(0.2, 0.03, 0.02, centre=(0, 0, 0.01)),
        B,
        G.pos_from(O),
        G.pos_from(O).dt(N),
        angular_velocity=B.ang_vel_in(N),
        inertial=N,
    )
    t = me.dynamicsymbols._t
    rng = np.random.default_rng(3)
    for _ in range(3):
        values = dict(zip([*q, *p], rng.uniform(-0.5, 0.5, 6), strict=True))
        rates = dict(zip([v.diff(t) for v in (*q, *p)], rng.uniform(-2, 2, 6), strict=True))

        def at(e, values=values, rates=rates):
            return float(sp.sympify(e).subs(rates).subs(values))

        assert at(c.height["on_plane"].diff(t)) == pytest.approx(at(c.slip_velocity[2]), abs=1e-12)
    # body rates along B give the same slip velocity as the angular velocity Vector
    body = rolling_contact(
        ellipsoid(0.2, 0.03, 0.02, centre=(0, 0, 0.01)),
        B,
        G.pos_from(O),
        G.pos_from(O).dt(N),
        body_angular_velocity=[B.ang_vel_in(N).dot(e) for e in (B.x, B.y, B.z)],
        inertial=N,
    )
    for i in range(3):
        assert at(body.slip_velocity[i]) == pytest.approx(at(c.slip_velocity[i]), abs=1e-12)


def test_the_rim_of_a_disk_gives_the_rolling_disks_constraints():
    """The rolling disk's no-slip constraints (written by hand on the contact point −r B.z) from
    the rim's surface, in the lean frame B (the rim is the same circle there, and B does not
    spin): equal wherever the coin is not past flat (cos θ > 0)."""
    from nmkane_core.systems.rolling_disk import _model

    model = _model()
    qs, us = model.q, model.u
    X, Y, Psi, Th, _ = qs
    r = sp.Symbol("r", positive=True)
    A = rot_z(Psi)
    Bm = A * rot_x(Th)
    Nz = sp.Matrix([0, 0, 1])
    w_lean = us[2] * Nz + us[3] * A[:, 0]  # B's angular velocity ψ̇ N.z + θ̇ A.x
    w_world = w_lean + us[4] * Bm[:, 1]  # the coin's: + φ̇ B.y
    centre = sp.Matrix([X, Y, 0]) + r * Bm[:, 2]  # r B.z above the contact point (x, y), u1, u2 its rates
    v_centre = sp.Matrix([us[0], us[1], 0]) + w_lean.cross(r * Bm[:, 2])
    c = rolling_contact(disk_edge(r, axis="y"), Bm, centre, v_centre, angular_velocity=w_world)
    rng = np.random.default_rng(5)
    for _ in range(5):
        values = {**dict(zip((*qs, *us), rng.uniform(-1.2, 1.2, 10), strict=True)), r: 0.3}
        for mine, theirs in zip(
            c.no_slip.values(), (model.nonholonomic["roll_x"], model.nonholonomic["roll_y"]), strict=True
        ):
            assert float(mine.evalf(subs=values)) == pytest.approx(float(theirs.evalf(subs=values)), abs=1e-12)
        np.testing.assert_allclose(num(c.point, values), [values[X], values[Y], 0.0], atol=1e-12)


def test_the_planes_force_is_read_from_the_multipliers():
    c = contact_of(ellipsoid(1, 2, 3), names=("rx", "ry", "h"))
    f = c.force("contact", on="the body")
    assert tuple(f.components) == (multiplier("rx"), multiplier("ry"), multiplier("h"))
    assert f.route == "multipliers" and f.columns == ("contact.x", "contact.y", "contact.normal")
    g = c.force("ground", normal=sp.Symbol("m") * 9.81)
    assert g.route == "multipliers + newton" and g.components[2] == sp.Symbol("m") * 9.81


def test_bad_declarations_are_refused_saying_what_is_allowed():
    n = sp.symbols("n1:4", real=True)
    with pytest.raises(InputError, match="direction"):
        support_surface(sp.Integer(2), n)  # a sphere's radius: the support of unit normals only
    with pytest.raises(InputError, match="homogeneous"):
        support_surface(sp.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2 + 1), n)
    with pytest.raises(InputError, match="exactly one"):
        rolling_contact(sphere(1), R, (x, y, z), (vx, vy, vz))
    with pytest.raises(InputError, match="three different"):
        contact_of(sphere(1), names=("a", "a", "b"))
    with pytest.raises(InputError, match="axis"):
        disk_edge(1, axis="w")
    s = sp.symbols("s1:4", real=True)
    with pytest.raises(InputError, match="quadric"):
        implicit_surface(s[0] ** 4 + s[1] ** 4 + s[2] ** 4 - 1, s)  # a superellipsoid: give its support
    with pytest.raises(InputError, match="quadric"):
        implicit_surface(s[0] ** 2 + s[1] ** 2 + s[2] ** 2 + sp.sin(s[0]) - 1, s)
