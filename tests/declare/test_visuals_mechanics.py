"""Visuals attached to sympy.physics.mechanics frames and points (a system built from bodies)."""

import sympy as sp
import sympy.physics.mechanics as me

from nmkane_core.declare.visuals import Frame, rot_x, rot_z


def test_a_frame_from_a_reference_frame_and_a_point():
    x, y, q, r = me.dynamicsymbols("x y q r")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (q, N.z))
    B = A.orientnew("B", "Axis", (r, A.x))
    O = me.Point("O")
    P = O.locatenew("P", x * N.x + y * N.y + 2 * A.z)
    f = Frame.of("body", B, P, N, O)
    assert f.name == "body" and f.origin == (x, y, 2)
    assert sp.simplify(sp.Matrix(f.rotation) - rot_z(q) * rot_x(r)) == sp.zeros(3, 3)
    # the body's x axis in world coordinates is the first column
    assert sp.simplify(sp.Matrix(f.rotation)[:, 0] - B.x.to_matrix(N)) == sp.zeros(3, 1)
