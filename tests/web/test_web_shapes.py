"""Declared shapes, one class per kind, compiled into one typed table and drawn by one
renderer per kind: every kind drawn where its declaration puts it, the compiled table
survives the JSON cache, and a system that declares no visuals is drawn as a point."""

from __future__ import annotations

import json

import numpy as np
import pytest

from nmkane_core import Parameter, System, register, simulate
from nmkane_core.declare import visuals as decl
from nmkane_core.kernel.visuals import CompiledShape, compile_visuals
from nmkane_core.run.registry import unregister
from web import geometry as geo
from web.declared import RENDERERS, DeclaredScene

NAME, BARE = "test-shapes-skate", "test-shapes-bare"


def skate_model():
    import sympy as sp

    from nmkane_core import MechanicalModel, plain_symbols

    x, y, th = plain_symbols("x y theta")
    u1, u2, u3 = plain_symbols("u1 u2 u3")
    m = sp.Symbol("m", positive=True)
    return MechanicalModel(
        q=(x, y, th),
        u=(u1, u2, u3),
        params=(m,),
        C=sp.eye(3),
        D=sp.zeros(3, 1),
        Q=sp.diag(m, m, m / 10),
        P=sp.zeros(3, 1),
        nonholonomic={"no_side_slip": -sp.sin(th) * u1 + sp.cos(th) * u2},
        u_independent=(u1, u3),
        energy=m / 2 * (u1**2 + u2**2) + m / 20 * u3**2,
    )


def every_kind():
    """One shape of every kind, sizes of the parameter m (so a new m reshapes them)."""
    import sympy as sp

    from nmkane_core import plain_symbols

    x, y, th = plain_symbols("x y theta")
    m = sp.Symbol("m", positive=True)
    return decl.Visuals(
        frames=(decl.Frame("skate", (x, y, 0), decl.rot_z(th)),),
        shapes=(
            decl.ground(-0.1),
            decl.box("blade", "skate", (0.4 * m, 0.03, 0.1), (0, 0, 0.05)),
            decl.cylinder("wheel", "skate", 0.1 * m, 0.02, "y", (0.2, 0, 0.1)),
            decl.sphere("toe", 0.05, "skate", (0.2, 0, 0.1)),
            decl.rod("mast", "skate", (0, 0, 0), (0, 0, m), 0.02),
            decl.sphere("ball", 0.1, at=(x, y, 1)),
            decl.segments("tether", [((0, 0, 0.5), (x, y, 0.5))]),
            decl.polyline("rail", [(-1, -1, 0), (1, -1, 0), (1, 1, 0)]),
            decl.trace("path", (x, y, 0.01)),
            decl.strip("ramp", [(-2, 0, 0), (-1, 0, 0.5 * m)], 1.0, "y"),
            decl.label("name", "skate", at=(x, y, 1.2)),
            decl.label("tag", "blade", frame="skate", offset=(0, 0, 0.3)),
        ),
    )


def declare(name: str, visuals) -> System:
    return System(
        name=name,
        variants=skate_model,
        parameters={"m": Parameter(1.0, 0.0, 10.0, "kg")},
        default_initial={"x": 0.0, "y": 0.0, "theta": 0.0, "u1": 1.0, "u3": 0.5},
        default_dt=0.01,
        default_t_final=2.0,
        visuals=visuals,
    )


@pytest.fixture(scope="module")
def systems():
    yield register(declare(NAME, every_kind)), register(declare(BARE, None))
    unregister(NAME)
    unregister(BARE)


def test_every_declared_kind_has_one_renderer():
    assert set(RENDERERS) == set(decl.SHAPES.values())
    for kind, cls in decl.SHAPES.items():
        assert cls.kind == kind and not set(cls.PARAM_FIELDS) & set(cls.STATE_FIELDS)


def test_the_compiled_table_survives_the_json_cache(systems):
    cv = compile_visuals(systems[0])
    assert [s.kind for s in cv.shapes] == [s.kind for s in every_kind().shapes]
    for cs in cv.shapes:
        assert CompiledShape.from_json(json.loads(json.dumps(cs.to_json()))) == cs
    by = {s.name: s for s in cv.shapes}
    assert by["ground"].fixed and by["ramp"].fixed and by["rail"].fixed is False  # points: may move
    assert not by["blade"].fixed and not by["ball"].fixed
    sizes = cv.sizes({"m": 2.0})
    blade = by["blade"].resolve(sizes)
    assert isinstance(blade, decl.Box) and blade.size.tolist() == [0.8, 0.03, 0.1]
    assert by["mast"].resolve(sizes).end.tolist() == [0.0, 0.0, 2.0]


