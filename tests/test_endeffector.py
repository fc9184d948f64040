"""End-effector polyhedra (loading, validation) and the realization with an end-effector."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from paraloop_core import design, pipeline
from paraloop_core.algebra import dq, poly
from paraloop_core.errors import EndEffectorError, ParaloopError, RealizationError
from paraloop_core.linkage import loops
from paraloop_core.realization import ee_certificate as eec
from paraloop_core.realization import endeffector as eem
from paraloop_core.realization import realize_ee as ree
from paraloop_core.realization.clearance import motion_data, segment_distance
from paraloop_core.realization.collision import check_polylines
from paraloop_core.realization.facecollide import (
    mesh_segment_collisions,
    mesh_segment_min_distance,
    segment_triangle_distance,
)
from paraloop_core.realization.realize import realize

SUN = Path(__file__).resolve().parents[1] / "assets" / "designs" / "sun-disc.json"


@pytest.fixture(scope="module")
def sun():
    sol = pipeline.solve(design.load_design(SUN), realize=False)
    return sol.loop.joint_factors, sol.reference


# ---------------------------------------------------------------- meshes and validation


def test_builtins_are_closed_triangle_meshes():
    d, p = eem.builtin("disc", 0.5), eem.builtin("panel", 2.0)
    assert d.closed and p.closed and len(d.faces) == 96 and len(p.faces) == 12
    assert np.ptp(d.vertices[:, 0]) == pytest.approx(1.0)
    assert np.ptp(p.vertices, axis=0) == pytest.approx([4.0, 2.0, 0.1])
    with pytest.raises(EndEffectorError, match="unknown built-in"):
        eem.builtin("sphere")


@pytest.mark.parametrize(
    ("vertices", "faces", "reason", "match"),
    [
        (np.eye(4, 3), np.array([[0, 1, 2, 3]]), "not-triangles", "triangles"),
        (np.eye(3), np.array([[0, 1, 5]]), "bad-index", "indices"),
        (np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), np.array([[0, 1, 2]]),
         "not-finite", "not finite"),
        (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]]),
         np.array([[0, 1, 2], [0, 1, 3]]), "degenerate", "zero area"),
        (np.eye(3), np.array([[0.0, 1, 2]]), "bad-index", "integers"),
    ],
)
def test_malformed_meshes_are_refused(vertices, faces, reason, match):
    with pytest.raises(ParaloopError, match=match) as exc:
        eem.polyhedron(vertices, faces)
    assert exc.value.reason == reason


def test_large_meshes_refused_or_enclosed():
    sphere = trimesh.creation.icosphere(subdivisions=2)  # 320 faces
    with pytest.raises(EndEffectorError, match="more than the limit") as exc:
        eem.polyhedron(sphere.vertices, sphere.faces, max_faces=100, simplify=False)
    assert exc.value.reason == "too-large"
    box = eem.polyhedron(sphere.vertices, sphere.faces, max_faces=100)  # hull 320 > 100: OBB
    assert len(box.faces) == 12 and box.closed
    torus = trimesh.creation.torus(1.0, 0.3, major_sections=32, minor_sections=16)
    hull = eem.polyhedron(torus.vertices, torus.faces, max_faces=len(torus.faces) - 1)
    assert hull.closed and len(hull.faces) < len(torus.faces)
    # enclosing: every original vertex lies inside or on the convex hull
    tri = hull.vertices[hull.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = hull.vertices.mean(0)
    n *= np.sign(np.sum(n * (tri[:, 0] - centre), 1))[:, None]  # outward
    side = np.einsum("fc,vfc->vf", n, torus.vertices[:, None] - tri[None, :, 0])
    assert np.all(side <= 1e-9)


def test_load_stl_obj_glb(tmp_path):
    box = trimesh.creation.box([1.0, 2.0, 3.0])
    for ext in ("stl", "obj", "glb"):
        path = tmp_path / f"box.{ext}"
        box.export(path)
        p = eem.load_mesh(path)
        assert p.closed and len(p.faces) == 12 and len(p.vertices) == 8  # STL copies merged
        assert np.ptp(p.vertices, axis=0) == pytest.approx([1.0, 2.0, 3.0])
    bad = tmp_path / "flat.stl"
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 0, 1]], [[0, 1, 2], [0, 1, 3]],
                    process=False).export(bad)
    with pytest.raises(EndEffectorError, match="zero area"):
        eem.load_mesh(bad)
    with pytest.raises(EndEffectorError, match="not found"):
        eem.load_mesh(tmp_path / "missing.stl")
    junk = tmp_path / "junk.stl"
    junk.write_bytes(b"\x00garbage")
    with pytest.raises(EndEffectorError):
        eem.load_mesh(junk)


def test_anchors_closest_to_axes_or_flagged(sun):
    jf, ref = sun
    ee = eem.attach(eem.builtin("disc", 0.4), ref, jf)
    ax = loops.factor_axes(jf)
    dist = [np.linalg.norm(np.cross(ee.vertices, ax[i, :3]) - ax[i, 3:], axis=1) for i in (2, 3)]
    assert ee.L == np.argmin(dist[0]) and ee.R == np.argmin(dist[1])
    assert np.allclose(ee.vertices, dq.transform_points(ref, eem.builtin("disc", 0.4).vertices))
    flagged = eem.attach(eem.builtin("disc", 0.4), ref, jf, L=3, R=7)
    assert (flagged.L, flagged.R) == (3, 7)
    with pytest.raises(EndEffectorError, match="vertex index"):
        eem.attach(eem.builtin("disc", 0.4), ref, jf, L=1000)


def test_initial_polyline_minimizes_the_routed_length_squares(sun):
    jf, ref = sun
    ee = eem.attach(eem.builtin("disc", 0.4), ref, jf)
    anchors = ee.vertices[[ee.L, ee.R]]

    def energy(v):
        path = np.concatenate([v[:3], anchors, v[3:], v[:1]])  # V0 V1 V2 L R V3 V4 V5 V0
        legs = np.diff(path, axis=0)
        keep = np.ones(len(legs), bool)
        keep[3] = False  # L -> R is rigid, not part of eq. 11
        return np.sum(legs[keep] ** 2)

    v0, u = eem.initial_polyline(jf, anchors)
    rng = np.random.default_rng(0)
    for _ in range(20):
        assert energy(v0) <= energy(v0 + 1e-3 * rng.normal(size=(6, 1)) * u) + 1e-12
    held, _ = eem.initial_polyline(jf, anchors, {2: 0.3})
    q, _ = eem.axis_frames(jf)
    assert u[2] @ (held[2] - q[2]) == pytest.approx(0.3)
    with pytest.raises(EndEffectorError, match="reference"):
        eem.attach(eem.builtin("disc", 0.4), np.zeros(8), jf)


# ---------------------------------------------------------------- realization


def _dense_check(r: eec.EndEffectorRealization, samples: int = 1500) -> None:
    """Every end-effector row recomputed in the base frame with loops.link_poses."""
    jf, ee = r.realization.joint_factors, r.effector
    t = poly.param_to_t(np.linspace(0.0, 1.0, samples, endpoint=False))
    poses = loops.link_poses(jf, t)  # (T, 6, 8)
    faces = dq.transform_points(poses[:, 3, None], ee.vertices[None])[:, ee.faces]  # (T,F,3,3)
    fixed, moving = eec.ee_segments(r)
    for n, (f, m, (_, lb)) in enumerate(zip(fixed, moving, r.ee_links, strict=True)):
        mm = dq.transform_points(poses[:, lb, None], m[None])  # (T, 2, 3)
        if np.isnan(f).any():
            dense = segment_triangle_distance(mm[:, None], faces).min()
        else:
            ff = dq.transform_points(poses[:, 3, None], f[None])
            dense = segment_distance(ff[:, 0], ff[:, 1], mm[:, 0], mm[:, 1]).min()
        assert dense >= r.ee_required[n] - 1e-9, r.ee_labels[n]
        if r.ee_exact[n]:
            assert r.ee_distance[n] <= dense + 1e-9, r.ee_labels[n]
        else:  # a certified lower bound
            assert r.ee_distance[n] <= dense + 1e-9 and r.ee_distance[n] >= r.ee_required[n]


def test_fig9_with_and_without_end_effector(sun):
    jf, ref = sun
    plain = realize(jf)
    ee = eem.attach(eem.builtin("disc", 0.4), ref, jf)
    r = ree.realize_with_effector(jf, ee)
    real = r.realization
    assert real.min_clearance >= 2 * real.radius and plain.min_clearance >= 2 * plain.radius
    assert not np.any(real.pairs[:, :2] == 6) and len(real.pairs) == 35
    assert np.all(r.ee_distance >= r.ee_required)
    assert np.all(real.design_space_radii >= real.radius - 1e-12)
    assert not np.allclose(real.points, plain.points)  # the realized polylines differ
    _dense_check(r)
    out = eec.ee_to_dict(r)
    assert out["L"] == ee.L and len(out["pairs"]) == len(r.ee_labels)
    assert out["min_clearance"] >= 0
    assert eec.effector_at(r, np.array([np.inf, 0.3])).shape == (2, len(ee.vertices), 3)
    assert np.allclose(eec.effector_at(r, np.array([np.inf]))[0], ee.vertices)


def test_random_loops_certified():
    from paraloop_core.validation.table1 import random_loops

    jfs = random_loops(4, 3).reshape(-1, 6, 8)
    done = 0
    for jf in jfs:
        base = realize(jf)
        mid = 0.5 * (base.thin[2] + base.thin[3])
        ee = eem.attach(eem.builtin("panel", 0.04 * base.length), dq.translation(mid), jf)
        try:
            r = ree.realize_with_effector(jf, ee, max_k=8)
        except RealizationError as exc:
            assert exc.reason == "cap-reached"
            continue
        _dense_check(r, samples=800)
        done += 1
    assert done >= 2


def test_only_the_end_effector_collides(sun):
    jf, _ = sun
    base = realize(jf)
    assert not check_polylines(jf, base.thin)  # the bars alone are collision-free
    # a small tetrahedron in link 3, placed where bar 0 passes at t = 0.7
    mid = 0.5 * (base.thin[5] + base.thin[0])  # segment 0 = [V_5, V_0], link 0 = base
    at = loops.link_poses(jf, np.array([0.7]))[0, 3]
    centre = dq.transform_points(dq.inv(at), mid)
    tet = eem.polyhedron(centre + 0.05 * np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1],
                                                   [-1, -1, 1]]),
                         np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]]))
    ee = eem.attach(tet, dq.IDENTITY, jf)
    assert ree.thin_collides(jf, ee, base.thin)
    # the exact face kernel sees P hit bar 0 (moving by R_30) at t = 0.7
    md = motion_data(loops.relative_motion(jf, 3, 0)[None])
    seg = base.thin[[5, 0]][None]
    assert mesh_segment_collisions(md, np.zeros(1, int), ee.vertices, ee.faces, ee.edges, seg)[0]
    dist, t = mesh_segment_min_distance(md, np.zeros(1, int), ee.vertices, ee.faces, ee.edges,
                                        seg)
    assert dist[0] < 1e-12


def test_bad_parameters(sun):
    jf, ref = sun
    ee = eem.attach(eem.builtin("disc", 0.4), ref, jf)
    with pytest.raises(RealizationError, match="ee_clearance"):
        ree.realize_with_effector(jf, ee, ee_clearance=-1.0)
    with pytest.raises(RealizationError, match="at most five"):
        ree.realize_with_effector(jf, ee, fixed={i: 0.0 for i in range(6)})
    with pytest.raises(RealizationError, match="fixed entries"):
        ree.realize_with_effector(jf, ee, fixed={7: 0.0})
