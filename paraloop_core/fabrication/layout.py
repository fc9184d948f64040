"""Laid for printing: each part's orientation on the bed, its support, the plates.

* **A link's print flat** (:func:`choose_down`): a link is printed lying on one flat face of its
  hexagonal bar (layers along the bar: the strong direction). Which face is free (a turn
  about the bar); it is chosen so that cutting everything below that face off (bosses become
  flat on the bed) leaves every bore its wall (:mod:`flat`; else a turn cut deeper), among
  those laid so that the part fits the bed where one does, and then so that the least surface
  needs support, judged on the part itself at coarse resolution (the lowest ones compete).
* **Support** (:func:`support`): a downward face needs support when it leans more than
  :data:`OVERHANG_DEG` from the vertical, where it lies above the first layers (a face is
  cut exactly at :data:`FIRST_LAYER_MM`); reported per part as area and as the share of the
  part's downward-facing area.
* **Plates** (:func:`bed_layout`): footprints turned to their smallest box (diagonally where a
  part needs it), in rows, largest first, :data:`GAP_MM` apart and :data:`bed.EDGE_MM` from
  the bed's edges (the room the sizing fitted them to); a new plate when the bed is full.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.spatial
import trimesh

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import bed, flat, profiles, sizing
from paraloop_core.fabrication.joints import Joint

#: Steepest overhang (degrees from the vertical) printed without support.
OVERHANG_DEG = 45.0
#: Height (mm) above the bed within which a face counts as the first layers (no support).
FIRST_LAYER_MM = 0.3
#: How many of the print flats whose cut keeps the walls (:mod:`flat`) are built (coarsely) to
#: measure their support.
TRIALS = 4
#: Print flats compete on support only among those at most this many times as high as the
#: lowest (plus 1 mm).
TALLER = 1.5
#: Gap between parts on a plate (mm).
GAP_MM = 5.0
#: Largest share of a part's downward-facing area printed over support without a warning.
SUPPORT_AIM = 0.2


def to_bed(down: np.ndarray) -> np.ndarray:
    """``(4, 4)`` rotation taking ``down`` to ``-z``."""
    return trimesh.geometry.align_vectors(np.asarray(down, float), [0.0, 0.0, -1.0])


def support(vertices: np.ndarray, faces: np.ndarray, down: np.ndarray) -> tuple[float, float]:
    """``(support area, downward-facing area)`` (mm^2) of a mesh printed with ``down`` towards
    the bed (module docstring)."""
    v = np.asarray(vertices, float) @ to_bed(down)[:3, :3].T
    tri = v[np.asarray(faces)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(n, axis=1)
    nz = np.divide(n[:, 2], 2 * area, out=np.zeros(len(area)), where=area > 0)
    steep = nz < -np.cos(np.radians(OVERHANG_DEG))
    above = _above(tri[steep, :, 2] - v[:, 2].min(), FIRST_LAYER_MM)
    return float(area[steep] @ above), float(area[nz < -1e-9].sum())


def _above(z: np.ndarray, level: float) -> np.ndarray:
    """Share ``(F,)`` of each planar triangle lying above the height ``level``, from its
    corners' heights ``z`` ``(F, 3)``: exact (height is linear on a triangle; a steep face
    touching the first layer at one corner still needs support over the rest)."""
    lo, mid, hi = np.sort(z, axis=1).T
    span = np.maximum(hi - lo, 1e-12)  # a flat triangle (span 0) is on one side: no division
    # the corner beyond the plane cuts off a similar triangle: its share is the square of
    # the ratio of heights along both edges from that corner
    low_tip = (level - lo) ** 2 / (span * np.maximum(mid - lo, 1e-12))
    high_tip = (hi - level) ** 2 / (span * np.maximum(hi - mid, 1e-12))
    return np.where(level <= lo, 1.0, np.where(level >= hi, 0.0, np.where(
        level <= mid, 1.0 - low_tip, high_tip)))


def laid_extent(vertices: np.ndarray, down: np.ndarray) -> np.ndarray:
    """Box extents ``(3,)`` (mm) of points ``(n, 3)`` resting on ``down``, turned about the
    vertical to their smallest footprint (principal axes)."""
    v = np.asarray(vertices, float) @ to_bed(down)[:3, :3].T
    xy = v[:, :2] - v[:, :2].mean(0)
    vt = np.linalg.svd(xy, full_matrices=False)[2]
    return np.r_[np.ptp(xy @ vt.T, axis=0), np.ptp(v[:, 2])]


def choose_down(bar: tuple[np.ndarray, np.ndarray], radius: float,
                joints: list[tuple[Joint, bool]], printer: profiles.Printer,
                build, more: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """``(down, slack)``: the print flat of a link (module docstring). ``build(down, lift)``
    makes the coarse part for a candidate (a manifold), cut ``lift`` mm below the bar's face
    (:func:`flat.lift`; None: not cut); among the candidates whose cut at the bar's face
    keeps every wall with room (:func:`flat.wall_slack` >= 0, else :func:`flat.lies_flat`), or
    else a few turns cut deeper, and the
    unit directions ``more`` ``(M, 3)`` (an end-effector's faces, not cut), the one with the
    least support area wins (ties: the lower part)."""
    downs = flat.down_candidates(bar)
    if more is not None:
        downs = np.vstack([downs, np.asarray(more, float).reshape(-1, 3)])
    slack = downs @ np.asarray(bar[0], float) + radius * sizing.APOTHEM - flat.depths(
        downs, joints, printer.wall_mm)
    turns = len(flat.TURNS_DEG)
    if more is not None:
        slack[turns:] = np.minimum(slack[turns:], -1.0)  # not perpendicular to the bar
    # the turns keeping the full room, else those keeping the least room, else all (lifted)
    ok = np.flatnonzero(slack[:turns] >= 0)
    ok = ok if len(ok) else np.flatnonzero(slack[:turns] >= flat.FLAT_SLACK)
    pool = ok if len(ok) else np.arange(turns)
    trials = [*pool[:: max(1, int(np.ceil(len(pool) / TRIALS)))], *range(turns, len(downs))]
    figures = {}  # trial: (support area, height)
    for k in trials:
        try:
            mesh = build(downs[k], flat.lift(slack[k]) if k < turns else None).to_mesh()
        except FabricationError:  # a cut of this trial leaves it in pieces: not this one
            continue
        v = mesh.vert_properties[:, :3]
        fits = bool(bed.laid_fit_factor(laid_extent(v, downs[k]), printer)[()] >= 1.0)
        figures[k] = (support(v, mesh.tri_verts, downs[k])[0], float(np.ptp(v @ downs[k])),
                      fits)
    if not figures:
        return downs[trials[0]], float(slack[trials[0]])
    if any(f for *_, f in figures.values()):  # laid so that it fits the bed, where one does
        figures = {k: f for k, f in figures.items() if f[2]}
    # a part standing tall is what comes off the bed mid-print: only the low ones compete
    low = min(h for _, h, _ in figures.values()) * TALLER + 1.0
    best = min((k for k, (_, h, _) in figures.items() if h <= low), key=lambda k: figures[k])
    return downs[best], float(slack[best])


@dataclass(frozen=True)
class Placement:
    """Where a part is printed: ``plate`` index, ``transform`` ``(4, 4)`` from its home frame
    (mm) to the plate (bed corner at the origin, z up), print ``height_mm``, ``contact_mm2``
    on the bed, ``support_mm2`` and ``downward_mm2``, its box on the plate from ``corner_mm``
    over ``extent_mm``."""

    name: str
    plate: int
    transform: np.ndarray
    height_mm: float
    contact_mm2: float
    support_mm2: float
    downward_mm2: float
    corner_mm: np.ndarray
    extent_mm: np.ndarray


def contact_area(mesh: trimesh.Trimesh, rot: np.ndarray) -> float:
    """Area (mm^2) of the faces lying on the bed after ``rot``."""
    v = trimesh.transform_points(mesh.vertices, rot)
    z = v[mesh.faces][:, :, 2].max(axis=1) - v[:, 2].min()
    nz = (mesh.face_normals @ rot[:3, :3].T)[:, 2]
    return float(mesh.area_faces[(z < 0.05) & (nz < -1 + 1e-6)].sum())


def _turn(xy: np.ndarray, room: np.ndarray) -> np.ndarray:
    """``(4, 4)`` turn about the vertical of a footprint's points ``xy`` ``(n, 2)`` (mm) that
    lets it grow the most inside ``room`` ``(2,)``: each of :data:`bed.TURNS` (both senses)
    measured on the points' hull itself (the sizing judged a box; the points' turned bounds
    never exceed the turned box's)."""
    hull = xy[scipy.spatial.ConvexHull(xy).vertices] if len(xy) > 2 else xy
    turns = np.concatenate([bed.TURNS, -bed.TURNS[1:]])
    c, s = np.cos(turns), np.sin(turns)
    x = np.ptp(hull[:, :1] * c - hull[:, 1:] * s, axis=0)
    y = np.ptp(hull[:, :1] * s + hull[:, 1:] * c, axis=0)
    best = float(turns[np.argmax(np.minimum(room[0] / np.maximum(x, 1e-12),
                                            room[1] / np.maximum(y, 1e-12)))])
    return trimesh.transformations.rotation_matrix(best, [0, 0, 1])


def bed_layout(meshes: dict[str, trimesh.Trimesh], downs: dict[str, np.ndarray],
               bed_mm: tuple[float, float, float]) -> list[Placement]:
    """Placements of ``meshes`` (home frame, mm) each resting on ``downs[name]`` on plates of
    the bed ``bed_mm``."""
    laid = {}
    for name, mesh in meshes.items():
        rot = to_bed(downs[name])
        xy = trimesh.transform_points(mesh.vertices, rot)[:, :2]
        to_box, _ = trimesh.bounds.oriented_bounds_2D(xy)
        turn = np.eye(4)
        turn[:2, :2], turn[:2, 3] = to_box[:2, :2], to_box[:2, 2]
        m = turn @ rot
        box = trimesh.transform_points(mesh.vertices, m)
        room = bed.room_xy(bed_mm)
        if np.any(np.ptp(box[:, :2], axis=0) > room):  # turned (diagonal) if that fits
            m = _turn(box[:, :2], room) @ m
            box = trimesh.transform_points(mesh.vertices, m)
        m = trimesh.transformations.translation_matrix(-box.min(axis=0)) @ m
        sup, downward = support(mesh.vertices, mesh.faces, downs[name])
        laid[name] = (m, np.ptp(box, axis=0), contact_area(mesh, m), sup, downward)
    edge = bed.EDGE_MM
    out, plate, x, y, row = [], 0, edge, edge, 0.0
    for name in sorted(laid, key=lambda n: -laid[n][1][1]):  # deepest first: even rows
        m, size, contact, sup, downward = laid[name]
        if x + size[0] > bed_mm[0] - edge and x > edge:  # next row
            x, y, row = edge, y + row + GAP_MM, 0.0
        if y + size[1] > bed_mm[1] - edge and y > edge:  # next plate
            plate, x, y, row = plate + 1, edge, edge, 0.0
        out.append(Placement(name, plate, trimesh.transformations.translation_matrix(
            [x, y, 0.0]) @ m, float(size[2]), contact, sup, downward, np.array([x, y, 0.0]),
            size))
        x, row = x + size[0] + GAP_MM, max(row, size[1])
    return sorted(out, key=lambda p: p.name)


def plate_files(meshes: dict[str, trimesh.Trimesh], layout: list[Placement]
                ) -> list[tuple[str, bytes]]:
    """One 3MF per plate with the parts (named) in print orientation."""
    files = []
    for plate in sorted({p.plate for p in layout}):
        scene = trimesh.Scene()
        for p in layout:
            if p.plate == plate:
                scene.add_geometry(meshes[p.name].copy().apply_transform(p.transform),
                                   node_name=p.name, geom_name=p.name)
        name = "paraloop.3mf" if plate == 0 else f"paraloop_plate{plate + 1}.3mf"
        files.append((name, scene.export(file_type="3mf")))
    return files


def layout_entry(layout: list[Placement], bed_mm: tuple[float, float, float]) -> dict:
    """The report's ``print_layout``: plates, and per part its plate, height, contact,
    support (area and share of the downward-facing area), transform, and bed fit."""
    parts = []
    for p in layout:
        far = p.corner_mm + p.extent_mm
        parts.append({"name": p.name, "plate": p.plate + 1, "height_mm": p.height_mm,
                      "footprint_mm": [float(p.extent_mm[0]), float(p.extent_mm[1])],
                      "contact_mm2": p.contact_mm2, "support_mm2": p.support_mm2,
                      "downward_mm2": p.downward_mm2,
                      "support_share": p.support_mm2 / p.downward_mm2 if p.downward_mm2 else 0.0,
                      "transform": p.transform.tolist(),
                      "fits_bed": bool(np.all(far <= np.asarray(bed_mm) + 1e-9))})
    return {"bed_mm": list(bed_mm), "plates": 1 + max(p.plate for p in layout),
            "overhang_deg": OVERHANG_DEG, "parts": parts,
            "method": "support: faces leaning more than 45 deg from the vertical, facing down, "
                      f"above the first {FIRST_LAYER_MM} mm; share of all downward faces"}
