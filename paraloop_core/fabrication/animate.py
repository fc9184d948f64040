"""Animated glTF 2.0 (binary ``.glb``) of a realized loop over one full cycle.

**Scene.** A root node ``paraloop`` with the six link nodes ``link_0 .. link_5`` as children.
Link i's mesh is its bar ``S_iE_i`` and its pin ``E_iS_{i+1}`` (edges 2i and 2i+1 of the
realization's ``points``) as capsules of the bar radius, in the home configuration (t = inf,
base frame), one colour per link (those of ``assembly.glb``).

**Animation** ``cycle``: per link node a TRANSLATION and a ROTATION channel, LINEAR, sharing
one input of N times ``seconds k / (N - 1)``. Frame k is the link poses of
:func:`loops.link_poses` at a parameter t_k: by default where joint 0 (the base link's first
joint) has turned by ``-2 pi k / (N - 1)`` about its factor's ``+direction`` (the sense of
:func:`loops.joint_angles` as t runs from +inf down to -inf): joint 0 turns at constant speed
and the last frame is the first (home) after one full turn. With a motor speed schedule
(:func:`scheduled_parameters`; ``paraloop animate`` and the studio use the design's drive
plan), frame k is where the schedule's motor is at time ``T k / (N - 1)``. Rotations are
glTF ``xyzw`` quaternions, consecutive ones in the same hemisphere.

**Units and axes.** Lengths are design units (one glTF "metre" is one design unit; stated in
``asset.extras``). Designs are Z-up, glTF is Y-up: the root node rotates by -90 deg about X
(design +Z -> glTF +Y, design +Y -> glTF -Z), so the loop stands upright in any viewer.
Vertices and keyframes are float32, so they are stored relative to the loop's centre c (the
mean of the points; the root node translates by c, in double-precision JSON): link meshes hold
home coordinates minus c and link node i maps such a point v to ``R_i (v + c) + t_i - c`` for
the pose ``x -> R_i x + t_i`` of link i. A design far from the origin keeps float32 precision
relative to the loop's size.
"""

from __future__ import annotations

import json
import struct

import numpy as np
import trimesh

from paraloop_core.algebra import dq, poly
from paraloop_core.fabrication.export import LINK_COLORS
from paraloop_core.linkage import drive, loops
from paraloop_core.linkage.schedule import SpeedSchedule

#: Capsule tessellation (latitude, longitude sections): smooth at viewer scale, ~0.2 MB a file.
CAPSULE_COUNT = (12, 24)
_FLOAT, _UINT = 5126, 5125  # glTF componentType
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963  # glTF bufferView targets


def _finite_array(value: np.ndarray, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} has non-finite values")
    return arr


