"""`paraloop animate`: the animated glTF of a realized loop, read back by an independent GLB
reader (struct + json) and by trimesh, against the link poses of `loops.link_poses`."""

from __future__ import annotations

import dataclasses
import json
import struct
from pathlib import Path

import fab_fixtures as F
import numpy as np
import pytest
import trimesh

from app.cli.main import main
from app.exports import animation_keyframes
from paraloop_core import design as design_mod
from paraloop_core import pipeline, printed
from paraloop_core.algebra import dq
from paraloop_core.design import DriveSettings
from paraloop_core.fabrication import animate
from paraloop_core.linkage import drive_plan, loops

TV8 = Path(__file__).resolve().parents[1] / "assets" / "designs" / "tv8.json"
#: design Z-up -> glTF Y-up as documented: (x, y, z) -> (x, z, -y)
Z_TO_Y = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])


@pytest.fixture(scope="module")
def real():
    sol = pipeline.solve(design_mod.load_design(TV8))
    assert sol.realization is not None
    return sol.realization


def read_glb(data: bytes) -> tuple[dict, bytes]:
    """JSON document and BIN chunk of a GLB, checking the container layout."""
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    jlen, jtype = struct.unpack_from("<I4s", data, 12)
    assert jtype == b"JSON" and jlen % 4 == 0
    doc = json.loads(data[20:20 + jlen])
    blen, btype = struct.unpack_from("<I4s", data, 20 + jlen)
    assert btype == b"BIN\0" and blen % 4 == 0 and 28 + jlen + blen == len(data)
    assert doc["buffers"][0]["byteLength"] <= blen
    return doc, data[28 + jlen:]


