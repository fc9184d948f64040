"""The printed links (trees of :mod:`csg` and their manifold3d solids, mm, home pose, base
frame).

Link i is its bar and the bosses of its two joints (:mod:`joints`):

* the **bar** ``S_i E_i``: a regular hexagonal prism of corner radius ``R_i`` (the sizing's),
  one flat face towards the link's print-down direction ``down_i`` (:mod:`layout`); with an
  end-effector, link 3 is the bars ``S_3 L``, ``R E_3`` and P's solid (:mod:`endlink`);
* a **fillet** where the bar meets each boss: the convex hull of the boss and the bar's first
  ``B - R`` mm, so it stays within the boss's radius of the pin;
* the **joint zones** are cleared for the neighbour: everything of link j within
  ``reach + c + eps`` of joint j's axis on the neighbour's side of the split (and past the
  neighbour's boss, where its hardware sits) is cut away, so inside the zone each link is a
  solid of revolution about the shared axis and the two never meet at any joint angle;
* the **bosses** (cylinders about the joint axis), then the bores (the rod's a press fit in
  the grounded link) and room for the hardware outside the bosses' faces;
* the **print flat**: everything past the bar's down face is cut off (bosses become flat on the
  bed); :mod:`layout` chooses ``down_i`` so that the bores keep their walls.

Every part lies in its ``capsules`` (segments ``(n, 2, 3)``, ``radii`` ``(n,)``, tagged with
the joint whose zone they belong to, -1 for the body): the verification's broad phase.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import manifold3d as m3d
import numpy as np
import trimesh

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import csg, keel, profiles, sizing
from paraloop_core.fabrication.joints import GLUED_CAP_SLACK_MM, SEAT_MM, Joint, outward
from paraloop_core.fabrication.voxelspace import point_segment_distance

#: Polygon segments of round solids (bosses, bores) and the zone margin they need.
SEGMENTS = 48
#: Margin (mm) of every cut past what it clears: the polygon error of the round solids.
EPS_MM = 0.05
#: Added to a capsule's radius (mm) where the solid's own corners lie on it (a keel's box,
#: the base plate's rim): the mesh's rounding may put them a hair outside.
CAPSULE_SLACK_MM = 1e-4


@dataclass(frozen=True)
class Part:
    """One printed part: ``manifold`` (mm, home frame) inside the union of capsules
    ``capsules`` ``(n, 2, 3)`` with ``radii`` ``(n,)``; ``joint`` ``(n,)`` tags each capsule
    with the joint whose zone it belongs to (-1: the body); ``link`` the loop link it moves
    with (-1: the base on the table); ``down`` ``(3,)`` the face laid on the bed (home frame,
    unit; zero: :mod:`layout` chooses); ``role`` ``"link"``, ``"pin"``, ``"cap"``,
    ``"base"``; ``csg`` the tree ``manifold`` was evaluated from (:mod:`csg`; None: only
    the mesh is known); ``slabs`` ``(n, 4)`` (None: none) a unit normal and a half thickness
    per capsule: its material also lies within that distance of the plane through the
    capsule's midpoint (inf: no slab), so a flat disc is bounded by more than its ball."""

    name: str
    link: int
    manifold: m3d.Manifold
    capsules: np.ndarray
    radii: np.ndarray
    joint: np.ndarray
    down: np.ndarray = field(default_factory=lambda: np.zeros(3))
    role: str = "link"
    csg: csg.Node | None = None
    slabs: np.ndarray | None = None
    #: how far (mm) a lifted link's keel reaches below its bar's face (0: no keel)
    keel_mm: float = 0.0


def cylinder(p0: np.ndarray, p1: np.ndarray, radius: float, segments: int = SEGMENTS,
             roll: np.ndarray | None = None) -> m3d.Manifold:
    """Prism of ``segments`` sides (a cylinder for many) of corner ``radius`` with flat ends
    at ``p0``, ``p1`` (mm); with ``roll`` a corner points along it."""
    return csg.manifold(csg.prism(p0, p1, radius, segments, roll))


def hex_node(p0: np.ndarray, p1: np.ndarray, radius: float, down: np.ndarray) -> csg.Prism:
    """Regular hexagonal prism of corner ``radius`` from ``p0`` to ``p1`` with a flat face
    whose outward normal is ``down`` (projected off the bar)."""
    d = np.asarray(p1, float) - p0
    u = d / np.linalg.norm(d)
    n = np.asarray(down, float) - (np.asarray(down, float) @ u) * u
    n = n / np.linalg.norm(n) if np.linalg.norm(n) > 1e-9 else csg.frame_to(p0, p1)[:, 0]
    # manifold's hexagon has a corner on +x: turn it by 30 deg so a face normal is on +x
    corner = np.cos(np.pi / 6) * n + np.sin(np.pi / 6) * np.cross(u, n)
    return csg.prism(p0, p1, radius, 6, corner)


