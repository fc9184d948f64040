"""The end link printed in pieces, where in one piece it needs support: arms and end-effector
glued on steel dowel pins.

Frames and units: the home frame, mm.

Link 3 with an end-effector P (:mod:`endlink`) is one rigid part: two hexagonal bars from its
bosses to P. A curved P no print face lays flat (the shading panel's arc) leaves the whole
part standing on P's edge with its bars rising over support. Where the part laid as well as
it can needs support under more than :data:`layout.SUPPORT_AIM` of its downward-facing area
or stands taller than :data:`MAX_HEIGHT_PER_WIDTH` times its contact's width,
:func:`split_end_link` cuts each bar square to its axis :data:`STUBS_MM` from where it meets P:

* each **arm** (bar and boss) lies on a face of its hexagonal bar, like every link, the boss
  cut flat with that face where its bore keeps the wall and the room of :mod:`flat`;
* the **end** (P and the two bar stubs) rests on one of its own flat faces, cut flat there
  (a stub reaching past it loses its tip): the one needing the least support among those it
  stands on at most :data:`MAX_HEIGHT_PER_WIDTH` times as high as the narrowest width of
  its contact;
* at each cut a :data:`DOWEL_D_MM` x :data:`DOWEL_L_MM` steel dowel pin (ISO 8734) sits in
  coaxial blind bores, half in each piece (engaged 2 diameters each side), glued: it aligns
  the faces and takes the shear. The bores keep the printer's wall to every surface
  (checked on the solid itself, :func:`_inside`).

The pieces are the verified link less material (the bores, the arms' flat cuts): nothing
grows, so the collision certificate of the whole link holds for them glued. ``link_3.stl``
stays the assembled link (for CAD, the animation, the physics); the 3MF holds the pieces.
Where no cut keeps every wall or leaves one piece each, or a piece would still need more
support or stand taller than those aims, the link stays whole (:func:`split_end_link`
returns None; the export's warning says how it prints).
"""

from __future__ import annotations

from dataclasses import dataclass

import manifold3d as m3d
import numpy as np
import scipy.spatial
import trimesh

from paraloop_core.fabrication import flat, layout, parts, sizing
from paraloop_core.fabrication.assembly import Assembly

#: The dowel pin (mm): ISO 8734, 3 mm x 12 mm, half in each piece.
DOWEL_D_MM, DOWEL_L_MM = 3.0, 12.0
#: Glue room (mm) past each end of the pin in its bore.
GLUE_MM = 0.5
#: Stub lengths (mm beyond the bore and its floor) tried for the cut, shortest first: a short
#: stub adds the least overhang to the end piece.
STUBS_MM = (1.0, 4.0, 10.0)
#: A part stands at most this many times as high as the narrowest width of its contact.
MAX_HEIGHT_PER_WIDTH = 3.0
#: Flat faces of the end piece tried to rest it on (the largest).
FACETS = 12
#: Largest share of the end piece's volume a flat cut under it may take.
END_CUT_SHARE = 0.15
#: A face lies on the bed when all its corners are this low (mm).
ON_BED_MM = 0.05


@dataclass(frozen=True)
class Dowel:
    """A glued dowel pin: centre ``origin`` ``(3,)`` on the cut, unit ``axis`` ``(3,)`` along
    the bar towards P, joining the pieces named ``pieces`` (arm, end)."""

    origin: np.ndarray
    axis: np.ndarray
    pieces: tuple[str, str]


@dataclass(frozen=True)
class Split:
    """Link ``link`` printed as ``meshes`` (name: trimesh, home frame, mm; arms first, then
    the end) laid on ``downs`` (name: unit down, home frame), joined by ``dowels``;
    ``removed_mm3``: the link's volume in no piece (bores, the arms' flat cuts)."""

    link: int
    meshes: dict[str, trimesh.Trimesh]
    downs: dict[str, np.ndarray]
    dowels: tuple[Dowel, ...]
    removed_mm3: float

    def entry(self) -> dict:
        """The report's ``printed_as`` of the link."""
        return {"pieces": list(self.meshes), "removed_mm3": self.removed_mm3,
                "dowels": [{"pin": f"{DOWEL_D_MM:g} x {DOWEL_L_MM:g} mm steel dowel pin "
                                   "(ISO 8734), glued",
                            "origin_mm": d.origin.tolist(), "axis": d.axis.tolist(),
                            "depth_mm": [DOWEL_L_MM / 2 + GLUE_MM] * 2, "pieces": list(d.pieces)}
                           for d in self.dowels]}


def _components(man: m3d.Manifold) -> list[m3d.Manifold]:
    """The solid's components of volume (booleans on coplanar faces leave slivers of none)."""
    return [m for m in man.decompose() if m.volume() > 1e-3]


