"""Carved link design spaces (paper Sec. 5.2) as meshes: the studio's *Carve design spaces* and
the export's carved link bodies.

Capsule design spaces of ``space_radius`` about the bars are carved in the user's order
(:mod:`carve`: wire cutting, then swept boolean differences over the whole cycle, voxels),
with joint zones kept clear for the joint hardware, and meshed (:mod:`meshing`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import carve, endlink, meshing, voxelspace
from paraloop_core.fabrication.progress import Progress

if TYPE_CHECKING:
    from paraloop_core.realization.ee_certificate import EndEffectorRealization
    from paraloop_core.realization.endeffector import EndEffector

#: Joint zone kept clear, as a multiple of the realization's bar radius (design units): room
#: for the bosses of the printed joint.
JOINT_ZONE = 3.0


def carve_design_spaces(joint_factors: np.ndarray, points: np.ndarray, radius: float,
                        space_radius: float | Sequence[float], *,
                        joint_radius: float | None = None, scale: float = 1.0,
                        resolution: int | None = None,
                        order: Sequence[tuple[int, int]] = carve.DEFAULT_ORDER,
                        effector: EndEffector | EndEffectorRealization | None = None,
                        progress: Progress | None = None,
                        ) -> tuple[carve.Carving, list[tuple[np.ndarray, np.ndarray] | None]]:
    """Carve capsule design spaces of ``space_radius`` (design units; see
    :func:`voxelspace.default_spaces`) in ``order``, the joint zones ``joint_radius`` (design
    units; default :data:`JOINT_ZONE` x ``radius``) kept clear, and mesh them (None where a
    space is too thin to mesh). Meshes in home frames, design units. ``resolution``: voxels
    along a space (None: :func:`voxelspace.auto_resolution`). With an ``effector`` link 3's
    space covers its bars ``S_3 L``, ``R E_3`` and P (:func:`endlink.link_space`, ``scale``
    mm per unit for its sheet thickness), and P, fixed in link 3, is removed with its sweep
    from every other space before the pairwise differences."""
    pts = np.asarray(points, float)
    resolution = resolution or voxelspace.auto_resolution(pts, space_radius)
    spaces = voxelspace.default_spaces(pts, space_radius, resolution=resolution)
    bars, fixed = None, []
    if effector is not None:
        el = endlink.end_link(effector, pts)
        r3 = float(np.ravel(space_radius)[3 if np.ndim(space_radius) else 0])
        spaces[3] = endlink.link_space(el, r3, scale, resolution)
        bars = [el.bars if i == 3 else None for i in range(6)]
        fixed = [(3, endlink.solid_space(el, spaces[3].pitch, scale))]
    zone = JOINT_ZONE * float(radius) if joint_radius is None else float(joint_radius)
    cv = carve.carve(joint_factors, pts, spaces, keep_radius=float(radius), joint_radius=zone,
                     order=order, bars=bars, fixed=fixed,
                     progress=None if progress is None else
                     (lambda f, m: progress(0.9 * f, m)))
    cv.report["resolution"] = resolution  # the automatic choice is worth reporting
    bodies = [carved_body(sp) for sp in cv.spaces]
    if progress is not None:
        progress(1.0, "carved spaces meshed")
    return cv, bodies


def carved_body(space: voxelspace.VoxelSpace) -> tuple[np.ndarray, np.ndarray] | None:
    """Mesh of a carved space (coarse first, then fine); None where it is too thin to mesh
    (the part then keeps just its bar)."""
    for stride in (2, 1):
        try:
            return meshing.space_mesh(space, stride=stride)
        except FabricationError:
            continue
    return None