def hex_bar(p0: np.ndarray, p1: np.ndarray, radius: float, down: np.ndarray) -> m3d.Manifold:
    """:func:`hex_node` as a manifold."""
    return csg.manifold(hex_node(p0, p1, radius, down))


def _axis(j: Joint, s0: float, s1: float, r: float, sides: int = SEGMENTS) -> csg.Prism:
    return csg.prism(j.at(s0), j.at(s1), r, sides)


def boss(j: Joint, upper: bool, n: int = SEGMENTS) -> csg.Prism:
    """The boss of link j (``upper`` False) or link j+1 at joint ``j``."""
    s0, s1 = j.upper if upper else j.lower
    return _axis(j, s0, s1, j.boss_radius, n)


def zone_cut(j: Joint, upper: bool, c: float, n: int = SEGMENTS) -> csg.Prism:
    """What a link's body loses at joint ``j``: within ``reach + c + eps`` of the axis, on the
    neighbour's side of the split and on past the joint's far end (the neighbour's boss and
    hardware, with ``c`` of room)."""
    lo, hi = j.extent
    r = j.reach + c + EPS_MM
    if upper:
        return _axis(j, lo - c - 1.0, j.split + j.gap / 2, r, n)
    return _axis(j, j.split - j.gap / 2, hi + c + 1.0, r, n)


def outer_cut(j: Joint, upper: bool, c: float, far: float, n: int = SEGMENTS) -> csg.Prism:
    """What a link's body loses past its boss's outer face at joint ``j``: within the boss
    radius plus ``c`` of the axis, ``far`` mm on (a bar's end standing out past the face)."""
    r = j.boss_radius + c + EPS_MM
    if upper:
        return _axis(j, j.upper[1], j.upper[1] + far, r, n)
    return _axis(j, j.lower[0] - far, j.lower[0], r, n)


def holes(j: Joint, upper: bool, far: float, n: int = SEGMENTS) -> csg.Union:
    """Bore and, for the grounding rod, the way out, of one side of joint ``j``, with room for
    the hardware outside the bosses' faces; ``far`` (mm) how far past the joint that room
    must run to leave any bar end."""
    lo, hi = j.extent
    bore = j.bore[1 if upper else 0]
    if j.kind == "dowel" and j.rod_side == int(upper):  # its blind bore: from the floor on
        floor = j.axle.s1 if upper else j.axle.s0  # the dowel's end in it
        return csg.Union((_axis(j, lo - far, floor, bore, n) if upper else
                          _axis(j, floor, hi + far, bore, n),))
    if j.blind and j.rod_side != int(upper):
        # the turning link's bore is blind, its floor a clearance past the axle's tip
        end = j.axle.s1 + j.gap if upper else j.axle.s0 - j.gap
        return csg.Union((_axis(j, lo - far, end, bore, n) if upper else
                          _axis(j, end, hi + far, bore, n),))
    cuts = [_axis(j, lo - far, hi + far, bore, n)]
    if j.kind in profiles.FASTENERS:  # washer, head or nut on the outer face, and beyond
        r = profiles.FASTENERS[j.kind].reach_r_mm + SEAT_MM
        cuts.append(_axis(j, j.upper[1], hi + far, r, n) if upper else
                    _axis(j, lo - far, j.lower[0], r, n))
    if j.kind in ("rod", "dowel", "printed-pin"):  # the cap or head sits outside the boss:
        for p in j.pieces:
            if p.printed and p.role != "pin":  # room for it, from the boss's face outwards
                beyond = p.s0 >= j.length / 2
                cuts.append(_axis(j, p.s0 - j.gap if beyond else p.s0 - far,
                                  p.s1 + far if beyond else p.s1 + j.gap,
                                  p.radius + j.gap + EPS_MM, n))
    return csg.Union(tuple(cuts))


def fillet_length(j: Joint, radius: float) -> float:
    """Length (mm) of the bar a fillet takes in: ``B - R`` (at least 0.5 mm)."""
    return max(j.boss_radius - radius, 0.5)