def _positive(value: float, name: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not (np.isfinite(x) and x > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return x


def _check_frames(frames: int) -> int:
    if isinstance(frames, bool) or not isinstance(frames, int | np.integer) or frames < 2:
        raise ValueError(f"frames must be an integer >= 2, got {frames!r}")
    return int(frames)


def keyframe_parameters(joint_factors: np.ndarray, frames: int) -> np.ndarray:
    """Parameters t ``(frames,)`` at which joint 0's angle is ``-2 pi k / (frames - 1)``;
    ``t = inf`` (home) at both ends. ``joint_factors`` ``(6, 8)``."""
    jf = _finite_array(joint_factors, (6, 8), "joint_factors")
    n = _check_frames(frames)
    root = loops.norm_roots(jf)[0]  # h_0 + i r of joint factor 0 (r = |vec h|)
    if not root.imag > 0:
        raise ValueError("joint factor 0 is not a rotation (zero vector part)")
    u = np.arange(n) / (n - 1)
    # Joint 0's angle is 2 atan2(-r, t - h_0) (loops.joint_angles), which is -2 pi u exactly
    # where t - h_0 = r cot(pi u) = r param_to_t(1 - u): inf at u = 0 and u = 1.
    return root.real + root.imag * poly.param_to_t(1.0 - u)


def motor_parameters(joint_factors: np.ndarray, motor: int, theta: np.ndarray) -> np.ndarray:
    """Parameters t ``(N,)`` at which joint ``motor`` has turned by ``theta`` ``(N,)`` rad
    since home, in :mod:`drive`'s sense (``t = a - b cot(theta / 2)``: t increasing); home
    (``t = inf``) where theta is a multiple of 2 pi."""
    _, a, b = drive.norm_roots(_finite_array(joint_factors, (6, 8), "joint_factors"))
    m = drive.check_index("motor", motor, 0, 5)
    theta = _finite_array(theta, np.shape(theta), "theta")
    if theta.ndim != 1:
        raise ValueError(f"theta must be a 1-D array of angles, got shape {theta.shape}")
    t = drive.gear(a, b, m, theta)[0]
    # home at both ends of a turn: gear's t is -inf at 0 but ~1e16 b at 2 pi (sin(pi) != 0)
    return np.where(np.abs(np.sin(0.5 * theta)) <= 4.0 * np.finfo(float).eps, np.inf, t)


def scheduled_parameters(joint_factors: np.ndarray, schedule: SpeedSchedule, frames: int
                         ) -> np.ndarray:
    """Parameters t ``(frames,)`` at the equal times ``k T / (frames - 1)`` of a motor speed
    ``schedule`` (:func:`schedule.speed_schedule`, T its cycle time) of the loop
    ``joint_factors``. Exact per step: ``x = omega^2`` is linear in the motor angle there, so
    ``omega`` is linear in time."""
    n, s = _check_frames(frames), schedule
    tau = np.linspace(0.0, s.time[-1], n)
    k = np.clip(np.searchsorted(s.time, tau, side="right") - 1, 0, len(s.time) - 2)
    w0, w1, step = s.motor_speed[k], s.motor_speed[k + 1], np.diff(s.theta)[k]
    w = w0 + (tau - s.time[k]) * (w1**2 - w0**2) / (2.0 * step)  # omega at tau
    with np.errstate(divide="ignore", invalid="ignore"):  # a step at constant speed: 0 / 0
        lam = np.where(np.abs(w1 - w0) > 1e-12 * w0, (w**2 - w0**2) / (w1**2 - w0**2),
                       (tau - s.time[k]) * w0 / step)
    theta = s.theta[k] + np.clip(lam, 0.0, 1.0) * step
    theta[-1] = s.theta[-1]  # the cycle closes at home exactly
    return motor_parameters(joint_factors, s.motor, theta)


def _capsule(p0: np.ndarray, p1: np.ndarray, radius: float) -> trimesh.Trimesh:
    """A capsule about the segment ``p0 p1`` (a sphere when the segment is a point)."""
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    mesh = trimesh.creation.capsule(height=length, radius=radius, count=CAPSULE_COUNT)
    if length > 0:  # trimesh's capsule lies along +z, centred at the origin
        mesh.apply_transform(trimesh.geometry.align_vectors([0.0, 0.0, 1.0], axis))
    mesh.apply_translation(0.5 * (p0 + p1))
    return mesh


def link_meshes(points: np.ndarray, radius: float) -> list[trimesh.Trimesh]:
    """Six meshes, link i = capsules of ``radius`` about its bar (points 2i, 2i+1) and its pin
    (points 2i+1, 2i+2 mod 12), in the coordinates of ``points`` ``(12, 3)``."""
    pts = _finite_array(points, (12, 3), "points")
    rho = _positive(radius, "radius")
    return [trimesh.util.concatenate([_capsule(pts[e], pts[(e + 1) % 12], rho)
                                      for e in (2 * i, 2 * i + 1)]) for i in range(6)]


def node_keyframes(joint_factors: np.ndarray, t: np.ndarray, centre: np.ndarray,
                   resting: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Link node keyframes at parameters ``t`` ``(T,)`` for meshes stored relative to
    ``centre`` ``(3,)``: translations ``(T, 6, 3)`` and rotations ``(T, 6, 4)`` (glTF xyzw,
    neighbours in one hemisphere), so that ``R (x - c) + tr + c`` is the link pose of
    :func:`loops.link_poses` relative to link ``resting`` (which stays still) applied to a
    home point ``x``."""
    jf = _finite_array(joint_factors, (6, 8), "joint_factors")
    c = _finite_array(centre, (3,), "centre")
    poses = dq.normalize(loops.link_poses(jf, t))  # (T, 6, 8) unit, p0 >= 0
    if resting:
        poses = dq.normalize(dq.mul(dq.conj(poses[:, resting, None]), poses))
        poses = np.where(poses[..., :1] < 0, -poses, poses)
    translation = dq.transform_points(poses, c) - c
    wxyz = poses[..., :4]
    # normalize() picks p0 >= 0, so a link turning past pi flips sign; interpolating between q
    # and -q would spin the long way round: flip every key into its predecessor's hemisphere.
    flip = np.einsum("kij,kij->ki", wxyz[1:], wxyz[:-1]) < 0
    wxyz[1:] *= np.cumprod(np.where(flip, -1.0, 1.0), axis=0)[..., None]
    return translation, wxyz[..., [1, 2, 3, 0]]


class _Buffer:
    """The BIN chunk being built: one bufferView (4-byte aligned) and accessor per array."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, array: np.ndarray, kind: str, target: int | None = None,
            bounds: bool = False) -> int:
        """Append ``array`` (rows = elements of glTF type ``kind``); returns its accessor."""
        is_int = np.issubdtype(np.asarray(array).dtype, np.integer)
        arr = np.ascontiguousarray(array, dtype="<u4" if is_int else "<f4")
        self.data += b"\0" * (-len(self.data) % 4)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": arr.nbytes}
        if target is not None:
            view["target"] = target
        self.data += arr.tobytes()
        self.views.append(view)
        acc = {"bufferView": len(self.views) - 1, "componentType": _UINT if is_int else _FLOAT,
               "count": len(arr), "type": kind}
        if bounds:  # required for POSITION and animation inputs; exact float32 values
            acc["min"] = np.atleast_1d(arr.min(axis=0)).tolist()
            acc["max"] = np.atleast_1d(arr.max(axis=0)).tolist()
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _linear_rgb(srgb: np.ndarray) -> list[float]:
    """glTF base colours are linear; ``srgb`` 0..255 as in ``assembly.glb``."""
    c = np.asarray(srgb, dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return [*lin.tolist(), 1.0]


def _glb(doc: dict, data: bytes) -> bytes:
    """GLB container: 12-byte header, JSON chunk (space padded), BIN chunk (zero padded)."""
    text = json.dumps(doc, separators=(",", ":"), allow_nan=False).encode()
    text += b" " * (-len(text) % 4)
    data += b"\0" * (-len(data) % 4)
    total = 12 + 8 + len(text) + 8 + len(data)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(text), b"JSON")
            + text + struct.pack("<I4s", len(data), b"BIN\0") + data)


def animated_glb(joint_factors: np.ndarray, points: np.ndarray, radius: float, *,
                 frames: int = 240, seconds: float = 10.0, t: np.ndarray | None = None,
                 meshes: list[list[tuple[trimesh.Trimesh, np.ndarray]]] | None = None,
                 resting: int = 0, world: np.ndarray | None = None, unit: str = "design units"
                 ) -> bytes:
    """Binary glTF 2.0 of the loop moving through one full cycle (module docstring).

    ``joint_factors`` ``(6, 8)`` (:mod:`paraloop_core.algebra.dq` convention), ``points``
    ``(12, 3)`` ``S_0, E_0, ..., S_5, E_5`` at home and the bar ``radius`` of a
    :class:`~paraloop_core.realization.certified.Realization`, design units; ``frames`` >= 2
    keyframes over ``seconds`` > 0, at the parameters ``t`` ``(frames,)`` if given (e.g.
    :func:`scheduled_parameters`: a motor's speed schedule), else :func:`keyframe_parameters`
    (joint 0 at constant speed). The printed loop: ``meshes`` per link its parts ``(mesh,
    rgb)`` in the coordinates of ``points`` (e.g. mm with points in mm), link ``resting``
    still (the grounded one, its base among its meshes), ``world`` ``(4, 4)`` placing the
    whole on the table (``Base.world_from_home``), ``unit`` named in the file. Raises
    ValueError on bad input."""
    jf = _finite_array(joint_factors, (6, 8), "joint_factors")
    pts = _finite_array(points, (12, 3), "points")
    rho = _positive(radius, "radius")
    n = _check_frames(frames)
    if t is None:
        t = keyframe_parameters(jf, n)
    elif np.shape(t) != (n,) or np.isnan(t).any():
        raise ValueError(f"t must be {n} parameters (inf allowed), got shape {np.shape(t)}")
    duration = _positive(seconds, "seconds")
    times = np.linspace(0.0, duration, n).astype(np.float32)
    if not (np.diff(times) > 0).all():  # glTF requires strictly increasing inputs
        raise ValueError(f"{n} frames over {duration:g} s are too close for float32 times")
    centre = pts.mean(axis=0)
    translation, xyzw = node_keyframes(jf, np.asarray(t, dtype=np.float64), centre, resting)
    if meshes is None:
        meshes = [[(m, LINK_COLORS[i])] for i, m in enumerate(link_meshes(pts, rho))]

    buf = _Buffer()
    gl_meshes, materials = [], []
    for i, items in enumerate(meshes):
        prims = []
        for mesh, rgb in items:
            prims.append({"attributes": {
                "POSITION": buf.add(mesh.vertices - centre, "VEC3", _ARRAY_BUFFER,
                                    bounds=True),
                "NORMAL": buf.add(mesh.vertex_normals, "VEC3", _ARRAY_BUFFER)},
                "indices": buf.add(mesh.faces.reshape(-1), "SCALAR", _ELEMENT_ARRAY_BUFFER),
                "material": len(materials), "mode": 4})
            materials.append({"name": f"link_{i}_{len(prims)}", "pbrMetallicRoughness": {
                "baseColorFactor": _linear_rgb(rgb), "metallicFactor": 0.0,
                "roughnessFactor": 0.6}})
        gl_meshes.append({"name": f"link_{i}", "primitives": prims})
    time_acc = buf.add(times, "SCALAR", bounds=True)
    samplers, channels = [], []
    for i in range(6):
        for path, values, kind in (("translation", translation, "VEC3"),
                                   ("rotation", xyzw, "VEC4")):
            samplers.append({"input": time_acc, "output": buf.add(values[:, i], kind),
                             "interpolation": "LINEAR"})
            channels.append({"sampler": len(samplers) - 1,
                             "target": {"node": 1 + i, "path": path}})

    # the root: design Z-up to glTF Y-up, after placing on the table, after the centre
    place = np.eye(4) if world is None else np.asarray(world, float)
    z_to_y = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])
    shift = np.eye(4)
    shift[:3, 3] = centre
    root = {"name": "paraloop", "children": list(range(1, 7)),
            "matrix": (z_to_y @ place @ shift).T.reshape(-1).tolist()}
    doc = {
        "asset": {"version": "2.0", "generator": "paraloop animate", "extras": {
            "units": f"{unit} (1 glTF unit = 1 {unit.rstrip('s')})",
            "axes": "design Z-up; the root node rotates it to glTF Y-up",
            "centre": centre.tolist(), "frames": n, "seconds": duration,
            "resting_link": resting}},
        "scene": 0,
        "scenes": [{"name": "paraloop", "nodes": [0]}],
        "nodes": [root] + [{"name": f"link_{i}", "mesh": i} for i in range(6)],
        "meshes": gl_meshes,
        "materials": materials,
        "animations": [{"name": "cycle", "samplers": samplers, "channels": channels}],
        "buffers": [{"byteLength": len(buf.data)}],
        "bufferViews": buf.views,
        "accessors": buf.accessors,
    }
    return _glb(doc, bytes(buf.data))
