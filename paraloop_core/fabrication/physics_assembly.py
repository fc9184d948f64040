"""A :class:`physics_model.PhysicsModel` of a printed loop (:class:`assembly.Assembly`).

The world is the sculpture standing on its table (``Base.world_from_home``; without a base,
the design's frame with the table under the lowest part). One body per printed part and per
piece of hardware: links with their printed pieces (caps, pins) and screws, nuts and washers
(on their joint's lower link: a piece about a joint axis is the same to either link); the rod
with the grounded link it is glued into; the base plate is the base (link -1), fixed to the
grounded link. Masses: mesh volume x
density (print material, steel for hardware). Convex pieces for collisions: each part lies in
the union of its capsules, whose hulls (cut at the table plane) contain it, so the contacts
found are conservative (a contact may be reported where the parts keep a gap smaller than the
capsules' excess); the base plate is its disc itself (its capsule is a ball over the whole
disc, which rose 90 mm over the table and met tv8's link 2, certified clear of the plate).
Hinges: the joint axes through the bosses' split, oriented so that each angle grows over the
cycle. The drive: the design's drive plan with the grounded link resting,
its motor turned by the speed schedule (at constant speed where no schedule meets the limits).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import trimesh

from paraloop_core.algebra import dq
from paraloop_core.design import DriveSettings
from paraloop_core.fabrication import animate, profiles
from paraloop_core.fabrication.assembly import Assembly
from paraloop_core.fabrication.check import part_trimesh
from paraloop_core.fabrication.physics_model import Body, Hinge, PhysicsModel, hinge_angles
from paraloop_core.linkage import drive_plan, loops

#: Samples of the cycle in the prediction (the pose check and the motor's reference).
SAMPLES = 601
#: The icosphere whose points, at both ends, make a capsule's hull.
_SPHERE = trimesh.creation.icosphere(subdivisions=1).vertices


def world_of(asm: Assembly) -> tuple[np.ndarray, int]:
    """``(T_world_home (4, 4), grounded link)``: standing on the base, or (no base) link 0
    resting with the table under the lowest part."""
    if asm.base is not None:
        return asm.base.world_from_home(), asm.base.link
    m = np.eye(4)
    m[2, 3] = -min(p.manifold.bounding_box()[2] for p in asm.parts)
    return m, 0


def model_from_assembly(asm: Assembly, material: profiles.Material,
                        drive: DriveSettings | None = None, samples: int = SAMPLES
                        ) -> PhysicsModel:
    """The physics model of ``asm`` (module docstring) printed in ``material``, driven by the
    ``drive`` settings' motor and cycle (None: the defaults)."""
    drive = DriveSettings() if drive is None else drive
    world, g = world_of(asm)
    jf = asm.joint_factors
    plan = drive_plan.plan_drive(jf, drive, resting_link=g)
    if plan.schedule is not None:
        t = animate.scheduled_parameters(jf, plan.schedule, samples)
    else:
        t = animate.motor_parameters(jf, plan.motor, np.linspace(0.0, 2 * np.pi, samples))
    poses = dq.to_matrix(loops.link_poses(jf, t))
    poses = np.linalg.inv(poses[:, g:g + 1]) @ poses  # the grounded link still
    poses[..., :3, 3] *= asm.scale
    poses = world @ poses @ np.linalg.inv(world)  # T_world_link for meshes in the world
    rot = world[:3, :3]
    hinges = tuple(Hinge(j.index, rot @ j.at(j.split) + world[:3, 3], rot @ j.w)
                   for j in asm.joints)
    rho = material.density_g_cm3
    plate = None if asm.base is None else asm.base.thickness
    bodies = [_body(p.name, -1 if p.role == "base" else p.link, p.manifold, p.capsules,
                    p.radii, rho, world, plate if p.role == "base" else None)
              for p in asm.parts]
    bodies += [_body(f"{h.role.replace(' ', '_')}_{h.joint}_{k}", h.link, h.solid,
                     h.capsule[None],
                     np.array([h.radius]), profiles.STEEL_G_CM3, world)
               for k, h in enumerate(asm.hardware)]
    model = PhysicsModel(tuple(bodies), hinges, g, 0.0, plan.motor,
                         np.linspace(0.0, plan.cycle_time_s, samples), np.zeros(samples), poses)
    turn = hinge_angles(model)[-1]  # each joint turns once: +-2 pi
    hinges = tuple(replace(h, axis=h.axis * np.sign(turn[h.joint])) for h in hinges)
    model = replace(model, hinges=hinges)
    return replace(model, motor_angle=hinge_angles(model)[:, plan.motor])


def _body(name: str, link: int, solid, capsules: np.ndarray, radii: np.ndarray,
          density_g_cm3: float, world: np.ndarray, plate_mm: float | None = None) -> Body:
    """A part as a body; ``plate_mm``: the base plate of that thickness on the table, whose
    first capsule (a ball over the whole disc, ample for the verification's broad phase)
    becomes the disc itself (the hull of its vertices up to its top face): a ball of the
    plate's radius stands that high over the table, where moving links pass."""
    mesh = part_trimesh(solid).apply_transform(world)
    caps = np.einsum("ij,nkj->nki", world[:3, :3], capsules) + world[:3, 3]
    pieces = []
    if plate_mm is not None:
        low = mesh.vertices[mesh.vertices[:, 2] <= plate_mm + 1e-6]
        pieces.append(trimesh.convex.convex_hull(low))
        caps, radii = caps[1:], radii[1:]
    for (p0, p1), r in zip(caps, radii, strict=True):
        hull = trimesh.convex.convex_hull(np.concatenate([p0 + r * _SPHERE, p1 + r * _SPHERE]))
        if hull.bounds[0, 2] < 0.0:
            hull = _above(hull, 0.0)
        if hull is not None:
            pieces.append(hull)
    return Body(name, link, mesh, mesh.volume * 1e-6 * density_g_cm3, tuple(pieces))


def _above(hull: trimesh.Trimesh, z: float) -> trimesh.Trimesh | None:
    """The part of the convex ``hull`` above the plane at height ``z`` (None if too thin):
    the hull of its vertices above and of its edges' crossings of the plane."""
    v = hull.vertices
    a, b = v[hull.edges_unique[:, 0]], v[hull.edges_unique[:, 1]]
    cross = (a[:, 2] - z) * (b[:, 2] - z) < 0
    s = (z - a[cross, 2]) / (b[cross, 2] - a[cross, 2])
    pts = np.concatenate([v[v[:, 2] >= z], a[cross] + s[:, None] * (b[cross] - a[cross])])
    if len(pts) < 4 or np.ptp(pts[:, 2]) <= 0:
        return None
    return trimesh.convex.convex_hull(pts)