def fillet(j: Joint, upper: bool, bar: tuple[np.ndarray, np.ndarray], radius: float,
           down: np.ndarray, n: int = SEGMENTS) -> csg.Hull:
    """Hull of a boss and the first ``B - R`` mm of the bar (``bar`` = (joint point, other
    end)) that meets it: the web that spreads the bar's load into the boss."""
    p0, p1 = bar
    length = float(np.linalg.norm(p1 - p0))
    f = min(fillet_length(j, radius), 0.5 * length)
    stub = hex_node(p0, p0 + (p1 - p0) * (f / length), radius, down)
    return csg.Hull((boss(j, upper, n), stub))


def keeled(body: csg.Node, bars: np.ndarray, radius: float, down: np.ndarray, bottom: float,
           neighbours: tuple[keel.Neighbour, ...] = (), wide: bool = True
           ) -> tuple[csg.Node, list[tuple]] | None:
    """``body`` with its bar ``(p0, p1)`` swept along ``down`` (its flat face's normal,
    perpendicular to the bar) past ``bottom`` mm below its axis (where the print flat cuts
    it at its full width, :mod:`keel`; not ``wide``: its face's width, the copy's side
    corners stopping above the cut), along the stretch :func:`keel.span` keeps clear of the
    ``neighbours``: the hull of the hexagonal bar and its copy moved down, its shortened ends
    sloping up at :data:`keel.END_SLOPE_DEG`. A bosses' cut face far below the bar (a bore
    that needs its wall) is so joined to the bar by a web on the bed instead of a bar printed
    over support. And its capsules (:func:`keel.capsule_radius`). None where no keel fits."""
    d = np.asarray(down, float)
    # wide: the copy's side corners below the cut (full width there); narrow: its bottom face
    sweep = bottom + keel.PAST_MM - (0.0 if wide else radius * sizing.APOTHEM)
    run = sweep / np.tan(np.radians(keel.END_SLOPE_DEG))  # the bottom faces' ends: that slope
    webs, caps = [], []
    for p0, p1 in bars:
        length = float(np.linalg.norm(p1 - p0))
        u = (p1 - p0) / length
        stretch = keel.span((p0, p1), radius, d, bottom, neighbours)
        if stretch is None:
            return None
        x0, x1 = stretch
        top = (p0 + max(x0 - run, 0.0) * u, p0 + min(x1 + run, length) * u)
        webs.append(csg.Hull((hex_node(*top, radius, d),
                              hex_node(p0 + x0 * u + sweep * d, p0 + x1 * u + sweep * d,
                                       radius, d))))
        caps.append((top[0] + bottom / 2 * d, top[1] + bottom / 2 * d,
                     keel.capsule_radius(radius, bottom) + CAPSULE_SLACK_MM, -1))
    return csg.Union((body, *webs)), caps


