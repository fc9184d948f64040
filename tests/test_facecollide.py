"""Exact edge-face collision checks and minimum distances against dense sampling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from paraloop_core.algebra import poly
from paraloop_core.linkage import loops
from paraloop_core.realization import facecollide as fc
from paraloop_core.realization.clearance import motion_data, moving_segments
from paraloop_core.realization.endeffector import panel, unique_edges
from paraloop_core.validation.table1 import random_loops

U = np.linspace(0.0, 1.0, 3001, endpoint=False)


def _dense_min(md, tri_faces, seg):
    """Sampled + locally refined min over the cycle of dist(mesh, moving seg) (an upper bound
    of the true minimum, close to it)."""
    def at(u):
        t = poly.param_to_t(np.atleast_1d(np.mod(u, 1.0)))
        moved = moving_segments(md, np.zeros(1, int), seg[None], t[None])[0]  # (T, 2, 3)
        return fc.segment_triangle_distance(moved[:, None], tri_faces[None]).min(axis=1)

    vals = at(U)
    best = float(vals.min())
    for i in np.argsort(vals)[:3]:
        res = minimize_scalar(lambda u: float(at(u)[0]), bounds=(U[i] - 1 / 3000, U[i] + 1 / 3000),
                              method="bounded", options={"xatol": 1e-12})
        best = min(best, float(res.fun))
    return best


def _random_case(rng, jf, j):
    md = motion_data(loops.relative_motion(jf, 3, j)[None])
    verts = rng.normal(size=(4, 3))  # a random tetrahedron
    faces = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]])
    return md, verts, faces, rng.normal(size=(2, 3)) + rng.normal(size=3)  # hits and misses


def test_point_and_segment_triangle_distance_against_sampling():
    rng = np.random.default_rng(0)
    tri = rng.normal(size=(50, 3, 3))
    x = rng.normal(size=(50, 3)) * 2
    seg = rng.normal(size=(50, 2, 3))
    w = rng.dirichlet(np.ones(3), size=4000)  # points of the triangles
    s = np.linspace(0, 1, 200)
    for b in range(50):
        pts = w @ tri[b]
        assert fc.point_triangle_distance(x[b], tri[b]) <= np.linalg.norm(pts - x[b], axis=1).min()
        assert fc.point_triangle_distance(x[b], tri[b]) >= \
            np.linalg.norm(pts - x[b], axis=1).min() - 0.05
        line = seg[b, 0] + s[:, None] * (seg[b, 1] - seg[b, 0])
        dense = np.linalg.norm(pts[:, None] - line[None], axis=-1).min()
        exact = fc.segment_triangle_distance(seg[b], tri[b])
        assert exact <= dense + 1e-12 and exact >= dense - 0.06


def test_segment_piercing_triangle_has_distance_zero():
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert fc.segment_triangle_distance(np.array([[0.2, 0.2, -1], [0.2, 0.2, 1]]), tri) == 0.0
    assert fc.segment_triangle_distance(np.array([[2.0, 2, -1], [2, 2, 1]]), tri) == \
        pytest.approx(3.0 / np.sqrt(2.0))  # to the hypotenuse x + y = 1


@pytest.mark.parametrize("j", [0, 1, 2, 4, 5])
def test_min_distance_and_collision_match_dense_sampling(j):
    rng = np.random.default_rng(10 + j)
    jfs = random_loops(j, 2).reshape(-1, 6, 8)
    hits = 0
    for jf in jfs:
        for _ in range(3):
            md, verts, faces, seg = _random_case(rng, jf, j)
            idx = np.zeros(1, int)
            edges = unique_edges(faces)
            dist, t = fc.mesh_segment_min_distance(md, idx, verts, faces, edges, seg[None])
            dense = _dense_min(md, verts[faces], seg)
            scale = 1.0 + np.abs(verts).max() + np.abs(seg).max()
            assert dist[0] <= dense + 1e-9 * scale  # exact <= any sampled value
            assert dist[0] >= dense - 1e-6 * scale  # and attained (refined sampling finds it)
            # the reported time attains the minimum
            moved = moving_segments(md, idx, seg[None], t[None])[0, 0]
            at_t = fc.segment_triangle_distance(moved[None], verts[faces]).min()
            assert at_t == pytest.approx(dist[0], abs=1e-9 * scale)
            hit = fc.mesh_segment_collisions(md, idx, verts, faces, edges, seg[None])[0]
            assert hit == (dist[0] <= 1e-9 * scale)
            hits += hit
            lower, _ = fc.sphere_bound(md, idx, verts, seg[None])
            assert lower[0] <= dist[0] + 1e-9 * scale
    assert 0 < hits < 12  # both outcomes covered


def test_vertex_face_minimum_is_exact_for_a_face_interior_minimum():
    # a point circling the z axis at height 1 above a big horizontal triangle: distance 1
    # everywhere (rotation about z, degree-1 motion t - k)
    md = motion_data(poly.linear(np.array([0, 0, 0, 1.0, 0, 0, 0, 0]))[None])
    tri = np.array([[[-10.0, -10, 0], [10, -10, 0], [0, 10, 0]]])
    dist, _ = fc.vertex_face_min_distance(md, np.zeros(1, int), tri, np.array([[1.0, 0.5, 1.0]]))
    assert dist[0] == pytest.approx(1.0)


def test_segment_through_face_for_the_whole_cycle_collides():
    # the segment lies on the rotation axis and pierces the triangle at every t
    md = motion_data(poly.linear(np.array([0, 0, 0, 1.0, 0, 0, 0, 0]))[None])
    verts = np.array([[-1.0, -1, 0], [1, -1, 0], [0, 1, 0]])
    faces = np.array([[0, 1, 2]])
    seg = np.array([[[0.0, 0, -1], [0, 0, 1]]])
    idx = np.zeros(1, int)
    assert fc.mesh_segment_collisions(md, idx, verts, faces, unique_edges(faces), seg)[0]
    assert fc.mesh_segment_min_distance(md, idx, verts, faces, unique_edges(faces), seg)[0][0] \
        == 0.0


def test_inside_closed():
    box = panel(2.0, 2.0, 2.0)
    pts = np.array([[0.0, 0, 0], [0.9, -0.9, 0.5], [1.1, 0, 0], [0, 0, -3]])
    assert fc.inside_closed(box.vertices, box.faces, pts).tolist() == [True, True, False, False]
