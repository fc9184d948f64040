"""The input of the physics check (:mod:`physics`): parts as rigid bodies, hinges, the drive.

A neutral description, independent of how the parts are built (:mod:`physics_assembly` makes
one from an exported :class:`parts.Assembly`). Frame and units: the world frame of the
assembled home pose, z up, gravity -z, lengths in mm (MuJoCo's metres come in :mod:`mjcf`).
Time 0 is the home pose: every link pose of the prediction is the identity there, and the
meshes are where the link poses put them.

Hinge i joins link i and link (i + 1) % 6; its angle (:func:`hinge_angles`) is the rotation
of link i+1 relative to link i about ``axis`` (right-hand rule), 0 at home. The prediction
``link_poses`` must move every hinge as a rotation about its axis, keep the grounded link
still and turn the motor hinge by ``motor_angle``: :func:`check_model` refuses a model that
does not (so a sign or frame slip shows at once, not as a failed simulation).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.interpolate import CubicSpline

from paraloop_core.algebra import dq
from paraloop_core.errors import FabricationError

#: metres per mm: the model is in mm, MuJoCo in metres (:mod:`mjcf`); the one conversion.
M_PER_MM = 1e-3
#: Body names (they name MJCF bodies, geoms and meshes).
NAME = re.compile(r"[A-Za-z0-9_.-]+")
#: Gravity (m/s^2) in the world: the sculpture standing on its table, z up.
GRAVITY_WORLD = np.array([0.0, 0.0, -9.81])
#: Relative (to the model's size) and absolute (rad) slack of :func:`check_model`'s
#: consistency checks: float64 link poses agree to ~1e-12; 1e-6 leaves room for poses built
#: from rounded data without letting a wrong axis or sign through.
CONSISTENCY = 1e-6


@dataclass(frozen=True)
class Body:
    """One rigid piece: ``mesh`` (mm, home pose, world frame; closed: its mass properties
    give the centre of mass and inertia at uniform density), ``mass_kg``, the ``link`` it is
    rigidly attached to (0..5; -1: the base standing on the table, fixed to the grounded
    link) and ``convex`` pieces (same frame) for collisions; none: the mesh's convex hull
    touches the table only, and contacts with other parts are not checked for this body."""

    name: str
    link: int
    mesh: trimesh.Trimesh
    mass_kg: float
    convex: tuple[trimesh.Trimesh, ...] = ()


@dataclass(frozen=True)
class Hinge:
    """Hinge ``joint`` (between link i and link (i + 1) % 6): a point on its axis (mm, home
    pose) and the unit ``axis`` of positive rotation of link i+1 relative to link i."""

    joint: int
    point_mm: np.ndarray
    axis: np.ndarray


@dataclass(frozen=True)
class PhysicsModel:
    """Bodies, the six hinges, the grounded link (base bodies have link -1), the table plane
    ``z = table_z_mm``, the motor hinge and its schedule: ``time_s`` ``(N,)`` increasing from
    0, ``motor_angle`` ``(N,)`` rad relative to home (unwrapped, 0 .. 2 pi), and the kinematic
    prediction ``link_poses`` ``(N, 6, 4, 4)``: ``T_world_link`` (mm) with the grounded link
    still."""

    bodies: tuple[Body, ...]
    hinges: tuple[Hinge, ...]
    grounded_link: int
    table_z_mm: float
    motor_joint: int
    time_s: np.ndarray
    motor_angle: np.ndarray
    link_poses: np.ndarray


def size_mm(model: PhysicsModel) -> float:
    """Longest side (mm) of the bounding box of the bodies of the loop's links at home."""
    box = np.array([b.mesh.bounds for b in model.bodies if b.link >= 0])
    return float(np.max(box[:, 1].max(axis=0) - box[:, 0].min(axis=0)))


def hinge_angles(model: PhysicsModel) -> np.ndarray:
    """Angles ``(N, 6)`` (rad, unwrapped from 0) of the six hinges along the prediction:
    the rotation of ``T_i^-1 T_{i+1}`` about hinge i's axis."""
    poses = np.asarray(model.link_poses, float)
    rel = np.linalg.inv(poses) @ np.roll(poses, -1, axis=1)  # link i+1 in link i's frame
    axis = np.array([h.axis for h in model.hinges])
    rot = rel[..., :3, :3]
    skew = 0.5 * np.stack([rot[..., 2, 1] - rot[..., 1, 2], rot[..., 0, 2] - rot[..., 2, 0],
                           rot[..., 1, 0] - rot[..., 0, 1]], axis=-1)
    sin = np.einsum("nik,ik->ni", skew, axis)
    cos = 0.5 * (np.trace(rot, axis1=-2, axis2=-1) - 1.0)
    ang = np.unwrap(np.arctan2(sin, cos), axis=0)
    return ang - ang[:1]


