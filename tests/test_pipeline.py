"""Design -> result: the result JSON satisfies its documented contract."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from paraloop_core import design, pipeline
from paraloop_core.algebra import dq, poly
from paraloop_core.linkage import loops

ASSETS = Path(__file__).resolve().parents[1] / "assets" / "designs"


@pytest.fixture(scope="module")
def tv8_result():
    d = design.load_design(ASSETS / "tv8.json")
    return d, pipeline.result_to_dict(pipeline.solve(d, realize=False))


def test_motion_visits_the_poses(tv8_result):
    d, res = tv8_result
    c = np.array(res["motion"]["coefficients"])
    targets = pipeline.design_poses(d)
    for t, pose in zip(res["motion"]["pose_parameters"], targets, strict=True):
        at = poly.evaluate_pose(c, np.inf if t is None else t)
        assert np.allclose(dq.normalize(at), dq.normalize(pose), atol=1e-9)
    assert res["motion"]["pose_parameters"][0] is None


def test_tv8_family_a_reproduces_tv6(tv8_result):
    _, res = tv8_result
    # TV8: family A visits (17/16, 5/8, 31/16); mu = 3/2 gives a^3 C((t - b)/a) of TV6
    assert np.allclose(res["motion"]["pose_parameters"][1:], [17 / 16, 5 / 8, 31 / 16])
    quads = np.array([res["motion"]["norm_quadratics"][k] for k in "ABC"])
    a, b = -7 / 16, 3 / 2  # t^2 + s -> ((t - b)/a)^2 + s, made monic
    want = np.array([[b * b + s * a * a, -2 * b, 1.0] for s in (1, 4, 9)])
    assert np.allclose(quads, want)


def test_factorizations_and_loops_contract(tv8_result):
    d, res = tv8_result
    c = np.array(res["motion"]["coefficients"])
    s0 = pipeline.design_poses(d)[0]
    assert len(res["factorizations"]) == 6
    for f in res["factorizations"]:
        prod = poly.mul(poly.from_factors(np.array(f["factors"])), s0[None])
        scale = np.abs(c).max() / np.abs(prod).max()
        assert np.allclose(prod * scale, c, atol=1e-9 * np.abs(c).max())
        assert sorted(f["norm_order"]) == ["A", "B", "C"]
    assert len(res["loops"]) == 9
    assert sum(lp["type"] == "angle-symmetric" for lp in res["loops"]) == 3
    for lp in res["loops"]:
        axes = np.array(lp["axes"])
        assert np.allclose(np.linalg.norm(axes[:, :3], axis=1), 1.0)
        assert np.allclose(np.sum(axes[:, :3] * axes[:, 3:], 1), 0.0, atol=1e-12)
        fa, fb = (res["factorizations"][i]["factors"] for i in lp["factorizations"])
        want = loops.factor_axes(np.array(fa + fb[::-1]))
        assert np.allclose(axes, want)
        assert lp["singularity"] > 0


def test_result_is_plain_json(tv8_result):
    _, res = tv8_result
    assert json.loads(json.dumps(res, allow_nan=False)) == res


def test_world_frame_is_respected():
    """Moving every pose by a rigid transform moves the axes by it (frame equivariance)."""
    d = design.load_design(ASSETS / "tv8.json")
    g = dq.from_pos_wxyz(np.array([0.3, -1.0, 2.0]), np.array([0.9, 0.1, -0.3, 0.2]))
    from dataclasses import replace

    moved = []
    for p in d.poses:
        q = dq.mul(g, dq.from_pos_wxyz(p.position, p.wxyz))
        pos, wxyz = dq.to_pos_wxyz(q)
        moved.append(design.Pose(pos, wxyz))
    a = pipeline.solve(d, realize=False)
    b = pipeline.solve(replace(d, poses=tuple(moved)), realize=False)
    assert np.allclose(b.pose_parameters, a.pose_parameters)
    assert np.allclose(b.loop.axes, dq.transform_lines(g, a.loop.axes), atol=1e-9)


@pytest.mark.parametrize("criterion", ["length", "end-axes", "base-axes", "extra-poses"])
def test_criteria_choose_mu_through_the_design(criterion):
    from dataclasses import replace

    from paraloop_core.motion import fourpose, selection

    d = design.load_design(ASSETS / "tv8.json")
    extra = (design.Pose(np.array([0.2, -1.0, -0.3]), np.array([0.8, 0.4, -0.4, 0.1])),)
    motion = replace(d.motion, criterion=criterion, targets=np.array([[0, 0, 0], [1, 1, 0.0]]),
                     extra_poses=extra)
    chosen = replace(d, motion=motion)
    sol = pipeline.solve(chosen, realize=False)
    fams = fourpose.four_pose_families(pipeline.design_poses(d))
    params = pipeline._criterion_params(chosen, 1.0)  # design units: the argmin is unit-free
    best = selection.score_mu(fams, d.motion.family, np.array([sol.mu]), criterion, **params)
    fixed = selection.score_mu(fams, d.motion.family, np.array([1.5]), criterion, **params)
    assert best[0] <= fixed[0] + 1e-9


def test_fit_design_reports_targets_and_hits_the_reference():
    d = design.load_design(ASSETS / "sun-path-fit.json")
    sol = pipeline.solve(d, realize=False)
    res = pipeline.result_to_dict(sol)
    fit = res["motion"]["fit"]
    assert res["motion"]["method"] == "fit" and len(fit["targets"]) == len(d.poses)
    assert fit["targets"][0]["closest_t"] is None and fit["targets"][0]["distance"] < 1e-9
    c = np.array(res["motion"]["coefficients"])
    s0 = pipeline.design_poses(d)[0]
    assert np.allclose(dq.normalize(poly.evaluate_pose(c, np.inf)), dq.normalize(s0))
    # the noisy targets are approximated: each reported distance is the metric distance
    from paraloop_core.motion import metric

    inertia = pipeline.inertia_of(d)
    for target, entry in zip(pipeline.design_poses(d), fit["targets"], strict=True):
        t = np.inf if entry["closest_t"] is None else entry["closest_t"]
        d2 = metric.distance_sq(target, poly.evaluate_pose(c, t), inertia)
        assert np.isclose(np.sqrt(d2), entry["distance"], atol=1e-9)
        assert entry["distance"] < 0.1


def test_bad_evolution_settings_are_refused_by_the_loader():
    import copy

    data = json.loads((ASSETS / "sun-path-fit.json").read_text())
    bad = copy.deepcopy(data)
    bad["evolution"]["starts"] = 0
    from paraloop_core.errors import DesignFileError

    with pytest.raises(DesignFileError, match="starts"):
        design.design_from_dict(bad)
    bad["evolution"] = {"colour": 1}
    with pytest.raises(DesignFileError) as info:
        design.design_from_dict(bad)
    assert info.value.field == "evolution.colour"  # the unknown key is named


def test_end_effector_design_is_realized_with_a_certificate():
    d = design.load_design(ASSETS / "shading-panel.json")
    res = pipeline.result_to_dict(pipeline.solve(d))
    ee = res["end_effector"]
    rho = res["realization"]["radius"]
    assert ee["min_clearance"] >= rho - 1e-12  # default required clearance is rho
    assert all(p["min_distance"] >= p["required"] - 1e-12 for p in ee["pairs"])
    # the end link is S_3 L + P + R E_3: L and R are vertices of the placed polyhedron
    verts = np.array(ee["vertices"])
    end = np.array(ee["end_link"])
    assert np.min(np.linalg.norm(verts - end[1], axis=1)) < 1e-9
    assert np.min(np.linalg.norm(verts - end[2], axis=1)) < 1e-9


def test_end_effector_mesh_errors_reach_the_user(tmp_path):
    from paraloop_core.errors import ParaloopError

    data = json.loads((ASSETS / "shading-panel.json").read_text())
    data["end_effector"]["mesh"] = "missing.stl"
    path = tmp_path / "d.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ParaloopError, match="^end_effector.mesh: no mesh file"):
        design.load_design(path)  # refused on load, not when solving
    mesh = tmp_path / "missing.stl"
    mesh.write_bytes((ASSETS.parent / "meshes" / "shading-panel.stl").read_bytes())
    loaded = design.load_design(path)
    mesh.unlink()  # gone after loading: the solve says which field
    with pytest.raises(ParaloopError, match="^end_effector.mesh: no mesh file"):
        pipeline.solve(loaded)


def test_rounded_inertia_axes_in_a_file_are_accepted_and_orthonormalized():
    data = json.loads((ASSETS / "tv8.json").read_text())
    c, s = np.cos(0.3), np.sin(0.3)
    data["inertia"]["axes"] = np.round([[c, -s, 0], [s, c, 0], [0, 0, 1]], 7).tolist()
    data["motion"]["criterion"] = "length"
    d = design.design_from_dict(data)
    inertia = pipeline.inertia_of(d)
    assert np.allclose(inertia.axes @ inertia.axes.T, np.eye(3), atol=1e-14)
    assert pipeline.solve(d, realize=False).mu is not None


def test_a_change_of_unit_changes_no_answer():
    """Positions x 2^-20 and x 1e8: the same mu, visiting parameters, loop, search counts and
    relative clearance; the singularity measure is unit-free."""
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    from independent.generic_designs import random_design

    def answer(scale):
        sol = pipeline.solve(design.design_from_dict(random_design(5, scale)))
        r = sol.realization
        return sol, (sol.design.loop, r.stats["k"], r.stats["work"]), r.min_clearance / r.length

    base, key, clear = answer(1.0)
    for scale in (2.0**-20, 1e8):
        sol, key_s, clear_s = answer(scale)
        assert key_s == key and sol.mu == base.mu
        assert np.allclose(sol.pose_parameters, base.pose_parameters, rtol=1e-9)
        assert np.allclose(sol.singularity, base.singularity, rtol=1e-6)
        assert abs(clear_s - clear) <= 1e-7 * clear


def test_a_nearly_degenerate_motion_says_so(monkeypatch):
    """Random design 12: every loop comes within S ~ 1e-20 of a singular configuration; with
    tiny work budgets it is not realized (with the default ones thin bars realize it), and the
    report names that cause (not only the exhausted budgets)."""
    from independent.generic_designs import random_design

    monkeypatch.setattr(pipeline, "FIRST_ATTEMPT_WORK", 30)
    monkeypatch.setattr(pipeline, "FALLBACK_WORK", 30)
    sol = pipeline.solve(design.design_from_dict(random_design(12, 1.0)))
    assert sol.realization is None and np.max(sol.singularity) < pipeline.NEAR_SINGULAR
    rep = sol.realization_report
    assert rep["status"] == "not_found" and "nearly degenerate" in rep["reason"]
    assert rep["advice"].startswith("move the poses apart")
    generic = pipeline.solve(design.design_from_dict(random_design(11, 1.0)))
    assert np.max(generic.singularity) > 1e3 * pipeline.NEAR_SINGULAR