def link_part(i: int, bars: np.ndarray, radius: float, down: np.ndarray,
              joints: tuple[Joint, ...], printer_c: float, extra: m3d.Manifold | None = None,
              extra_capsules: list[tuple] = (), lift: float | None = 0.0,
              segments: int = SEGMENTS, keel_level: int = keel.WIDE,
              neighbours: tuple[keel.Neighbour, ...] = ()) -> Part:
    """Link ``i``: its ``bars`` ``(n, 2, 3)`` (mm, from ``S_i`` to ``E_i``; with an
    end-effector ``S_3 L``, ``R E_3``) of hex corner ``radius`` with flat face ``down``, its
    joints ``i - 1`` (upper side) and ``i`` (lower side), ``extra`` solids joined to it (P,
    a carved body), clearance ``printer_c``; cut at the print flat ``lift`` mm below the bar's
    down face (> 0 where a bore needs the cut deeper: the bar then prints over support; < 0
    into the bar; None: not cut, nor where it would cut an ``extra``); ``segments`` of round
    solids (fewer for trial parts). Raises :class:`FabricationError` when the cuts leave it
    in pieces. A link cut ``lift`` > 0 below its bar's face gets the bar's :func:`keeled` web
    down to the cut (``keel_level``: :data:`keel.WIDE`, ``NARROW`` or ``NONE``), where it
    clears the links on its joints (``neighbours``): it prints lying on it, not over
    support."""
    lower, upper = joints[i], joints[(i - 1) % 6]
    body = csg.Union(tuple(hex_node(p0, p1, radius, down) for p0, p1 in bars))
    caps = [(p0, p1, radius, -1) for p0, p1 in bars]
    keel_mm = float(lift) if keel_level != keel.NONE and extra is None and lift is not None \
        and lift > 0 else 0.0
    made = keeled(body, bars, radius, down, radius * sizing.APOTHEM + keel_mm, neighbours,
                  keel_level == keel.WIDE) if keel_mm else None
    if made is None:
        keel_mm = 0.0
    else:
        body, more = made
        caps += more
    if extra is not None:
        body = csg.Union((body, csg.Mesh(extra)))
        caps += list(extra_capsules)
    n = segments
    webs = (fillet(upper, True, (bars[0][0], bars[0][1]), radius, down, n),
            fillet(lower, False, (bars[-1][1], bars[-1][0]), radius, down, n))
    body = csg.Cut(csg.Union((body, *webs)), (zone_cut(lower, False, printer_c, n),
                                                zone_cut(upper, True, printer_c, n)))
    body = csg.Union((body, boss(lower, False, n), boss(upper, True, n)))
    # past each boss's outer face: a bar's end standing out is trimmed to the face (clean
    # faces for the head and the nut) unless the bar itself leaves that way, then the holes
    # run out through it (and the grounding rod's through anything of its own link)
    ends = ((lower, False, bars[-1][0] - bars[-1][1]), (upper, True, bars[0][1] - bars[0][0]))
    cuts = []
    for j, up, vec in ends:
        away = j.w if up else -j.w
        if outward(vec, away, radius, j.boss_radius + printer_c + EPS_MM) <= radius + 1.0:
            cuts.append(outer_cut(j, up, printer_c, radius + 1.0, n))
        out = 3.0 * radius + 10.0 if j.kind == "rod" else \
            outward(vec, away, radius, j.reach + EPS_MM) + 1.0
        cuts.append(holes(j, up, out, n))
    body = csg.Cut(body, tuple(cuts))
    # the print flat: nothing past the bar's down face (or ``lift`` below it)
    face = np.asarray(down, float)
    level = float(np.max(bars.reshape(-1, 3) @ face)) + radius * sizing.APOTHEM
    # an end-effector P is never cut: the flat only where P lies wholly above it
    clear = extra is None or float(np.max(np.asarray(
        extra.to_mesh().vert_properties[:, :3], float) @ face)) <= level + float(lift or 0.0)
    if lift is not None and clear:
        level += float(lift)
        body = csg.Trim(body, tuple(-face), -level)
    solid = _one_piece(csg.manifold(body), i)
    for j, up in ((lower, False), (upper, True)):
        s0, s1 = j.upper if up else j.lower
        # the boss and its fillet: within max(B, f + R) of the pin's points it spans
        reach = max(j.boss_radius, fillet_length(j, radius) + radius)
        caps.append((j.at(min(s0, 0.0 if not up else j.length)),
                     j.at(max(s1, 0.0 if not up else j.length)), reach, j.index))
    return Part(f"link_{i}", i, solid, np.array([[c[0], c[1]] for c in caps]),
                np.array([c[2] for c in caps]), np.array([c[3] for c in caps]), face, "link",
                csg.Largest(body), keel_mm=keel_mm)


def _one_piece(body: m3d.Manifold, link: int) -> m3d.Manifold:
    """``body`` as one solid: a carved island or a bar end cut off by a joint zone (a sliver
    the cuts leave) is dropped when it is small; a link cut through raises."""
    if body.status() != m3d.Error.NoError or body.is_empty():
        raise FabricationError(f"link {link} is not a valid solid ({body.status()})",
                               "not-watertight")
    keep, vols = csg.largest(body)
    if len(vols) > 1 and np.sort(vols)[-2] > 0.02 * vols.max():
        raise FabricationError(f"link {link} falls apart into {len(vols)} pieces between its "
                               "joints (a bar leaning over its pin is cut through)",
                               "falls-apart")
    return keep


def piece_solid(j: Joint, p: profiles.Fastener | object) -> csg.Prism:
    """A joint piece (:class:`joints.Piece`) as a solid: a cylinder, the nut a hexagon."""
    return _axis(j, p.s0, p.s1, p.radius, p.sides or SEGMENTS)