def check_model(model: PhysicsModel) -> None:
    """Raise :class:`FabricationError` (``bad-parameters``) naming the field of a model that
    is malformed or inconsistent (module docstring)."""
    def bad(msg: str) -> FabricationError:
        return FabricationError(f"physics model: {msg}", "bad-parameters")

    if not (isinstance(model.grounded_link, int) and 0 <= model.grounded_link <= 5):
        raise bad(f"grounded_link must be in 0..5, got {model.grounded_link!r}")
    if not (isinstance(model.motor_joint, int) and 0 <= model.motor_joint <= 5):
        raise bad(f"motor_joint must be in 0..5, got {model.motor_joint!r}")
    if not np.isfinite(model.table_z_mm):
        raise bad("table_z_mm must be finite")
    if sorted(h.joint for h in model.hinges) != list(range(6)):
        raise bad("hinges must be the six joints 0..5, once each")
    for h in model.hinges:
        axis, point = np.asarray(h.axis, float), np.asarray(h.point_mm, float)
        if axis.shape != (3,) or point.shape != (3,) or not np.isfinite([*axis, *point]).all() \
                or abs(np.linalg.norm(axis) - 1.0) > CONSISTENCY:
            raise bad(f"hinge {h.joint}: point_mm and axis must be finite (3,), axis a unit "
                      "vector")
    names = [b.name for b in model.bodies]
    if len(set(names)) != len(names) or not all(NAME.fullmatch(n) for n in names):
        raise bad("body names must be distinct and made of letters, digits, '_', '-', '.' "
                  "(they name MJCF elements)")
    for b in model.bodies:
        if not (isinstance(b.link, int) and -1 <= b.link <= 5):
            raise bad(f"body {b.name}: link must be in -1..5, got {b.link!r}")
        if not (np.isfinite(b.mass_kg) and b.mass_kg > 0):
            raise bad(f"body {b.name}: mass_kg must be > 0, got {b.mass_kg!r}")
        if not b.mesh.is_volume:
            raise bad(f"body {b.name}: the mesh must be a closed volume (its mass properties "
                      "give the inertia)")
    if {b.link for b in model.bodies} - {-1} != set(range(6)):
        raise bad("every link 0..5 needs at least one body")
    time, angle = np.asarray(model.time_s, float), np.asarray(model.motor_angle, float)
    poses = np.asarray(model.link_poses, float)
    n = len(time)
    if time.ndim != 1 or n < 4 or time[0] != 0.0 or not (np.diff(time) > 0).all():
        raise bad("time_s must be (N,), N >= 4, increasing from 0")
    if angle.shape != (n,) or poses.shape != (n, 6, 4, 4) or \
            not np.isfinite(angle).all() or not np.isfinite(poses).all():
        raise bad(f"motor_angle must be ({n},) and link_poses ({n}, 6, 4, 4), finite")
    if not (np.diff(angle) > 0).all():
        raise bad("motor_angle must increase (the motor turns one way)")
    _check_prediction(model, poses, angle, bad)


def _check_prediction(model: PhysicsModel, poses: np.ndarray, angle: np.ndarray, bad) -> None:
    """The prediction starts at home, keeps the grounded link still, moves each hinge about
    its axis and turns the motor by ``motor_angle``."""
    tol = CONSISTENCY * max(size_mm(model), 1.0)
    if np.abs(poses[0] - np.eye(4)).max() > CONSISTENCY or \
            np.abs(poses[:, model.grounded_link] - poses[0, model.grounded_link]).max() > tol:
        raise bad("link_poses must start at home (identity) and keep the grounded link still")
    rel = np.linalg.inv(poses) @ np.roll(poses, -1, axis=1)
    for h in model.hinges:
        r = rel[:, h.joint]
        p, a = np.asarray(h.point_mm, float), np.asarray(h.axis, float)
        moved = r[:, :3, :3] @ p + r[:, :3, 3] - p
        if np.abs(moved).max() > tol or np.abs(r[:, :3, :3] @ a - a).max() > CONSISTENCY:
            raise bad(f"hinge {h.joint}: link_poses do not turn link {(h.joint + 1) % 6} about "
                      f"this axis relative to link {h.joint}")
    turned = hinge_angles(model)[:, model.motor_joint]
    if np.abs(turned - (angle - angle[0])).max() > 1e3 * CONSISTENCY or abs(angle[0]) > 1e-9:
        raise bad(f"motor_angle must start at 0 and be hinge {model.motor_joint}'s angle in "
                  "link_poses (sign: right-hand rule about the hinge axis)")


