"""Collision-free realization (steps 3-4), certificate, design spaces and the result dict."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import RealizationError
from paraloop_core.linkage import loops
from paraloop_core.realization import polyline, realize, report
from paraloop_core.realization.clearance import segment_distance
from paraloop_core.validation import table1


@pytest.fixture(scope="module")
def realized():
    jf = table1.random_loops(9, 2)  # (2, 2, 6, 8): AS and DB loops of two motions
    return [realize.realize(jf[m, k]) for m in range(2) for k in range(2)]


def _on_line(x, axis):
    return np.linalg.norm(np.cross(x, axis[:3]) - axis[3:]) < 1e-9 * (1 + np.linalg.norm(x))


def _pair_distances(r, u):
    """Distances ``(42,)`` of the checked pairs at parameter u, via base-frame link poses."""
    pose = loops.link_poses(r.joint_factors, poly.param_to_t(np.atleast_1d(u)))[0]
    pts = dq.transform_points(np.repeat(pose, 2, axis=0), r.points)  # S_i, E_i on link i
    e1, e2 = r.pairs[:, 0], r.pairs[:, 1]
    return segment_distance(pts[e1], pts[(e1 + 1) % 12], pts[e2], pts[(e2 + 1) % 12])


def test_certificate_equals_brute_force(realized):
    # non-trivial offset sequences and a step back are covered
    assert all(np.any(r.offsets != 0) for r in realized[:2])
    assert realized[1].stats["steps_back"] >= 1
    for r in realized[:2]:
        u = np.linspace(0.0, 1.0, 3001, endpoint=False)
        vals = np.array([_pair_distances(r, x) for x in u])  # (U, 42), u = 0 is t = inf
        scale = np.abs(r.points).max()
        for p in range(42):
            i = int(np.argmin(vals[:, p]))
            res = minimize_scalar(lambda x, p=p, r=r: _pair_distances(r, x)[p],
                                  bounds=(u[i] - 1 / 3000, u[i] + 1 / 3000), method="bounded",
                                  options={"xatol": 1e-12})
            ref = min(res.fun, vals[i, p])
            assert r.pair_distance[p] <= ref + 1e-9 * scale
            assert ref <= r.pair_distance[p] + 1e-7 * scale
            t = r.pair_t[p]  # the reported time attains the reported distance
            at = _pair_distances(r, 0.0 if np.isinf(t) else poly.t_to_param(t))[p]
            assert at == pytest.approx(r.pair_distance[p], abs=1e-9 * scale)
        assert r.min_clearance >= 2 * r.radius


def test_geometry_of_the_offset_polyline(realized):
    for r in realized:
        ax = loops.factor_axes(r.joint_factors)
        s, e = r.points[0::2], r.points[1::2]
        for i in range(6):
            assert _on_line(e[i], ax[i]) and _on_line(s[i], ax[i - 1])
        # the two vertices on each axis are d apart; the thin vertex lies between or at one end
        gap = np.linalg.norm(e - np.roll(s, -1, axis=0), axis=1)
        assert np.allclose(gap, r.separation)
        _, v0 = polyline.shortest_polyline(r.joint_factors)
        _, u = polyline.axis_frames(r.joint_factors)
        assert np.allclose(r.thin_initial, v0)
        assert np.allclose(r.thin, v0 + (r.shifts * r.length / r.p)[:, None] * u)
        assert set(np.abs(r.shifts)) <= {0, r.stats["k"]}
        assert r.stats["length_ratio"] == pytest.approx(
            polyline.polyline_length(r.points) / r.length)
        assert r.separation == pytest.approx(0.01 * r.length)
        assert r.radius == pytest.approx(0.25 * r.separation)


def test_thin_polyline_of_the_result_is_collision_free(realized):
    from paraloop_core.realization.collision import check_polylines

    for r in realized:
        assert not check_polylines(r.joint_factors, r.thin)


def test_design_spaces_are_consistent(realized):
    for r in realized:
        radii = r.design_space_radii
        assert np.all(radii >= r.radius - 1e-12)
        for (e1, e2, _, _), dist in zip(r.pairs, r.pair_distance, strict=True):
            if e1 % 2 == 0 and e2 % 2 == 0:
                assert radii[e1 // 2] + radii[e2 // 2] <= dist + 1e-12
            elif e1 % 2 == 0 or e2 % 2 == 0:
                bar = e1 if e1 % 2 == 0 else e2
                assert radii[bar // 2] + r.radius <= dist + 1e-12
        # largest: each radius is attained by some pair
        assert np.all(np.isfinite(radii))


def test_result_dict_is_json_ready(realized):
    r = realized[1]
    out = json.loads(json.dumps(report.realization_to_dict(r)))
    assert len(out["points"]) == 12 and len(out["pairs"]) == 42
    assert len(out["design_space_radii"]) == 6
    assert set(out["stats"]) >= {"k", "collision_checks", "steps_back",
                                 "min_distance_computations", "length_ratio"}
    assert out["min_clearance"] == pytest.approx(min(p["min_distance"] for p in out["pairs"]))
    assert all(p["t"] is None or np.isfinite(p["t"]) for p in out["pairs"])
    assert out["offsets"] == [int(o) for o in r.offsets]


def test_search_is_deterministic():
    jf = table1.random_loops(9, 1)[0, 1]
    a = report.realization_to_dict(realize.realize(jf))
    b = report.realization_to_dict(realize.realize(jf.copy()))
    assert a == b
    assert np.array_equal(table1.random_loops(9, 3), table1.random_loops(9, 5)[:3])  # prefix


def test_fixed_vertices_are_held():
    jf = table1.random_loops(4, 1)[0, 0]
    q, u = polyline.axis_frames(jf)
    r = realize.realize(jf, fixed={1: 0.4, 3: -0.2})
    assert r.shifts[1] == 0 and r.shifts[3] == 0
    assert np.allclose(r.thin[1], q[1] + 0.4 * u[1]) and np.allclose(r.thin[3], q[3] - 0.2 * u[3])


@pytest.mark.parametrize(
    "kwargs",
    [{"rho": 0.0}, {"rho": -1.0}, {"rho": 0.1, "d": 0.15}, {"p": 0.0}, {"p": -2.0},
     {"max_k": 0}, {"fixed": {i: 0.0 for i in range(6)}}, {"rho": float("nan")}],
)
def test_bad_parameters(kwargs):
    jf = table1.random_loops(1, 1)[0, 0]
    with pytest.raises(RealizationError) as err:
        realize.realize(jf, **kwargs)
    assert err.value.reason == "bad-parameters"


def test_cap_reached_is_reported():
    jf = table1.random_loops(1, 1)[0, 0]
    _, v0 = polyline.shortest_polyline(jf)
    big = float(polyline.polyline_length(v0))  # bars as thick as the whole loop: impossible
    with pytest.raises(RealizationError) as err:
        realize.realize(jf, rho=big, d=2 * big, max_k=2, fixed={0: 0.0, 1: 0.0, 2: 0.0, 3: 0.0})
    assert err.value.reason == "cap-reached" and "k <= 2" in str(err.value)


def test_spherical_loop_is_singular():
    h = table1.random_rotation_factors(np.random.default_rng(0), (6,))
    h[:, 5:8] = 0.0  # all axes through the origin
    with pytest.raises(RealizationError) as err:
        realize.realize(h)
    assert err.value.reason == "singular-loop"


def test_validate_realization_cli(tmp_path, capsys):
    from app.cli.main import main

    csv_path = tmp_path / "rows.csv"
    code = main(["validate", "realization", "--motions", "2", "--seed", "3",
                                      "--workers", "1", "--csv", str(csv_path), "--quiet"])
    out = capsys.readouterr().out
    assert code == 0
    assert "1169.782" in out and "928.379" in out  # the paper's values are shown beside ours
    rows = csv_path.read_text().strip().splitlines()
    assert len(rows) == 1 + 4 and rows[0].startswith("motion,kind,ok")
    summary = table1.summarize(table1.run(2, 3))
    assert summary["AS"]["successes"] == summary["DB"]["successes"] == 2


def test_scaling_the_loop_scales_the_realization():
    jf = table1.random_loops(7, 2)[0, 1]
    big = jf.copy()
    big[:, 5:8] *= 1000.0  # moments scale with the unit of length: same loop in mm
    a, b = realize.realize(jf), realize.realize(big)
    assert np.array_equal(a.offsets, b.offsets) and np.array_equal(a.shifts, b.shifts)
    assert np.allclose(b.points, 1000.0 * a.points, rtol=1e-9, atol=1e-9)
    assert np.allclose(b.pair_distance, 1000.0 * a.pair_distance, rtol=1e-9)
    # counts identical; the length ratio (a float) to rounding: x1000 is not exact in float64
    counts = [{k: v for k, v in r.stats.items() if k != "length_ratio"} for r in (a, b)]
    assert counts[0] == counts[1] and len(counts[0]) == len(a.stats) - 1
    assert b.stats["length_ratio"] == pytest.approx(a.stats["length_ratio"], rel=1e-12)


@pytest.mark.parametrize("factor", [2.0**-20, 2.0**30])
def test_search_runs_in_its_own_unit(factor):
    """A power-of-two change of unit is exact in float64: the search sees the same numbers
    (it works in :func:`realize.unit_length`), so every decision and count is identical."""
    jf = table1.random_loops(7, 2)[0, 1]
    a, b = realize.realize(jf), realize.realize(dq.scale_lengths(jf, factor))
    assert a.stats == b.stats and np.array_equal(a.offsets, b.offsets)
    assert np.array_equal(b.points, factor * a.points)
    assert np.array_equal(b.pair_lower, factor * a.pair_lower)
    assert b.radius == factor * a.radius and b.tolerance == factor * a.tolerance


def test_work_budget_stops_the_search_deterministically():
    jf = table1.random_loops(7, 2)[0, 1]
    full = realize.realize(jf)
    assert full.stats["work"] >= full.stats["collision_checks_sequential"]
    assert realize.realize(jf, budget=full.stats["work"]).stats == full.stats
    errors = []
    for _ in range(2):
        with pytest.raises(RealizationError) as err:
            # checked before each candidate: the last one's thin checks alone exceed this
            realize.realize(jf, budget=full.stats["collision_checks_sequential"] - 1)
        errors.append(str(err.value))
    assert err.value.reason == "budget" and errors[0] == errors[1]
