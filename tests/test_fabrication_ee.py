"""Fabrication with an end-effector: link 3 = bars S_3L, RE_3 + P in export, carving, checks."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from paraloop_core import design, pipeline
from paraloop_core.algebra import dq, poly
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import endlink, export, grounding, parts
from paraloop_core.linkage import loops
from paraloop_core.realization.endeffector import EndEffector
from paraloop_core.realization.facecollide import inside_closed

SHADING = Path(__file__).resolve().parents[1] / "assets" / "designs" / "shading-panel.json"
SPEC = parts.PartSpec(size_mm=500.0)


@pytest.fixture(scope="module")
def sol() -> pipeline.Solution:
    return pipeline.solve(design.load_design(SHADING))


@pytest.fixture(scope="module")
def exported(sol) -> export.ExportResult:
    r = sol.realization
    return export.export_parts(r.joint_factors, r.points, r.radius, spec=SPEC,
                                    ground=False, effector=sol.end_effector)


def _inside_p(sol, n: int, seed: int = 0) -> np.ndarray:
    """``n`` random points inside P (home frame, design units)."""
    e = sol.end_effector.effector
    rng = np.random.default_rng(seed)
    lo, hi = e.vertices.min(0), e.vertices.max(0)
    x = lo + rng.random((40 * n, 3)) * (hi - lo)
    x = x[inside_closed(e.vertices, e.faces, x)]
    assert len(x) >= n
    return x[:n]


def _surface_p(e: EndEffector, n: int, seed: int = 1, skip: int = 0) -> np.ndarray:
    """P's vertices and ``n`` random points on its faces but the first ``skip`` (home frame,
    design units)."""
    rng = np.random.default_rng(seed)
    w = rng.dirichlet(np.ones(3), n)
    tri = e.vertices[e.faces[rng.integers(skip, len(e.faces), size=n)]]
    return np.concatenate([e.vertices, np.einsum("nk,nkd->nd", w, tri)])


def test_link3_part_is_the_end_effector_with_its_bars(sol, exported):
    files = dict(exported.files)
    scale = exported.report["scale_mm_per_unit"]
    link3 = trimesh.load(io.BytesIO(files["link_3.stl"]), file_type="stl")
    assert link3.is_watertight
    # P's volume is in the link-3 part, untouched (no joint zone reaches P here)
    inside = inside_closed(link3.vertices, link3.faces, _inside_p(sol, 200) * scale)
    assert inside.all()
    ee = exported.report["end_effector"]
    assert ee["method"] == "closed" and ee["kept_mm3"] == pytest.approx(ee["volume_mm3"])
    # no bar S_3E_3: its midpoint (away from P and the new bars) is not in the part
    pts = sol.realization.points
    mid = 0.5 * (pts[6] + pts[7])
    assert not inside_closed(link3.vertices, link3.faces, mid[None] * scale)[0]
    r = sol.end_effector.end_link()
    assert min(np.linalg.norm(mid - r[1]), np.linalg.norm(mid - r[2])) > 0.1


def test_end_effector_export_verifies(exported):
    ver = exported.report["verification"]
    assert ver["ok"] and ver["watertight"] and ver["collisions"] == 0
    assert ver["samples"] == 720 and all(p["watertight"] for p in ver["parts"])
    assert 0 < ver["continuous_min_gap_mm"] <= ver["min_gap_mm"]
    # P (far from the other links here) bounds the link-3 pairs, not the joint gaps
    far = [p for p in ver["pairs"] if 3 in p["links"] and not p["adjacent"]]
    assert min(p["min_gap_mm"] for p in far) > 10.0


def test_link3_capsules_cover_the_end_effector(sol):
    """The broad phase and the continuity reach of the verification use the part's
    capsules: every point of P's surface lies in one."""
    r = sol.realization
    scale = parts.design_scale(r.points, SPEC.size_mm)
    el = endlink.end_link(sol.end_effector, r.points)
    asm = parts.build_assembly(r.joint_factors, r.points, r.radius, SPEC,
                               end_link=(el.bars, endlink.solid_manifold(el, scale)))
    part = asm.parts[3]
    x = _surface_p(sol.end_effector.effector, 500) * scale
    d = export.segment_distance(part.capsules[None, :, 0], part.capsules[None, :, 1],
                                     x[:, None], x[:, None]) - part.radii[None]
    assert np.all(d.min(axis=1) <= 1e-6)
    assert len(part.capsules) > 2  # the two bars, P's chain and the hardware


def _moved_effector(sol, link: int, scale: float) -> EndEffector:
    """The design's P scaled about its centroid and centred on the bar of ``link`` (overlapping
    that link's design space at home; only for carving, not a realized design)."""
    e, pts = sol.end_effector.effector, sol.realization.points
    v = (e.vertices - e.vertices.mean(0)) * scale + 0.5 * (pts[2 * link] + pts[2 * link + 1])
    return EndEffector(v, e.faces, e.edges, e.L, e.R, True)