def mass_properties(body: Body) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass (mm, home) and inertia tensor about it (kg mm^2, home axes) of
    ``body`` at uniform density in its closed mesh."""
    props = body.mesh.mass_properties
    return (np.asarray(props["center_mass"], float),
            np.asarray(props["inertia"], float) * (body.mass_kg / props["mass"]))


def rigid_dynamics(model: PhysicsModel, gravity: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(inertia (N,) kg m^2, torque (N,) N m, its gravity part dU/dtheta (N,))`` of the
    mechanism as a rigid one-degree-of-
    freedom system along the prediction, the grounded link still: the inertia reduced to the
    motor hinge ``I = sum m |dc/dtheta|^2 + w^T I_b w`` (``w`` the body's turn per motor
    radian) and the motor torque ``I theta'' + I'(theta) theta'^2 / 2 + dU/dtheta`` (Lagrange
    for one coordinate; ``gravity`` (3,) m/s^2). Derivatives along the motor angle are finite
    differences over the samples (second order), theta' and theta'' those of a cubic spline
    of ``motor_angle(time)``; accurate to the sampling of the prediction."""
    poses = np.asarray(model.link_poses, float)
    theta = np.asarray(model.motor_angle, float)
    rot, pos = poses[..., :3, :3], poses[..., :3, 3]
    drot = np.gradient(rot, theta, axis=0)
    dpos = np.gradient(pos, theta, axis=0)
    skew = np.swapaxes(rot, -1, -2) @ drot  # skew(w) in the link's home frame per radian
    omega = 0.5 * np.stack([skew[..., 2, 1] - skew[..., 1, 2], skew[..., 0, 2] - skew[..., 2, 0],
                            skew[..., 1, 0] - skew[..., 0, 1]], axis=-1)  # (N, 6, 3)
    inertia, potential = np.zeros(len(theta)), np.zeros(len(theta))
    for b in model.bodies:
        link = model.grounded_link if b.link < 0 else b.link
        com, tensor = mass_properties(b)
        v = (np.einsum("nij,j->ni", drot[:, link], com) + dpos[:, link]) * M_PER_MM  # m/rad
        w = omega[:, link]
        inertia += b.mass_kg * np.einsum("ni,ni->n", v, v) + \
            np.einsum("ni,ij,nj->n", w, tensor, w) * M_PER_MM**2
        potential -= b.mass_kg * v @ np.asarray(gravity, float)
    spline = CubicSpline(np.asarray(model.time_s, float), theta)
    speed, accel = spline(model.time_s, 1), spline(model.time_s, 2)
    torque = inertia * accel + 0.5 * np.gradient(inertia, theta) * speed**2 + potential
    return inertia, torque, potential


def link_path(model: PhysicsModel, link: int, time_s: np.ndarray) -> np.ndarray:
    """``T_world_link`` ``(T, 4, 4)`` (mm) of ``link`` at ``time_s`` ``(T,)``: the product of
    the hinge rotations from the grounded link (still) to ``link`` (each about its home axis,
    as every body's frame is the world frame at home), the angles a cubic spline of
    :func:`hinge_angles` over ``model.time_s``: smooth between the prediction's samples and
    equal to ``link_poses`` at them."""
    angles = CubicSpline(np.asarray(model.time_s, float), hinge_angles(model), axis=0)(time_s)
    out = np.broadcast_to(np.eye(4), (len(angles), 4, 4)).copy()
    by_joint = {h.joint: h for h in model.hinges}
    for joint in (np.arange(model.grounded_link, model.grounded_link + (link -
                  model.grounded_link) % 6) % 6):
        h = by_joint[int(joint)]
        out = out @ dq.to_matrix(dq.rotation_about_line(h.axis, h.point_mm, angles[:, joint]))
    return out


def hand_links(model: PhysicsModel) -> tuple[int, ...]:
    """The links a hand may hold to turn the loop, the grounded link held too: the three not
    next to the grounded one, best first by how rigid their two half-chains (the hinges
    from the grounded link to it, and the rest) stay over the prediction. A half-chain
    between two held links is rigid where its hinges' screws are linearly independent; the
    measure is the least singular value of the screws ``(axis, moment / size)``, least over
    the samples and both halves (0: the loop moves there with both links held). A measure,
    not a proof: :func:`physics.simulate` tries the next where a hold loses the loop."""
    poses = np.asarray(model.link_poses, float)
    size = size_mm(model)
    screws = np.zeros((len(poses), 6, 6))
    for h in model.hinges:  # hinge j is carried by link j
        rot, shift = poses[:, h.joint, :3, :3], poses[:, h.joint, :3, 3]
        axis = rot @ np.asarray(h.axis, float)
        point = rot @ np.asarray(h.point_mm, float) + shift
        screws[:, h.joint] = np.concatenate([axis, np.cross(point, axis) / size], axis=-1)
    g, best = model.grounded_link, {}
    for k in ((g + 2) % 6, (g + 3) % 6, (g + 4) % 6):
        half = (np.arange((k - g) % 6) + g) % 6
        rest = np.setdiff1d(np.arange(6), half)
        best[k] = min(np.linalg.svd(screws[:, part], compute_uv=False)[:, -1].min()
                      for part in (half, rest))
    return tuple(sorted(best, key=lambda k: (best[k], k == (g + 3) % 6), reverse=True))