def piece_parts(joints: tuple[Joint, ...]) -> list[Part]:
    """The separately printed pieces (printed pins, pin caps, rod caps) as parts (module
    docstring of the loop below for the link each moves with)."""
    out = []
    for j in joints:
        for k, p in enumerate(q for q in j.pieces if q.printed):
            solid = piece_solid(j, p)
            if p.role in ("pin cap", "rod cap", "dowel cap"):  # its hole: the axle's end
                axle = j.axle
                hole = j.axle_d / 2 + (-profiles.PRINTED_CAP_PRESS_MM / 2
                                       if p.role == "pin cap" else GLUED_CAP_SLACK_MM)
                solid = csg.Cut(solid, (_axis(j, max(p.s0, axle.s0) - EPS_MM,
                                              min(p.s1, axle.s1) + EPS_MM, hole),))
            name = f"{p.role.replace(' ', '_')}_{j.index}" + (f"_{k}" if k > 1 else "")
            # a rod or dowel cap is glued on its axle: rigid with the link holding it; the
            # others turn about the axis with either link (the lower one, by convention)
            link = j.fixed_link if p.role in ("rod cap", "dowel cap") else j.index
            # a cap prints on its closed end, the hole up; a pin on its side (export)
            beyond = p.s0 >= j.length / 2
            down = np.asarray(j.w, float) * (1.0 if beyond else -1.0)
            out.append(Part(name, link, csg.manifold(solid),
                            np.array([[j.at(p.s0), j.at(p.s1)]]), np.array([p.radius]),
                            np.array([j.index]), down, p.role.split()[-1], solid))
    return out


def part_trimesh(solid: m3d.Manifold) -> trimesh.Trimesh:
    """A solid as a merged trimesh (mm, home frame): what the export writes."""
    mesh = solid.to_mesh()
    return trimesh.Trimesh(np.asarray(mesh.vert_properties[:, :3], float),
                           np.asarray(mesh.tri_verts, np.int64), process=True)


def pinched(man: m3d.Manifold) -> bool:
    """Two vertices at one position, or within trimesh's merge tolerance (a boolean can pinch
    a solid so): valid for manifold3d, but the exported mesh, merged by position as a slicer
    merges it, is open there."""
    return not part_trimesh(man).is_watertight


def check_solid(man: m3d.Manifold, name: str) -> None:
    if man.status() != m3d.Error.NoError or man.is_empty():
        raise FabricationError(f"{name} is not a valid manifold solid ({man.status()})",
                               "not-watertight")


def body_capsules(body: m3d.Manifold, p0: np.ndarray, p1: np.ndarray,
                  pieces: int = 16) -> list[tuple]:
    """Capsules about ``pieces`` consecutive pieces of the segment ``[p0, p1]`` containing
    ``body``: each triangle goes to the piece of its centroid's projection and the radius
    covers its vertices (a triangle lies in the convex hull of its vertices, a capsule is
    convex). A surface inside such a chain of capsules encloses nothing outside it."""
    mesh = body.to_mesh()
    tri = np.asarray(mesh.vert_properties[:, :3], float)[np.asarray(mesh.tri_verts)]
    d = p1 - p0
    t = np.clip((tri.mean(1) - p0) @ d / float(d @ d), 0.0, 1.0 - 1e-12)
    piece = (t * pieces).astype(int)
    ends = p0 + np.linspace(0.0, 1.0, pieces + 1)[:, None] * d
    # manifold3d keeps float32 vertices: the solid they came from may lie a rounding away
    pad = 4.0 * float(np.finfo(np.float32).eps) * float(np.abs(tri).max(initial=0.0))
    out = []
    for k in np.unique(piece):
        v = tri[piece == k].reshape(-1, 3)
        r = float(point_segment_distance(v, ends[k], ends[k + 1]).max()) + pad
        out.append((ends[k], ends[k + 1], r, -1))
    return out


def principal_capsules(body: m3d.Manifold, pieces: int = 16) -> list[tuple]:
    """:func:`body_capsules` along the extent of ``body``'s vertices on their principal axis."""
    v = np.asarray(body.to_mesh().vert_properties[:, :3], float)
    c = v.mean(0)
    axis = np.linalg.svd(v - c, full_matrices=False)[2][0]
    s = (v - c) @ axis
    return body_capsules(body, c + s.min() * axis, c + s.max() * axis, pieces)


def mesh_manifold(vertices: np.ndarray, faces: np.ndarray) -> m3d.Manifold:
    """A mesh as a manifold; empty where manifold3d refuses it."""
    mesh = m3d.Mesh(np.ascontiguousarray(vertices, np.float32),
                    np.ascontiguousarray(faces, np.uint32))
    man = m3d.Manifold(mesh)
    return man if man.status() == m3d.Error.NoError else m3d.Manifold()