def test_every_kind_is_drawn_where_its_declaration_puts_it(systems, module_server):
    system = systems[0]
    run = simulate({"system": NAME, "params": {"m": 2.0}}, progress=False)
    scene = DeclaredScene(module_server.scene, system)
    scene.install(run, run.settings["params"])
    k = len(run.t) // 2
    scene.pose(k)
    x, y, th = (float(run.state[n][k]) for n in ("x", "y", "theta"))
    node = lambda path: module_server.scene.get_handle_by_name(f"/sys/{NAME}/{path}")  # noqa: E731
    np.testing.assert_allclose(node("frames/skate").position, (x, y, 0), atol=1e-5)
    np.testing.assert_allclose(geo.rotate(node("frames/skate").wxyz, (1, 0, 0)), (np.cos(th), np.sin(th), 0), atol=1e-5)
    assert tuple(node("frames/skate/blade").dimensions) == pytest.approx((0.8, 0.03, 0.1))
    wheel = node("frames/skate/wheel").vertices - np.array([0.2, 0, 0.1])  # a disk: a round rim's mesh
    assert np.hypot(wheel[:, 0], wheel[:, 2]).max() == pytest.approx(0.2)
    assert np.abs(wheel[:, 1]).max() == pytest.approx(0.01)
    assert tuple(node("frames/skate/mast").position) == pytest.approx((0, 0, 1.0))  # the rod's middle
    np.testing.assert_allclose(node("world/ball").position, (x, y, 1), atol=1e-5)
    np.testing.assert_allclose(node("world/name").position, (x, y, 1.2), atol=1e-5)
    np.testing.assert_allclose(node("world/tether").points[0], [(0, 0, 0.5), (x, y, 0.5)], atol=1e-5)
    np.testing.assert_allclose(node("world/rail").points[:, 0], [(-1, -1, 0), (1, -1, 0)], atol=1e-6)
    trace = node("world/path").points
    np.testing.assert_allclose(trace[-1, 1], (run.state["x"][-1], run.state["y"][-1], 0.01), atol=1e-5)
    assert tuple(node("ground").position) == pytest.approx((0, 0, -0.1))
    assert node("world/ramp").vertices.max(axis=0)[2] == pytest.approx(1.0)  # 0.5 m
    assert tuple(node("frames/skate/tag").position) == pytest.approx((0, 0, 0.3))
    lo, hi = scene.bounds()
    assert hi[2] >= 1.0 and lo[0] > -1.5  # the ball's path is inside the bounds, the fixed ramp and rail not
    assert scene.extent == pytest.approx(0.8)  # the largest solid: the blade (the ramp's half length: 0.71)
    ghost = DeclaredScene(module_server.scene, system, ghost=(255, 0, 0), index=1)
    ghost.install(run, run.settings["params"])
    ghost_node = lambda path: module_server.scene.get_handle_by_name(f"/sys/{NAME}/ghost1/{path}")  # noqa: E731
    assert tuple(ghost_node("frames/skate/blade").color) == (255, 0, 0)
    assert ghost_node("frames/skate/blade").opacity < 1
    for fixed in ("world/ramp", "ground", "world/name", "frames/skate/tag"):  # drawn once, by the main scene
        assert ghost_node(fixed) is None, fixed


def test_a_system_without_visuals_is_drawn_as_a_point_at_its_coordinates(systems, module_server):
    run = simulate({"system": BARE}, progress=False)
    scene = DeclaredScene(module_server.scene, systems[1])
    scene.install(run, run.settings["params"])
    k = len(run.t) - 1
    scene.pose(k)
    point = module_server.scene.get_handle_by_name(f"/sys/{BARE}/world/point")
    np.testing.assert_allclose(point.position, [run.state[n][k] for n in ("x", "y", "theta")], atol=1e-5)
    assert module_server.scene.get_handle_by_name(f"/sys/{BARE}/world/trace").points.shape[0] > 10


@pytest.mark.parametrize("lean_deg", [0.0, 10.0, 30.0, 60.0])
def test_a_leaning_disk_stays_on_the_ground(lean_deg):
    """A coin modelled as a thin disk touches the ground with its mid-plane's rim: drawn with a
    flat rim (a cylinder) its edge sank by length/2 · sin(lean) into the floor (issue 43, item 6);
    the round rim sinks at most length/2 · (1 − cos(lean)) and reaches the ground within that."""
    r, w = 1.0, 0.08
    verts, faces = geo.disk_mesh(r, w, (0.0, 1.0, 0.0))
    lean = np.radians(lean_deg)
    # the disk's axis y turned by the lean about x, its centre at the thin disk's height r cos(lean)
    R = np.array([[1, 0, 0], [0, np.cos(lean), -np.sin(lean)], [0, np.sin(lean), np.cos(lean)]])
    z = (verts @ R.T)[:, 2] + r * np.cos(lean)
    sink = -z.min()
    assert sink <= w / 2 * (1 - np.cos(lean)) + 1e-6
    assert sink >= -1e-3 * r  # and touches it (within the mesh's facets)
    assert sink <= np.tan(lean / 2) * w / 2 * np.sin(lean) + 1e-6  # the flat rim's: w/2 · sin(lean)
    tri = verts[faces]
    assert np.all(np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) > 0)