def accessor(doc: dict, blob: bytes, index: int) -> np.ndarray:
    """Accessor ``index`` as float64 ``(count,)`` or ``(count, components)``."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    comps = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc["type"]]
    dtype = {5126: "<f4", 5125: "<u4"}[acc["componentType"]]
    start = view["byteOffset"] + acc.get("byteOffset", 0)
    assert start % 4 == 0
    arr = np.frombuffer(blob, dtype, count=acc["count"] * comps, offset=start)
    assert arr.nbytes <= view["byteLength"] and start + arr.nbytes <= len(blob)
    arr = arr.reshape(acc["count"], comps) if comps > 1 else arr
    if "min" in acc:
        assert np.array_equal(np.atleast_1d(arr.min(axis=0)), acc["min"])
        assert np.array_equal(np.atleast_1d(arr.max(axis=0)), acc["max"])
    return arr.astype(np.float64)


def rotation(xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of unit glTF quaternions ``(..., 4)`` (x, y, z, w)."""
    x, y, z, w = np.moveaxis(np.asarray(xyzw, float), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def uniform_t(jf: np.ndarray, n: int) -> np.ndarray:
    """The test's own keyframe parameters: joint 0 of ``t - h`` turns by
    ``2 atan2(-|vec h|, t - h_0)``, so angle ``-2 pi k/(n-1)`` at ``t = h_0 + |vec h| cot``."""
    k = np.arange(n)
    with np.errstate(divide="ignore"):
        cot = np.where((k == 0) | (k == n - 1), np.inf, 1.0 / np.tan(np.pi * k / (n - 1)))
    return jf[0, 0] + np.linalg.norm(jf[0, 1:4]) * cot


def animated(doc: dict, blob: bytes) -> dict[int, dict[str, np.ndarray]]:
    """Per animated node: ``times`` and the ``translation`` / ``rotation`` keyframes."""
    (anim,) = doc["animations"]
    out: dict[int, dict[str, np.ndarray]] = {}
    for ch in anim["channels"]:
        sampler = anim["samplers"][ch["sampler"]]
        assert sampler["interpolation"] == "LINEAR"
        node = out.setdefault(ch["target"]["node"], {})
        assert ch["target"]["path"] not in node
        node["times"] = accessor(doc, blob, sampler["input"])
        node[ch["target"]["path"]] = accessor(doc, blob, sampler["output"])
    return out


def check_motion(data: bytes, jf: np.ndarray, points: np.ndarray, radius: float, frames: int,
                 seconds: float, t: np.ndarray | None = None) -> None:
    """Everything the file promises, read back from ``data``; keyframes at parameters ``t``
    (default: joint 0 at constant speed, checked here)."""
    doc, blob = read_glb(data)
    nodes = doc["nodes"]
    (root_index,) = doc["scenes"][doc["scene"]]["nodes"]
    root = nodes[root_index]
    anim = animated(doc, blob)
    assert len(anim) == 6 and sorted(anim) == sorted(root["children"])
    size = float(np.ptp(points, axis=0).max())
    centre = np.array(doc["asset"]["extras"]["centre"])
    # the root: the centre, then Z-up -> Y-up (one matrix, glTF's column-major order)
    root_m = np.array(root["matrix"], float).reshape(4, 4).T
    assert np.array_equal(root_m[3], [0.0, 0.0, 0.0, 1.0])
    root_rot, root_tr = root_m[:3, :3], root_m[:3, 3]
    assert np.allclose(root_rot, Z_TO_Y, atol=1e-12)
    assert np.allclose(root_tr, Z_TO_Y @ centre, rtol=1e-12, atol=1e-12 * size)
    uniform = t is None
    if uniform:
        t = uniform_t(jf, frames)
        assert np.allclose(loops.joint_angles(jf, t)[1:-1, 0],
                           -2 * np.pi * np.arange(1, frames - 1) / (frames - 1), atol=1e-9)
    expected = dq.to_matrix(loops.link_poses(jf, t))  # (N, 6, 4, 4), homogeneous -> matrices
    for link in range(6):
        node_index = next(i for i in root["children"] if nodes[i]["name"] == f"link_{link}")
        keys = anim[node_index]
        times, tr, q = keys["times"], keys["translation"], keys["rotation"]
        assert times.shape == (frames,) and tr.shape == (frames, 3) and q.shape == (frames, 4)
        assert times[0] == 0 and np.all(np.diff(times) > 0)
        assert times[-1] == pytest.approx(seconds, rel=1e-6)
        assert np.allclose(np.diff(times), seconds / (frames - 1), rtol=1e-4)
        assert np.allclose(np.linalg.norm(q, axis=1), 1, atol=1e-6)
        assert np.all(np.einsum("ki,ki->k", q[1:], q[:-1]) > 0)  # one hemisphere
        # the mesh: capsules about the link's bar and pin, stored relative to the centre
        prim = doc["meshes"][nodes[node_index]["mesh"]]["primitives"][0]
        verts = accessor(doc, blob, prim["attributes"]["POSITION"]) + centre
        segs = points[[2 * link, 2 * link + 1, (2 * link + 2) % 12]]
        dist = np.array([_segment_distance(verts, segs[j], segs[j + 1]) for j in (0, 1)])
        assert np.abs(dist - radius).min(axis=0).max() < 1e-5 * size  # on one capsule's surface
        for j in (0, 1):  # each capsule is there, end to end
            axis = segs[j + 1] - segs[j]
            on = np.abs(dist[j] - radius) < 1e-5 * size
            s = (verts[on] - segs[j]) @ axis / np.linalg.norm(axis)
            assert s.min() < -0.9 * radius and s.max() > np.linalg.norm(axis) + 0.9 * radius
        # home points of the link through root o node at every frame
        home = segs
        rot = rotation(q)  # (N, 3, 3)
        local = np.einsum("kab,pb->kpa", rot, home - centre) + tr[:, None, :]
        world = np.einsum("ab,kpb->kpa", root_rot, local) + root_tr
        want = (np.einsum("kab,pb->kpa", expected[:, link, :3, :3], home)
                + expected[:, link, None, :3, 3])
        assert np.abs(world - want @ Z_TO_Y.T).max() < 1e-6 * size
    # joint 0 read from the file: link 1 turns about A_0 (base frame) one full turn, by default
    # uniformly
    axis = loops.factor_axes(jf)[0, :3]
    q1 = anim[next(i for i in root["children"] if nodes[i]["name"] == "link_1")]["rotation"]
    angle = 2 * np.arctan2(q1[:, :3] @ axis, q1[:, 3])
    step = np.angle(np.exp(1j * np.diff(angle)))  # wrapped into (-pi, pi]
    if uniform:
        assert np.allclose(step, -2 * np.pi / (frames - 1), atol=1e-5)  # so one turn in all
    assert abs(abs(step.sum()) - 2 * np.pi) < 1e-5


def _segment_distance(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    s = np.clip((x - a) @ ab / max(ab @ ab, 1e-300), 0.0, 1.0)
    return np.linalg.norm(x - (a + s[:, None] * ab), axis=1)


def test_glb_matches_link_poses(real):
    data = animate.animated_glb(real.joint_factors, real.points, real.radius)
    check_motion(data, real.joint_factors, real.points, real.radius, 240, 10.0)


def test_far_from_origin_keeps_precision(real):
    # the same loop moved 1e6 loop sizes away: float32 would lose it without the centring
    shift = dq.translation(np.array([3e6, -2e6, 1e6]))
    jf = dq.mul(dq.mul(shift, real.joint_factors), dq.inv(shift))
    points = dq.transform_points(shift, real.points)
    data = animate.animated_glb(jf, points, real.radius, frames=7, seconds=3.0)
    check_motion(data, jf, points, real.radius, 7, 3.0)


def test_keyframe_parameters_turn_joint0_uniformly(real):
    jf = real.joint_factors
    t = animate.keyframe_parameters(jf, 13)
    assert np.isinf(t[[0, -1]]).all()
    assert np.allclose(t[1:-1], uniform_t(jf, 13)[1:-1], rtol=1e-12, atol=1e-12)
    phi = loops.joint_angles(jf, t)[:, 0]
    assert np.allclose(phi[:-1], -2 * np.pi * np.arange(12) / 12, atol=1e-12)


def test_trimesh_loads_scene(real, tmp_path):
    path = tmp_path / "loop.glb"
    path.write_bytes(animate.animated_glb(real.joint_factors, real.points, real.radius,
                                          frames=5))
    scene = trimesh.load(path)
    assert isinstance(scene, trimesh.Scene) and len(scene.geometry) == 6
    assert all(g.is_watertight for g in scene.geometry.values())


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"joint_factors": np.zeros((5, 8))}, "joint_factors must have shape"),
    ({"points": np.zeros((12, 2))}, "points must have shape"),
    ({"points": np.full((12, 3), np.nan)}, "points has non-finite"),
    ({"radius": 0.0}, "radius must be a finite number > 0"),
    ({"radius": np.inf}, "radius must be a finite number > 0"),
    ({"frames": 1}, "frames must be an integer >= 2"),
    ({"frames": 2.5}, "frames must be an integer >= 2"),
    ({"seconds": 0.0}, "seconds must be a finite number > 0"),
    ({"seconds": np.nan}, "seconds must be a finite number > 0"),
])
def test_bad_input_raises(real, kwargs, message):
    args = {"joint_factors": real.joint_factors, "points": real.points, "radius": real.radius}
    extra = {k: kwargs.pop(k) for k in ("frames", "seconds") if k in kwargs}
    args.update(kwargs)
    with pytest.raises(ValueError, match=message):
        animate.animated_glb(args["joint_factors"], args["points"], args["radius"], **extra)


