"""A :class:`physics_model.PhysicsModel` of an exported :class:`parts.Assembly`.

One body per part (its link; the grounding column and foot are in the grounded link's part,
so there is no separate base body), its mass the mesh volume times the density. Convex pieces:
each part lies in the union of its bounding capsules (``Part.capsules``, ``Part.radii``), so
their hulls, cut at the table plane (the parts are above it at home), are convex pieces that
contain the part: collisions between them are conservative (a contact may be reported where
the parts keep a gap smaller than the capsules' excess). Hinges: the loop's joint axes in mm
through the middle of each pin, oriented so that each angle grows over the cycle. The drive:
the design's drive plan (:func:`drive_plan.plan_drive`) with the grounded link resting, its
motor turned by the speed schedule (at constant speed where no schedule meets the limits),
sampled at equal times.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import trimesh

from paraloop_core.algebra import dq
from paraloop_core.design import DriveSettings
from paraloop_core.fabrication import animate
from paraloop_core.fabrication.export import part_trimesh
from paraloop_core.fabrication.parts import Assembly, Part
from paraloop_core.fabrication.physics_model import Body, Hinge, PhysicsModel, hinge_angles
from paraloop_core.linkage import drive_plan, loops

#: Samples of the cycle in the prediction (the pose check and the motor's reference).
SAMPLES = 601
#: Subdivisions of the icosphere whose points, at both ends, make a capsule's hull.
_SPHERE = trimesh.creation.icosphere(subdivisions=1).vertices


def model_from_assembly(asm: Assembly, grounded_link: int, table_z_mm: float,
                        drive: DriveSettings | None = None, samples: int = SAMPLES
                        ) -> PhysicsModel:
    """The physics model of ``asm`` (module docstring): ``grounded_link`` resting with the
    table at ``table_z_mm`` (the foot's underside, ``report["grounding"]["ground_z_mm"]``),
    the ``drive`` settings' motor, cycle and density (None: the defaults)."""
    drive = DriveSettings() if drive is None else drive
    jf = asm.joint_factors
    plan = drive_plan.plan_drive(jf, drive, resting_link=grounded_link)
    if plan.schedule is not None:
        t = animate.scheduled_parameters(jf, plan.schedule, samples)
    else:
        t = animate.motor_parameters(jf, plan.motor, np.linspace(0.0, 2 * np.pi, samples))
    poses = dq.to_matrix(loops.link_poses(jf, t))  # relative to link 0, design units
    poses = np.linalg.inv(poses[:, grounded_link:grounded_link + 1]) @ poses
    poses[..., :3, 3] *= asm.scale
    axes = loops.factor_axes(jf)
    # the point: the middle of the pin E_i S_{i+1} (on the axis, between the two links)
    hinges = tuple(Hinge(i, z.at(0.5 * z.length), axes[i, :3]) for i, z in enumerate(asm.zones))
    bodies = tuple(_body(p, drive.density_kg_m3, table_z_mm) for p in asm.parts)
    model = PhysicsModel(bodies, hinges, grounded_link, float(table_z_mm), plan.motor,
                         np.linspace(0.0, plan.cycle_time_s, samples), np.zeros(samples), poses)
    turn = hinge_angles(model)[-1]  # each joint turns once: +-2 pi
    hinges = tuple(replace(h, axis=h.axis * np.sign(turn[h.joint])) for h in hinges)
    model = replace(model, hinges=hinges)
    return replace(model, motor_angle=hinge_angles(model)[:, plan.motor])


def _body(part: Part, density_kg_m3: float, table_z_mm: float) -> Body:
    mesh = part_trimesh(part)
    pieces = []
    for (p0, p1), r in zip(part.capsules, part.radii, strict=True):
        hull = trimesh.convex.convex_hull(np.concatenate([p0 + r * _SPHERE, p1 + r * _SPHERE]))
        if hull.bounds[0, 2] < table_z_mm:
            hull = _above(hull, table_z_mm)
        if hull is not None:
            pieces.append(hull)
    return Body(part.name, part.link, mesh, mesh.volume * 1e-9 * density_kg_m3, tuple(pieces))


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
