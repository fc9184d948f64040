"""Local wall thickness (:mod:`fabrication.thickness`): known answers on simple solids."""

from __future__ import annotations

import fab_fixtures as F
import numpy as np
import pytest
import trimesh

from paraloop_core.fabrication import thickness


def test_known_walls():
    bar = trimesh.creation.cylinder(radius=1.0, height=50.0, sections=96)
    d = thickness.wall_thickness(bar, cap=8.0)
    # the side is 96 % of the surface: its chords are the polygon's width across flats
    assert np.percentile(d, 50) == pytest.approx(2 * np.cos(np.pi / 96), rel=1e-9)
    tube = trimesh.creation.annulus(r_min=3.0, r_max=5.0, height=10.0, sections=256)
    assert thickness.thickness_summary(tube, 2.0)["ok"]
    assert np.percentile(thickness.wall_thickness(tube, 8.0), 5) == pytest.approx(2.0, rel=1e-3)
    plate = trimesh.creation.box((10.0, 20.0, 3.0))
    d = thickness.wall_thickness(plate, cap=100.0, count=4000)
    faces = np.isclose(d, 3.0) | np.isclose(d, 10.0) | np.isclose(d, 20.0)
    assert faces.mean() > 0.999  # every ray leaves through the opposite face
    # the share of 3 mm chords is the big faces' share of the area (400 of 580 mm^2)
    assert np.mean(np.isclose(d, 3.0)) == pytest.approx(400 / 580, abs=0.03)


def test_cap_and_thin_fins_are_found():
    body = trimesh.creation.box((20.0, 20.0, 20.0))
    fin = trimesh.creation.box((1.0, 30.0, 30.0))  # 1 mm fin through the block
    part = trimesh.boolean.union([body, fin.apply_translation([0, 0, 0])], engine="manifold")
    s = thickness.thickness_summary(part, wall_mm=2.0)
    assert not s["ok"] and s["p5_mm"] == pytest.approx(1.0)
    assert thickness.wall_thickness(body, cap=5.0).max() == pytest.approx(5.0)  # clipped
    with pytest.raises(ValueError, match="cap > 0"):
        thickness.wall_thickness(body, cap=0.0)


def test_micrometre_folds_are_not_walls():
    """Two copies of a 3 mm plate 5 um apart stand in for the sliver folds of a boolean's
    float32 mesh: the layer 5 um under a face is skipped, the plate reads 3 mm."""
    plate = trimesh.creation.box((10.0, 20.0, 3.0))
    folded = trimesh.util.concatenate([plate, plate.copy().apply_translation([0, 0, 0.005])])
    d = thickness.wall_thickness(folded, cap=8.0, count=4000)
    big = np.isclose(d, 3.0, atol=0.006)  # the two big faces' share of the area
    assert big.mean() == pytest.approx(2 * 400 / (2 * 580), abs=0.03)
    assert np.percentile(d, 5) > 2.9


def test_broad_phase_drops_no_hit():
    """The runs' box pre-selection against every ray times every triangle (brute force:
    ``fab_fixtures.ray_hits``): the same first exits on a bent tube of long and short
    triangles."""
    a = trimesh.creation.annulus(r_min=2.0, r_max=3.5, height=40.0, sections=24)
    b = trimesh.creation.box((30.0, 4.0, 4.0))
    b.apply_translation([15.0, 0.0, 18.0])
    mesh = trimesh.boolean.union([a, b], engine="manifold")
    rng = np.random.default_rng(3)
    face = rng.integers(0, len(mesh.faces), 300)
    w = rng.dirichlet(np.ones(3), 300)
    origins = np.einsum("nk,nkd->nd", w, mesh.triangles[face])
    dirs = -mesh.face_normals[face]
    cap = 6.0
    got = thickness._first_exit(origins, dirs, mesh.triangles, cap)
    want = np.full(len(origins), cap)
    for k, (o, d) in enumerate(zip(origins, dirs, strict=True)):
        t = F.ray_hits(mesh.triangles, o, d)  # every crossing along the ray
        t = t[(t > thickness.FOLD * cap) & (t <= cap)]
        if len(t):
            want[k] = t.min()
    assert got == pytest.approx(want, abs=1e-9)
    assert (got < cap).mean() > 0.5  # the test measures walls, not only misses
