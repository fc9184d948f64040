"""Bennett 4R from three poses (issue 29): checked from the result JSON with independent code
(``tests/independent/dq8``): the Bennett conditions on the four axes, the motion through the
poses, the loop's closure; degenerate inputs refused with the project's errors."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from paraloop_core import design as dm
from paraloop_core import pipeline
from paraloop_core.algebra import dq
from paraloop_core.errors import DesignFileError, InterpolationError, ParaloopError
from paraloop_core.linkage import bennett
from paraloop_core.motion import threepose
from paraloop_core.result import result_to_dict
from tests.independent import dq8

SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def _pose_dict(rng: np.random.Generator, size: float) -> dict:
    return {"position": (rng.normal(size=3) * size).tolist(), "wxyz": rng.normal(size=4).tolist()}


def random_bennett_design(seed: int, size: float = 2.0) -> dict:
    """Three random poses (a design file with nothing else: linkage and method by default)."""
    rng = np.random.default_rng(seed)
    return {"name": f"bennett-{seed}", "poses": [_pose_dict(rng, size) for _ in range(3)]}


def _solved(data: dict, realize: bool = True) -> dict:
    return result_to_dict(pipeline.solve(dm.design_from_dict(data), realize=realize))


# --- independent checks of a result --------------------------------------------------------------


def bennett_residual(axes: np.ndarray) -> float:
    """Largest violation of the Bennett conditions by four unit Pluecker lines ``(4, 6)`` in
    loop order: opposite common-normal lengths and twists (sine and |cosine|) equal, and
    ``a / sin(alpha)`` equal for two adjacent links; lengths relative to the largest one."""
    d1, m1 = axes[:, :3], axes[:, 3:]
    d2, m2 = np.roll(d1, -1, axis=0), np.roll(m1, -1, axis=0)  # link i: axes i and i+1
    cross = np.linalg.norm(np.cross(d1, d2), axis=-1)
    sin, cos = cross, np.abs((d1 * d2).sum(-1))
    a = np.abs((d1 * m2).sum(-1) + (d2 * m1).sum(-1)) / cross
    size = a.max()
    return float(max(abs(a[0] - a[2]) / size, abs(a[1] - a[3]) / size,
                     abs(sin[0] - sin[2]), abs(sin[1] - sin[3]), abs(cos[0] - cos[2]),
                     abs(cos[1] - cos[3]), abs(a[0] / sin[0] - a[1] / sin[1]) * sin.min() / size))


def pose_error(result: dict, data: dict) -> float:
    """Largest distance (rotation matrix and position over the poses' size) of the world
    motion at each pose's parameter from that pose."""
    coef = np.array(result["motion"]["coefficients"])
    t = np.array([np.inf if x is None else x for x in result["motion"]["pose_parameters"]])
    at = dq8.poly_at(coef, *dq8.homogeneous(t))
    pos = np.array([p["position"] for p in data["poses"]])
    want = dq8.pose_from_pos_wxyz(pos, np.array([p["wxyz"] for p in data["poses"]]))
    (r1, x1), (r2, x2) = dq8.rigid(at), dq8.rigid(want)
    size = max(1.0, float(np.abs(pos).max()))
    return float(max(np.abs(r1 - r2).max(), np.abs(x1 - x2).max() / size))


def closure_error(result: dict, n: int = 1001) -> float:
    """Largest deviation from the identity of ``(t - h1)(t - h2)(t - k2~)(t - k1~)`` (the four
    joint transforms of the loop, forward) at ``n`` parameters round the cycle, relative."""
    f = np.array([x["factors"] for x in result["factorizations"]])  # [[h1, h2], [k1, k2]]
    joints = np.stack([f[0, 0], f[0, 1], dq8.dconj(f[1, 1]), dq8.dconj(f[1, 0])])
    c, s = dq8.homogeneous(np.tan(np.pi * (np.linspace(0.0, 1.0, n) - 0.5)))
    lin = dq8.linear_at(joints, c, s)  # (n, 4, 8): t - h, t - h~ = conj(t - h)
    prod = dq8.dmul(dq8.dmul(lin[:, 0], lin[:, 1]), dq8.dmul(lin[:, 2], lin[:, 3]))
    size = np.abs(prod[:, 0])
    unit = max(1.0, float(np.abs(f[..., 5:]).max()))
    return float(max((np.abs(prod[:, 1:4]).max(-1) / size).max(),
                     (np.abs(prod[:, 4:]).max(-1) / size).max() / unit))


# --- properties ----------------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(SEEDS, st.sampled_from([1e-3, 1.0, 1e3]))
def test_random_three_poses_give_a_bennett_loop(seed, size):
    data = random_bennett_design(seed, size)
    try:
        out = _solved(data, realize=False)
    except InterpolationError as exc:  # random poses: a zero pitch has probability 0
        pytest.fail(f"random poses refused: {exc}")
    assert out["linkage"] == "bennett" and out["motion"]["method"] == "three-pose"
    (loop,) = out["loops"]
    assert loop["type"] == "Bennett" and loop["factorizations"] == [0, 1]
    axes = np.array(loop["axes"])
    assert axes.shape == (4, 6)
    assert bennett_residual(axes) <= 1e-9
    assert pose_error(out, data) <= 1e-9
    assert closure_error(out) <= 1e-9
    assert [f["norm_order"] for f in out["factorizations"]] == [["A", "B"], ["B", "A"]]
    assert loop["singularity"] > 0


@settings(max_examples=20, deadline=None)
@given(SEEDS)
def test_axes_over_the_cycle_are_dependent_and_singularity_is_their_3x3_minors(seed):
    """Rank 3 (the loop moves) at every t; S = e_3 of the squared singular values (SVD)."""
    sol = pipeline.solve(dm.design_from_dict(random_bennett_design(seed)), realize=False)
    jf = sol.loop.joint_factors
    t = np.tan(np.pi * (np.linspace(0.0, 1.0, 257)[1:-1] - 0.5))
    j = bennett.axes_at(jf, t) / np.array([1, 1, 1, sol.unit, sol.unit, sol.unit])
    sv = np.linalg.svd(j, compute_uv=False)  # (T, 4)
    assert (sv[:, 3] <= 1e-9 * sv[:, 0]).all()
    q = sv[:, :3] ** 2
    e3 = q[:, 0] * q[:, 1] * q[:, 2]
    assert np.allclose(bennett.singularity_curve(jf, t, sol.unit), e3, rtol=1e-8)
    dense = bennett.singularity_curve(jf, np.tan(np.pi * (np.linspace(0, 1, 20001) - 0.5)),
                                      sol.unit)
    assert 0 < sol.singularity[0] <= dense.min() * (1 + 1e-6)  # attained where it says:
    at = bennett.singularity_curve(jf, np.array([sol.singularity_t[0]]), sol.unit)[0]
    assert at == pytest.approx(sol.singularity[0], rel=1e-9)


def test_known_answer_conic_of_the_peer():
    """rational-linkages' three-pose test vectors (literal 8-vectors, its test_interpolate):
    the conic through three poses is the plane of the poses cut by the Study quadric, so ours
    and the peer's expected curve span the same plane. The peer's opposite dual sign does not
    matter: D -> -D maps the plane and the quadric to themselves."""
    p = np.array([[0, 17, -33, -89, 0, -6, 5, -3], [0, 84, -21, -287, 0, -30, 3, -9],
                  [0, 10, 37, -84, 0, -3, -6, -3]], dtype=float)
    peer = np.array([[0.0, 0.0, 0.0], [5.61314791, 50.4045512, 27.98230088],
                     [20.76864728, 12.54993679, -54.31858407],
                     [-47.15044248, -93.3539823, -146.49557522], [0.0, 0.0, 0.0],
                     [-1.68394437, -18.43994943, -9.87610619],
                     [-3.36788875, -1.86219975, 8.2300885],
                     [-1.68394437, -2.37800253, -4.9380531]]).T  # (3, 8) coefficient rows
    s = dq.normalize(p)
    ours = dq.mul(s[0], threepose.three_pose_motion(s))  # the world conic S_0 C(t)
    sv = np.linalg.svd(np.concatenate([ours / np.abs(ours).max(), peer / np.abs(peer).max()]),
                       compute_uv=False)
    assert sv[2] > 1e-3 and sv[3] <= 1e-8 * sv[0]  # one plane (peer rounded to 1e-8)
    at = dq.normalize(dq.mul(s[0], threepose.three_pose_motion(s).sum(0)))  # S_0 C(1) ∝ S_2
    assert np.allclose(at * np.sign(at @ s[2]), s[2], atol=1e-12)


def test_design_file_and_cli(tmp_path):
    from app.cli.main import main

    data = random_bennett_design(7)
    d = dm.design_from_dict(data)
    assert d.linkage == "bennett" and d.motion.method == "three-pose"
    again = dm.design_from_dict(json.loads(json.dumps(dm.design_to_dict(d))))
    assert again.linkage == "bennett"
    path = tmp_path / "b.json"
    path.write_text(json.dumps(data))
    start = time.perf_counter()
    code = main(["solve", str(path), "-o", str(tmp_path / "b.result.json")])
    seconds = time.perf_counter() - start
    out = json.loads((tmp_path / "b.result.json").read_text())
    assert code == 3  # solved, not realized: never a false claim
    real = out["realization"]
    assert real["status"] == "not_found" and "Bennett realization not yet supported" in \
        real["reason"]
    assert "points" not in real and "certified_clearance" not in real
    assert bennett_residual(np.array(out["loops"][0]["axes"])) <= 1e-9
    assert "family" not in out["motion"] and "mu" not in out["motion"]
    assert seconds < 10


def test_unit_invariance():
    data = random_bennett_design(11)
    big = json.loads(json.dumps(data))
    for p in big["poses"]:
        p["position"] = [1000.0 * x for x in p["position"]]
    a = np.array(_solved(data, False)["loops"][0]["axes"])
    b = np.array(_solved(big, False)["loops"][0]["axes"])
    assert np.allclose(a[:, :3], b[:, :3], atol=1e-9)
    assert np.allclose(1000.0 * a[:, 3:], b[:, 3:], atol=1e-9 * np.abs(b).max())


# --- refused inputs ------------------------------------------------------------------------------


def _three(poses: list[np.ndarray]) -> dict:
    rows = [dq.to_pos_wxyz(q) for q in poses]
    return {"poses": [{"position": p.tolist(), "wxyz": w.tolist()} for p, w in rows]}


S0 = dq.from_pos_wxyz(np.array([0.3, -0.2, 0.5]), np.array([0.9, 0.1, -0.3, 0.2]))
S1 = dq.from_pos_wxyz(np.array([1.0, 0.4, -0.6]), np.array([0.5, 0.6, 0.2, -0.4]))


@pytest.mark.parametrize("case, reason, words", [
    ("coincident", "coincident", "poses 1 and 2 coincide"),
    ("translations", "zero-pitch", "pure translation"),
    ("rotation-from-pose-1", "zero-pitch", "pose 2 is reached from pose 1"),
    # three distinct poses spanning only a pencil need a zero pitch: refused as such
    ("one-axis", "zero-pitch", "pose 1 is reached from pose 0 by a rotation without pitch"),
])
def test_degenerate_three_poses_refused(case, reason, words):
    turn = dq.rotation_about_line(np.array([0.2, 1.0, 0.5]), np.array([1.0, -2.0, 0.3]), 1.1)
    poses = {
        "coincident": [S0, S1, S1],
        "translations": [S0, dq.mul(dq.translation(np.array([1.0, 2, 0])), S0),
                         dq.mul(dq.translation(np.array([0.0, 1, 3])), S0)],
        "rotation-from-pose-1": [S0, S1, dq.mul(S1, turn)],
        "one-axis": [dq.mul(S0, dq.rotation_about_line(np.array([0.0, 0.3, 1.0]),
                                                       np.array([1.0, 0, 0]), a))
                     for a in (0.0, 0.7, 1.9)],
    }[case]
    with pytest.raises(InterpolationError, match=words) as info:
        pipeline.solve(dm.design_from_dict(_three(poses)), realize=False)
    assert info.value.reason == reason and isinstance(info.value, ParaloopError)


def test_linkage_field_checked():
    three = random_bennett_design(3)
    four = {"poses": three["poses"] + [_pose_dict(np.random.default_rng(1), 2.0)]}
    with pytest.raises(DesignFileError, match="exactly 3 poses"):
        pipeline.solve(dm.design_from_dict({**four, "linkage": "bennett"}))
    with pytest.raises(DesignFileError) as info:
        dm.design_from_dict({**three, "linkage": "6R", "motion": {"method": "three-pose"}})
    assert info.value.field == "motion.method"
    with pytest.raises(DesignFileError) as info:
        dm.design_from_dict({**three, "loop": 1})
    assert info.value.field == "loop"
    with pytest.raises(DesignFileError) as info:
        dm.design_from_dict({**three, "motion": {"criterion": "length"}})
    assert info.value.field == "motion.criterion"
    with pytest.raises(DesignFileError, match="'three-pose' for 3"):  # a 6R edit in progress
        pipeline.solve(dm.design_from_dict({**three, "motion": {"method": "four-pose"}}))
    assert dm.design_from_dict(four).linkage == "6R"


def test_bennett_example_is_valid_json_schema():
    import jsonschema

    schema = json.loads(Path(dm.__file__).with_name("design.schema.json").read_text())
    jsonschema.validate(dm.design_to_dict(dm.design_from_dict(random_bennett_design(5))), schema)


def test_studio_refuses_bennett_designs_with_one_message():
    """The studio's panels are written for 6R loops: a Bennett design is refused on load (one
    DesignFileError naming ``linkage``), never a crash in a panel."""
    from app.files import studio_design

    with pytest.raises(DesignFileError, match="^linkage: the studio does not show Bennett"):
        studio_design(dm.design_from_dict(random_bennett_design(2)))
    four = dm.load_design(Path(dm.__file__).parents[1] / "assets" / "designs" / "tv8.json")
    assert studio_design(four) is four


def test_known_answer_paper_flip():
    """MATH section 4's exact flip: C = (t - i)(t - 2j - eps i) through S_0 = 1 (t = inf), C(0),
    C(1) is interpolated back, and its factorizations are exactly (i, 2j + eps i) and
    (8/5 i + 6/5 j + eps (9/25 i - 12/25 j), -3/5 i + 4/5 j + eps (16/25 i + 12/25 j))."""
    e = np.eye(8)
    h1, h2 = e[1], 2 * e[2] + e[5]
    k1 = np.array([0, 8 / 5, 6 / 5, 0, 0, 9 / 25, -12 / 25, 0])
    k2 = np.array([0, -3 / 5, 4 / 5, 0, 0, 16 / 25, 12 / 25, 0])
    quad = dq8.from_factors(np.stack([h1, h2]))
    poses = [e[0], *(dq.normalize(dq8.poly_at(quad, np.array([t]), np.ones(1))[0])
                     for t in (0.0, 1.0))]
    sol = pipeline.solve(dm.design_from_dict(_three(poses)), realize=False)
    assert np.allclose(sol.monic, quad, atol=1e-12)
    assert np.allclose(sol.factorizations.factors, [[h1, h2], [k1, k2]], atol=1e-12)
    assert np.allclose(sol.loop.joint_factors, [h1, h2, k2, k1], atol=1e-12)
    assert sol.pose_parameters[1:].tolist() == [0.0, 1.0]


def test_three_poses_on_a_motion_with_a_translation_are_refused():
    """Poses of ``(t - h)(t - eps d)`` (a rotation then a translation): their quadratic is that
    motion, whose norm has the real root 0, so it has no Bennett factorization."""
    from paraloop_core.errors import NonGenericMotionError

    h = np.array([0.3, 0.2, 1.0, -0.5, 0.0, 0.4, 0.1, 0.36])
    h[5:] -= (h[1:4] @ h[5:]) / (h[1:4] @ h[1:4]) * h[1:4]
    quad = dq8.from_factors(np.stack([h, [0, 0, 0, 0, 0, 0.7, -0.2, 0.5]]))
    poses = [np.eye(8)[0], *(dq.normalize(dq8.poly_at(quad, np.array([t]), np.ones(1))[0])
                             for t in (0.5, 2.0))]
    with pytest.raises(NonGenericMotionError, match="real root") as info:
        pipeline.solve(dm.design_from_dict(_three(poses)), realize=False)
    assert info.value.reason == "real-root"


def test_near_real_norm_root_refused_without_warnings():
    """A pose turned by 2e-8 rad and moved (found by fuzzing three-pose designs): the norm root
    sits on the real line within float64, refused as ``real-root``, no RuntimeWarning."""
    import warnings

    from paraloop_core.errors import NonGenericMotionError

    data = {"poses": [{"position": [0.0, 0.0, 0.0], "wxyz": [1.0, 0.0, 0.0, 0.0]},
                      {"position": [-1.0, 0.0, 1.0], "wxyz": [0.0, 1.0, 0.0, 0.0]},
                      {"position": [-1.0, 0.0, 0.0], "wxyz": [115549969.0, 1.0, 1.0, 0.0]}]}
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(NonGenericMotionError) as info:
            pipeline.solve(dm.design_from_dict(data))
    assert info.value.reason == "real-root"
