"""What the physics check (:mod:`physics`) measures of a run: points carried by poses, a
link's bounding-box corners (where its pose error is measured), the base's motion relative to
its settled pose, the moving parts' height over the table. Units mm, poses ``(..., 4, 4)``."""

from __future__ import annotations

import numpy as np

from paraloop_core.fabrication.physics_model import M_PER_MM, Body, PhysicsModel, mass_properties


def points(poses: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` ``(..., P, 3)`` moved by ``poses`` ``(..., 4, 4)`` (broadcast)."""
    return np.einsum("...ij,...pj->...pi", poses[..., :3, :3], points) + poses[..., None, :3, 3]


def corners(bodies: list[Body]) -> np.ndarray:
    """The 8 corners ``(8, 3)`` (mm, home) of the bounding box of ``bodies``' meshes."""
    box = np.array([b.mesh.bounds for b in bodies])
    lo, hi = box[:, 0].min(axis=0), box[:, 1].max(axis=0)
    return np.array([[(lo, hi)[i >> k & 1][k] for k in range(3)] for i in range(8)])


def base_motion(model: PhysicsModel, root: np.ndarray, settled: tuple[np.ndarray, np.ndarray]
                ) -> tuple[float, float, float]:
    """Largest tilt (deg), rise of the lowest point and horizontal slide of the base group's
    centre of mass (mm) relative to the settled pose."""
    ref = np.eye(4)
    ref[:3, :3], ref[:3, 3] = settled[1], settled[0] / M_PER_MM
    rel = np.linalg.inv(ref) @ root
    cos = np.clip(0.5 * (np.trace(rel[:, :3, :3], axis1=1, axis2=2) - 1.0), -1.0, 1.0)
    tilt = float(np.degrees(np.arccos(cos)).max(initial=0.0))
    base = [b for b in model.bodies if b.link in (-1, model.grounded_link)]
    hull = np.concatenate([b.mesh.convex_hull.vertices for b in base])
    low = points(root, hull)[..., 2].min(axis=-1) - points(ref, hull)[:, 2].min()
    masses = np.array([b.mass_kg for b in base])
    com = masses @ np.array([mass_properties(b)[0] for b in base]) / masses.sum()
    slide = points(root, com[None])[:, 0, :2] - points(ref, com[None])[0, :2]
    return tilt, float(low.max(initial=0.0)), float(np.linalg.norm(slide, axis=-1).max(initial=0.0))


def table_clearance(model: PhysicsModel, poses: np.ndarray) -> float:
    """Least height (mm) of the moving bodies' hull vertices above the table with the links
    at ``poses`` ``(T, 6, 4, 4)`` (mm; inf if none)."""
    low = np.inf
    for b in model.bodies:
        if b.link not in (-1, model.grounded_link):
            z = points(poses[:, b.link], b.mesh.convex_hull.vertices)[..., 2]
            low = min(low, float(z.min(initial=np.inf)))
    return low - model.table_z_mm