def test_cli_writes_glb(tmp_path, capsys, real):
    """The file plays the design's drive: its recommended motor with the speed schedule."""
    out = tmp_path / "sub" / "loop.glb"
    assert main(["animate", str(TV8), "--out", str(out), "--frames", "12",
                 "--seconds", "2"]) == 0
    printed = capsys.readouterr().out
    assert "->" in printed and "with its speed schedule" in printed
    t, cycle, _ = animation_keyframes(real, DriveSettings(), 12)
    assert cycle == 10.0
    check_motion(out.read_bytes(), real.joint_factors, real.points, real.radius, 12, 2.0, t)
    assert [p.name for p in out.parent.iterdir()] == ["loop.glb"]  # no temporary left
    default = tmp_path / "default.glb"  # without --seconds: the drive's cycle time
    assert main(["animate", str(TV8), "--out", str(default), "--frames", "12"]) == 0
    assert read_glb(default.read_bytes())[0]["asset"]["extras"]["seconds"] == 10.0


def test_scheduled_keyframes_follow_the_schedule_in_time(real):
    """Frame k's motor angle is reached at time T k / (N - 1): the time to each keyframe's
    angle, integrated numerically (d tau = d theta / omega, omega^2 linear per step), is the
    keyframe's time; the motor joint's own angle (loops.joint_angles) is that angle."""
    jf = real.joint_factors
    plan = drive_plan.plan_drive(jf, DriveSettings())
    s, n = plan.schedule, 25
    t = animate.scheduled_parameters(jf, s, n)
    m, a, b = plan.motor, jf[plan.motor, 0], np.linalg.norm(jf[plan.motor, 1:4])
    theta = np.mod(2 * np.arctan2(b, a - t), 2 * np.pi)  # the motor's turn since home
    theta[-1] = 2 * np.pi
    assert np.all(np.diff(theta) > 0)
    fine = np.linspace(0.0, 2 * np.pi, 400_001)
    omega = np.sqrt(np.interp(fine, s.theta, s.motor_speed**2))
    step = np.diff(fine) * 0.5 * (1 / omega[1:] + 1 / omega[:-1])  # trapezoids of 1 / omega
    tau = np.concatenate([[0.0], np.cumsum(step)])
    at = np.interp(theta, fine, tau)
    assert np.allclose(at, np.linspace(0.0, s.cycle_time, n), atol=1e-4 * s.cycle_time)
    turn = np.abs(loops.joint_angles(jf, t)[1:-1, m])  # the motor joint's angle
    assert np.allclose(np.minimum(turn, 2 * np.pi - turn),
                       np.minimum(theta[1:-1], 2 * np.pi - theta[1:-1]), atol=1e-9)