def _one(man: m3d.Manifold) -> m3d.Manifold | None:
    """The solid's one component of volume, or None where it falls into more."""
    big = _components(man)
    return big[0] if len(big) == 1 else None


def _nearest(man: m3d.Manifold, point: np.ndarray) -> m3d.Manifold:
    """The component of ``man`` (of volume) nearest ``point``."""
    return min(_components(man), key=lambda m: np.linalg.norm(
        m.to_mesh().vert_properties[:, :3] - point, axis=1).min())


def _share(mesh: trimesh.Trimesh, down: np.ndarray) -> float:
    sup, area = layout.support(mesh.vertices, mesh.faces, down)
    return sup / area if area > 0 else 0.0


def stand_ratio(mesh: trimesh.Trimesh, down: np.ndarray) -> float:
    """Height over the narrowest width (calipers) of the faces lying on the bed when
    ``mesh`` rests on ``down`` (inf: it stands on an edge or a point)."""
    v = mesh.vertices @ layout.to_bed(down)[:3, :3].T
    z = v[:, 2] - v[:, 2].min()
    on = np.all(z[mesh.faces] <= ON_BED_MM, axis=1)
    pts = v[mesh.faces[on]].reshape(-1, 3)[:, :2]
    if len(pts) < 3 or np.linalg.matrix_rank(pts - pts.mean(0), tol=1e-6) < 2:
        return np.inf
    hull = pts[scipy.spatial.ConvexHull(pts).vertices]
    edge = np.roll(hull, -1, axis=0) - hull
    normal = np.stack([-edge[:, 1], edge[:, 0]], 1) / np.linalg.norm(edge, axis=1)[:, None]
    width = float(np.ptp(hull @ normal.T, axis=0).min())
    return float(z.max()) / width if width > 0 else np.inf


def _inside(solid: m3d.Manifold, p0: np.ndarray, p1: np.ndarray, radius: float) -> bool:
    """Whether the cylinder of ``radius`` from ``p0`` to ``p1`` lies inside ``solid`` (to a
    thousandth of its volume): a bore less the wall around it keeps that wall."""
    grown = parts.cylinder(p0, p1, radius)
    return (grown - solid).volume() <= 1e-3 * grown.volume()


def _arm_down(arm: m3d.Manifold, a: np.ndarray, u: np.ndarray, r: float, link_down: np.ndarray,
              joint, upper: bool, wall: float) -> tuple[m3d.Manifold, np.ndarray] | None:
    """The arm cut flat on the face of its hexagonal bar (:func:`parts.hex_node`: a face normal
    is the link's down projected off the bar, the others 60 deg apart) whose cut keeps the
    boss's wall and room (:func:`flat.lies_flat`) and needs the least support."""
    n0 = link_down - (link_down @ u) * u
    if np.linalg.norm(n0) < 1e-9:
        return None
    n0 /= np.linalg.norm(n0)
    best = None
    for k in range(6):
        t = np.pi / 3 * k
        d = np.cos(t) * n0 + np.sin(t) * np.cross(u, n0)
        level = float(d @ a + r * sizing.APOTHEM)
        if not flat.lies_flat(flat.wall_slack(d, level, [(joint, upper)], wall)):
            continue
        cut = _one(arm.trim_by_plane(tuple(-d), -level))
        if cut is None:
            continue
        share = _share(parts.part_trimesh(cut), d)
        if best is None or share < best[0]:
            best = (share, cut, d)
    return None if best is None else (best[1], best[2])


def _end_down(end: m3d.Manifold, bores: list[tuple[np.ndarray, np.ndarray]], bore: float,
              half: float, wall: float) -> tuple[m3d.Manifold, np.ndarray, float] | None:
    """``(piece, down, support share)`` of the end piece: resting on one of its flat faces
    (the largest first), cut flat there (a stub reaching past that face loses its tip; each
    bore keeps its wall, at most :data:`END_CUT_SHARE` of the volume goes), the one needing
    the least support among those standing at most :data:`MAX_HEIGHT_PER_WIDTH` times as
    high as their contact is wide (ties: the lower)."""
    mesh = parts.part_trimesh(end)
    order = np.argsort(-mesh.facets_area)[:FACETS]
    best = None
    for d, facet in zip(mesh.facets_normal[order], (mesh.facets[k] for k in order),
                        strict=True):
        level = float((mesh.vertices[mesh.faces[facet].ravel()] @ d).max())
        cut = _one(end.trim_by_plane(tuple(-d), -level))
        if cut is None or cut.volume() < (1 - END_CUT_SHARE) * end.volume() or not all(
                _inside(cut, x, x + (half + wall) * u, bore + wall) for x, u in bores):
            continue
        tm = parts.part_trimesh(cut)
        if stand_ratio(tm, d) > MAX_HEIGHT_PER_WIDTH:
            continue
        key = (_share(tm, d), float(np.ptp(tm.vertices @ d)))
        if best is None or key < best[0]:
            best = (key, cut, d)
    return None if best is None else (best[1], best[2], best[0][0])