@pytest.mark.parametrize("moved", [False, True])
def test_carved_spaces_avoid_the_end_effector(sol, moved):
    """Dense samples: no other carved region meets P. Moved onto link 5's bar, P overlaps the
    spaces of links 5 and 0 over the cycle: without the fixed-solid pass they would meet it."""
    r = sol.realization
    ee = _moved_effector(sol, 5, 0.6) if moved else sol.end_effector.effector
    radius = float(np.median(r.design_space_radii))
    cv, bodies = export.carve_design_spaces(r.joint_factors, r.points, r.radius, radius,
                                                 spec=SPEC, resolution=64, effector=ee)
    fixed = [o for o in cv.report["operations"] if o["kind"] == "fixed"]
    assert sorted(o["target"] for o in fixed) == [0, 1, 2, 4, 5]
    assert moved or bodies[3] is not None  # the moved P leaves link 3 too thin to mesh
    # link 3's potential space covers P (before the wire cut, which may trim near other bars)
    el = endlink.end_link(ee, r.points)
    scale = parts.design_scale(r.points, SPEC.size_mm)
    sp3 = endlink.link_space(el, radius, scale, 64)
    surf = _surface_p(ee, 1000)
    assert np.all(cKDTree(sp3.centers()).query(surf)[0] <= sp3.half_diagonal + 1e-9)
    u = (np.arange(720) + 0.5) / 720
    poses = dq.to_matrix(loops.link_poses(r.joint_factors, poly.param_to_t(u)))
    for a in (0, 1, 2, 4, 5):
        sp = cv.spaces[a]
        rel = np.linalg.inv(poses[:, a]) @ poses[:, 3]  # link 3 in link a's home frame
        moved_p = np.einsum("tij,nj->tni", rel[:, :3, :3], surf) + rel[:, None, :3, 3]
        dist = cKDTree(sp.centers()).query(moved_p.reshape(-1, 3))[0]
        assert dist.min() > sp.half_diagonal, a  # P's surface is outside a's region ...
        back = np.linalg.inv(rel[::60])  # ... and no centre of a lies inside P
        c = np.einsum("tij,nj->tni", back[:, :3, :3], sp.centers()) + back[:, None, :3, 3]
        assert not inside_closed(ee.vertices, ee.faces, c.reshape(-1, 3)[::13]).any(), a


def test_open_end_effector_is_thickened(sol):
    """An open P (here the panel without one face) is printed as a sheet of SHEET_MM."""
    e = sol.end_effector.effector
    r = sol.realization
    sheet = EndEffector(e.vertices, e.faces[1:], e.edges, e.L, e.R, False)
    scale = parts.design_scale(r.points, SPEC.size_mm)
    el = endlink.end_link(sheet, r.points)
    solid = endlink.solid_manifold(el, scale)
    assert el.method == "thickened" and solid.status().name == "NoError"
    area = trimesh.Trimesh(e.vertices * scale, e.faces[1:]).area
    assert solid.volume() == pytest.approx(area * endlink.SHEET_MM, rel=0.1)
    mask = endlink.solid_mask(el, _surface_p(e, 100, skip=1), 0.0, scale)
    assert mask.all()



def test_grounding_uses_the_end_link_capsules():
    """Link 3's skeleton is replaced by the given capsules: the bar S_3E_3 split in two
    gives the same column, and a huge ball on link 3 leaves no collision-free column."""
    from test_parts import example_loop

    jf, pts, radius = example_loop()
    kw = {"bar_radius": radius, "hub_radius": radius, "hub_extent": 0.0}
    mid = 0.5 * (pts[6] + pts[7])
    split = [(pts[6], mid, radius), (mid, pts[7], radius)]
    caps = grounding.link_capsules(pts, radius, radius, 0.0, split)
    assert [c[:2] for c in caps[3] if c[3] == -1] == [c[:2] for c in split]
    g0 = grounding.ground_column(jf, pts, **kw)
    g1 = grounding.ground_column(jf, pts, **kw, end_link=split)
    assert g1.ground_z == pytest.approx(g0.ground_z) and g1.clearance == pytest.approx(
        g0.clearance)
    fat = [(pts[6], pts[7], radius), (mid, mid, 3.0 * np.ptp(pts[:, 2]))]
    with pytest.raises(FabricationError):
        grounding.ground_column(jf, pts, **kw, end_link=fat)


def test_carved_parts_with_end_effector_verify(sol):
    r = sol.realization
    res = export.export_parts(r.joint_factors, r.points, r.radius, spec=SPEC,
                                   ground=False, effector=sol.end_effector, samples=90,
                                   space_radius=float(np.median(r.design_space_radii)),
                                   resolution=64)
    ver = res.report["verification"]
    assert ver["ok"] and ver["watertight"] and res.report["carving"]["meshed"][3]
    ee = res.report["end_effector"]
    assert ee["kept_mm3"] == pytest.approx(ee["volume_mm3"])


def test_closed_end_effector_is_oriented():
    """A closed P with a face turned the wrong way, or inside out, still prints as itself."""
    from paraloop_core.realization import endeffector as eem

    p = eem.builtin("panel", 1.0)  # 2 x 1 x 0.05
    flipped = p.faces.copy()
    flipped[0] = flipped[0][::-1]
    for faces in (flipped, p.faces[:, ::-1]):
        ee = EndEffector(p.vertices, faces, eem.unique_edges(faces), 0, 1, True)
        el = endlink.end_link(ee, np.zeros((12, 3)))
        assert el.method == "closed"
        assert endlink.solid_manifold(el, 10.0).volume() == pytest.approx(100.0, rel=1e-5)


def test_cli_export_of_the_end_effector_design(tmp_path):
    from app.cli.main import main

    out = tmp_path / "parts"
    code = main(["export", "assets/designs/shading-panel.json", "--out", str(out),
                 "--size-mm", "500", "--no-ground", "--samples", "90", "--quiet"])
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert report["verification"]["ok"]
    assert report["end_effector"]["method"] == "closed"