def test_cli_refuses_existing_output(tmp_path, capsys):
    out = tmp_path / "loop.glb"
    out.write_bytes(b"old")
    assert main(["animate", str(TV8), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "already exists" in err[0] and "--force" in err[0]
    assert out.read_bytes() == b"old"


@pytest.mark.parametrize("argv", [["--frames", "1"], ["--seconds", "0"], ["--frames", "x"]])
def test_cli_bad_option(tmp_path, capsys, argv):
    out = tmp_path / "loop.glb"
    assert main(["animate", str(TV8), "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and argv[0] in err[0]
    assert not out.exists()


@pytest.mark.parametrize("name", ["loop.gltf", "folder.glb"])
def test_cli_refuses_unusable_output_before_solving(tmp_path, capsys, monkeypatch, name):
    (tmp_path / "folder.glb").mkdir()

    def no_solve(*args, **kwargs):
        raise AssertionError("solved before checking the output")

    monkeypatch.setattr(pipeline, "solve", no_solve)
    assert main(["animate", str(TV8), "--out", str(tmp_path / name)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert not (tmp_path / "loop.gltf").exists()


def test_cli_not_realized_exit_3(tmp_path, capsys, monkeypatch):
    solve = pipeline.solve

    def unrealized(design, **kwargs):
        return dataclasses.replace(solve(design, realize=False), realization=None,
                                   realization_report={"status": "not_found",
                                                       "reason": "no luck\nat all"})

    monkeypatch.setattr(pipeline, "solve", unrealized)
    out = tmp_path / "loop.glb"
    assert main(["animate", str(TV8), "--out", str(out)]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no collision-free realization" in err[0]
    assert "no luck at all" in err[0]  # the reason, on the same line
    assert not out.exists()


# --- the printed parts (printed.animation, paraloop animate --printed) ----------------------


def test_printed_parts_animation_follows_the_kinematics():
    """The printed loop's animation: six animated link nodes holding every built part and
    piece of hardware (mm), the grounded link still, every node at each keyframe where the
    loop's link poses (relative to the grounded link) put it, the whole standing on its
    table: root = Z-up to Y-up o world_from_home o the centre."""
    pr = F.printed()
    asm, g = pr.assembly, pr.base.link
    frames, seconds = 9, 3.0
    glb, how = printed.animation(pr, DriveSettings(), frames, seconds)
    doc, blob = read_glb(glb)
    extras = doc["asset"]["extras"]
    assert extras["resting_link"] == g and "millimetres" in extras["units"]
    assert extras["frames"] == frames and extras["seconds"] == seconds
    nodes = doc["nodes"]
    (root_index,) = doc["scenes"][doc["scene"]]["nodes"]
    root = nodes[root_index]
    anim = animated(doc, blob)
    assert len(anim) == 6 and sorted(anim) == sorted(root["children"])
    centre = np.array(extras["centre"])
    shift = np.eye(4)
    shift[:3, 3] = centre
    z_to_y = np.eye(4)
    z_to_y[:3, :3] = Z_TO_Y
    root_m = np.array(root["matrix"], float).reshape(4, 4).T
    world = pr.base.world_from_home()
    assert np.allclose(root_m, z_to_y @ world @ shift, atol=1e-9)
    # the keyframes' parameters: the design's drive with the grounded link resting
    plan = drive_plan.plan_drive(asm.joint_factors, DriveSettings(), resting_link=g)
    assert f"motor joint {plan.motor}" in how
    if plan.schedule is not None:
        t = animate.scheduled_parameters(asm.joint_factors, plan.schedule, frames)
    else:
        t = animate.motor_parameters(asm.joint_factors, plan.motor,
                                     np.linspace(0.0, 2 * np.pi, frames))
    poses = dq.to_matrix(loops.link_poses(asm.joint_factors, t))
    poses[..., :3, 3] *= asm.scale
    rel = np.linalg.inv(poses[:, g, None]) @ poses  # (frames, 6, 4, 4), mm
    size = float(np.ptp(asm.bars[0].reshape(-1, 3), axis=0).max())
    for link in range(6):
        index = next(i for i in root["children"] if nodes[i]["name"] == f"link_{link}")
        keys = anim[index]
        if link == g:  # the grounded link stands still
            assert np.allclose(keys["translation"], 0.0, atol=1e-6 * size)
            assert np.allclose(np.abs(keys["rotation"][:, 3]), 1.0, atol=1e-6)
        # the node's meshes: the link's parts and hardware, stored relative to the centre
        prims = doc["meshes"][nodes[index]["mesh"]]["primitives"]
        verts = np.concatenate([accessor(doc, blob, p["attributes"]["POSITION"])
                                for p in prims]) + centre
        solids = [p.manifold for p in asm.parts if p.link == link]
        solids += [h.solid for h in asm.hardware if h.link == link]
        assert len(prims) == len(solids)
        home = np.concatenate([F.mesh_of(s).vertices for s in solids])
        assert np.allclose(verts.min(0), home.min(0), atol=1e-4) and \
            np.allclose(verts.max(0), home.max(0), atol=1e-4)
        probe = home[:: max(1, len(home) // 20)]
        local = np.einsum("kab,pb->kpa", rotation(keys["rotation"]), probe - centre) + \
            keys["translation"][:, None]
        shown = np.einsum("ab,kpb->kpa", root_m[:3, :3], local) + root_m[:3, 3]
        want = np.einsum("kab,pb->kpa", rel[:, link, :3, :3], probe) + rel[:, link, None, :3, 3]
        want = np.einsum("ab,kpb->kpa", (z_to_y @ world)[:3, :3], want) + (z_to_y @ world)[:3, 3]
        assert np.abs(shown - want).max() < 1e-4 * size, link


def test_cli_animates_the_printed_loop(tmp_path, capsys):
    out = tmp_path / "printed.glb"
    assert main(["animate", str(TV8), "--printed", "--out", str(out), "--frames", "5"]) == 0
    assert "the printed parts" in capsys.readouterr().out
    doc, blob = read_glb(out.read_bytes())
    assert "millimetres" in doc["asset"]["extras"]["units"] and len(animated(doc, blob)) == 6