def split_end_link(asm: Assembly, mesh: trimesh.Trimesh, down: np.ndarray) -> Split | None:
    """Link 3 with an end-effector (``asm.bars[3]`` two bars ``S_3 L``, ``R E_3``; ``mesh``
    the part, laid whole on ``down``) in pieces, where whole it needs support under more than
    :data:`layout.SUPPORT_AIM` of its downward area or stands more than
    :data:`MAX_HEIGHT_PER_WIDTH` times as high as its contact is wide, and the pieces meet
    both; else None (module docstring)."""
    if len(asm.bars) != 6 or len(asm.bars[3]) != 2 or (
            _share(mesh, down) <= layout.SUPPORT_AIM
            and stand_ratio(mesh, down) <= MAX_HEIGHT_PER_WIDTH):
        return None
    if len(asm.bars) != 6 or len(asm.bars[3]) != 2:
        return None
    link = asm.parts[3]
    whole = link.manifold
    r, wall = float(asm.plan.radii[3]), asm.printer.wall_mm
    bore = DOWEL_D_MM / 2 + asm.printer.hole_allowance_mm / 2
    half = DOWEL_L_MM / 2 + GLUE_MM
    # bar S_3 L leaves joint 2 (link 3 its upper side), bar R E_3 joint 3 (the lower side)
    (s3, left), (right, e3) = (np.asarray(b, float) for b in asm.bars[3])
    arms_at = ((s3, left, asm.joints[2], True), (e3, right, asm.joints[3], False))
    for stub in STUBS_MM:
        arms, dowels, downs, bores = [], [], {}, []
        for k, (a, b, joint, upper) in enumerate(arms_at):
            u = (b - a) / np.linalg.norm(b - a)
            x = b - (half + wall + stub) * u
            if (x - a) @ u < half + wall + joint.boss_radius:  # the bore clear of the boss
                break
            if not _inside(whole, x - (half + wall) * u, x + (half + wall) * u, bore + wall):
                break
            arm = _nearest(whole.trim_by_plane(tuple(-u), float(-(u @ x))), a)
            laid = _arm_down(arm, a, u, r, np.asarray(link.down, float), joint, upper, wall)
            if laid is None or not _inside(laid[0], x - (half + wall) * u, x, bore + wall):
                break
            name = f"link_3_arm_{k + 1}"
            arms.append((name, arm, laid[0]))
            downs[name] = laid[1]
            bores.append(parts.cylinder(x - half * u, x + half * u, bore))
            dowels.append(Dowel(x, u, (name, "link_3_end")))
        else:
            # the end: the link less a cylinder about each arm ending on its cut (the arms'
            # own faces would be coplanar with the link's and leave slivers), which must hold
            # its arm and nothing else
            end = whole
            for (_, arm, _), d in zip(arms, dowels, strict=True):
                v = parts.part_trimesh(arm).vertices - d.origin
                along = v @ d.axis
                reach = np.linalg.norm(v - along[:, None] * d.axis, axis=1).max() + 1.0
                cutter = parts.cylinder(d.origin + (along.min() - 1.0) * d.axis, d.origin,
                                        reach, 48)
                if abs((whole ^ cutter).volume() - arm.volume()) > 1e-4 * whole.volume():
                    break
                end = end - cutter
            else:
                end = _one(end)
            # the pieces tile the link: an arm reaching round through P to the other arm (a
            # large P crossing a cut's plane) holds the other arm too
            if not isinstance(end, m3d.Manifold) or end is whole or abs(
                    end.volume() + arms[0][1].volume() + arms[1][1].volume() - whole.volume()
            ) > 1e-4 * whole.volume() or (arms[0][1] ^ arms[1][1]).volume() > 1e-3:
                continue
            laid_end = _end_down(end, [(d.origin, d.axis) for d in dowels], bore, half, wall)
            if laid_end is None:
                continue
            meshes = {n: parts.part_trimesh(cut - bores[k]) for k, (n, _, cut) in enumerate(arms)}
            meshes["link_3_end"] = parts.part_trimesh(laid_end[0] - bores[0] - bores[1])
            if not all(m.is_watertight for m in meshes.values()):
                continue
            downs["link_3_end"] = laid_end[1]
            if any(_share(m, downs[n]) > layout.SUPPORT_AIM
                   or stand_ratio(m, downs[n]) > MAX_HEIGHT_PER_WIDTH
                   for n, m in meshes.items()):
                continue
            removed = whole.volume() - sum(m.volume for m in meshes.values())
            return Split(3, meshes, downs, tuple(dowels), float(removed))
    return None
