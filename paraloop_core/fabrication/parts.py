"""Printable link parts (manifold3d solids in mm) with joint hardware.

Scale: ``scale = size_mm / (longest side of the bounding box of the 12 polyline points)`` maps
design units to mm; parts are built in the home configuration (t = inf, base frame).

Joint i (axis A_i, pin ``E_i S_{i+1}`` of length L, unit ``w`` from ``E_i`` to ``S_{i+1}``,
axial coordinate ``s`` from ``E_i``) with boss radius R, boss length b, clearance c:

* link i: boss ``s in [-b, m - c/2]`` and a pin of radius r fixed in it, reaching to the far
  end of link i+1's boss (``s = L + b``; print-in-place: on through an axial gap c to a head of
  radius R, which captures link i+1);
* link i+1: boss ``s in [m + c/2, L + b]`` with a bore of radius ``r + c`` through it; the
  boss ends facing each other act as spacers with the axial gap c.

The split ``m`` (:func:`_split`) is per joint: a bar that leans back over the pin runs through
the zone beside the other link's boss, and the zone would notch it (a weak bar and a hairline
gap). So ``m`` moves away from such a bar, as far as both bars allow, else to the middle of
the conflict (``Zone.notch`` then says by how much each bar still reaches over).

Each link body (its bar as a capsule of radius rho, or a carved mesh) is cut by both **joint
zones** ``Z`` (cylinder of radius R about the axis covering all hardware) before the hardware is
added. So inside ``Z`` each part is a solid of revolution about the shared axis (the joint's
relative motion is a rotation about it): the two parts there never meet, with radial gap c
(pin/bore) and axial gap c (boss ends), for every joint angle. Verification uses this.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import manifold3d as m3d
import numpy as np

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication.voxelspace import point_segment_distance
from paraloop_core.linkage import loops

MIN_WALL_MM = 0.8  # default thinnest boss wall (typical FDM: 2 perimeters); PartSpec.wall_mm


@dataclass(frozen=True)
class PartSpec:
    """Fabrication parameters in mm (None: derived, see :func:`resolve_spec`)."""

    size_mm: float = 150.0
    clearance_mm: float = 0.3
    rho_mm: float | None = None
    boss_radius_mm: float | None = None
    pin_radius_mm: float | None = None
    boss_length_mm: float | None = None
    print_in_place: bool = False
    segments: int = 48
    #: thinnest wall: around a bore, and each boss's axial thickness where the pin is long
    #: enough for two (the split moves to keep it; sizing makes the pins long enough)
    wall_mm: float = MIN_WALL_MM


@dataclass(frozen=True)
class Zone:
    """Joint zone in mm: cylinder about ``origin + s w`` (``origin = E_i``, ``w`` towards
    ``S_{i+1}``, pin ``length``), ``s in [s0, s1]``, radius ``radius``."""

    origin: np.ndarray
    w: np.ndarray
    length: float
    s0: float
    s1: float
    radius: float
    eps: float
    gap: float
    #: axial ``s`` where the two bosses meet (their gap ``c`` centred on it)
    split: float
    #: mm by which link i's / link i+1's bar still reaches into the other's boss region
    notch: tuple[float, float]

    def at(self, s: float) -> np.ndarray:
        return self.origin + s * self.w


@dataclass(frozen=True)
class Part:
    """One printable link: ``manifold`` (mm, home frame) inside the union of capsules
    ``capsules`` ``(n, 2, 3)`` with ``radii`` ``(n,)``; ``joint`` ``(n,)`` tags each capsule
    with the joint whose hardware it bounds (-1: the body)."""

    name: str
    link: int
    manifold: m3d.Manifold
    capsules: np.ndarray
    radii: np.ndarray
    joint: np.ndarray


@dataclass(frozen=True)
class Assembly:
    """The six parts, the mm-per-design-unit ``scale``, the resolved ``spec``, the joint
    ``zones`` and the loop's ``joint_factors`` (for the motion)."""

    parts: tuple[Part, ...]
    scale: float
    spec: PartSpec
    zones: tuple[Zone, ...]
    joint_factors: np.ndarray


def design_scale(points: np.ndarray, size_mm: float) -> float:
    """mm per design unit so that the polyline's longest bounding-box side is ``size_mm``."""
    if not (np.isfinite(size_mm) and size_mm > 0):
        raise FabricationError(f"size_mm must be > 0, got {size_mm}", "bad-parameters")
    ext = float(np.max(np.ptp(np.asarray(points, float), axis=0)))
    if not ext > 0:
        raise FabricationError("the linkage has zero extent", "bad-parameters")
    return size_mm / ext


def resolve_spec(spec: PartSpec, radius: float, scale: float) -> PartSpec:
    """Fill the derived sizes and validate. Defaults keep the printed geometry inside the
    realized (certified) radius minus clearances: bar ``rho = radius * scale - clearance``,
    boss radius ``radius * scale - clearance / 2`` (bosses then end at the joint points:
    boss length 0), pin ``min(boss / 2, boss - clearance - wall_mm)``. Raises
    :class:`FabricationError` (``bad-parameters``)."""
    c, wall = spec.clearance_mm, spec.wall_mm
    if not (np.isfinite(c) and c >= 0):
        raise FabricationError(f"clearance must be >= 0 mm, got {c}", "bad-parameters")
    if not (np.isfinite(wall) and wall > 0):
        raise FabricationError(f"wall must be > 0 mm, got {wall}", "bad-parameters")
    if spec.segments < 8:
        raise FabricationError("segments must be >= 8", "bad-parameters")
    rho = spec.rho_mm if spec.rho_mm is not None else radius * scale - c
    boss = spec.boss_radius_mm if spec.boss_radius_mm is not None else rho + c / 2
    pin = spec.pin_radius_mm if spec.pin_radius_mm is not None else \
        min(0.5 * boss, boss - c - wall)
    length = spec.boss_length_mm if spec.boss_length_mm is not None else 0.0
    for name, v in (("bar radius", rho), ("pin radius", pin), ("boss radius", boss)):
        if not (np.isfinite(v) and v > 0):
            # smallest size giving a 0.5 mm pin with the default proportions
            need = spec.size_mm * (2 * (c + wall) + c / 2) / max(radius * scale, 1e-9)
            raise FabricationError(
                f"{name} must be > 0 mm, got {v:.4g}: the realized bars are only "
                f"{radius * scale:.3g} mm thick at this size; use a size of at least "
                f"{np.ceil(need):.0f} mm, a larger realization radius or explicit radii",
                "bad-parameters")
    if not (np.isfinite(length) and length >= 0):
        raise FabricationError(f"boss length must be >= 0 mm, got {length}", "bad-parameters")
    if pin + c + wall > boss + 1e-9:
        raise FabricationError(
            f"pin radius {pin:.3g} + clearance {c:.3g} + wall {wall:g} mm exceeds the boss "
            f"radius {boss:.3g} mm", "bad-parameters")
    if not rho < boss:
        raise FabricationError(f"bar radius {rho:.3g} mm must be below the boss radius "
                               f"{boss:.3g} mm", "bad-parameters")
    return replace(spec, rho_mm=rho, boss_radius_mm=boss, pin_radius_mm=pin,
                   boss_length_mm=length)


def _frame_to(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """3x4 affine map taking the z axis segment [0, |p1-p0|] onto ``[p0, p1]``."""
    d = p1 - p0
    z = d / np.linalg.norm(d)
    x = np.cross(z, [1.0, 0, 0] if abs(z[0]) < 0.9 else [0, 1.0, 0])
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z, p0])


def cylinder(p0: np.ndarray, p1: np.ndarray, radius: float, segments: int) -> m3d.Manifold:
    """Solid cylinder of ``radius`` with flat ends at ``p0``, ``p1`` (mm)."""
    h = float(np.linalg.norm(p1 - p0))
    return m3d.Manifold.cylinder(h, radius, radius, segments).transform(_frame_to(p0, p1))


def capsule(p0: np.ndarray, p1: np.ndarray, radius: float, segments: int) -> m3d.Manifold:
    """Convex hull of two spheres of ``radius`` about ``p0``, ``p1``, tessellated in the bar's
    frame: world-aligned vertex rings would lie in faces through an end point (the end link's
    bars end at vertices of P) and give degenerate, non-watertight unions."""
    s = m3d.Manifold.sphere(radius, segments)
    h = float(np.linalg.norm(np.asarray(p1) - p0))
    if h == 0.0:
        return s.translate(tuple(p0))
    return m3d.Manifold.batch_hull([s, s.translate((0.0, 0.0, h))]).transform(_frame_to(p0, p1))


def _head_length(spec: PartSpec) -> float:
    return max(1.0, 0.5 * spec.boss_radius_mm)


def joint_zones(joint_factors: np.ndarray, pts: np.ndarray, spec: PartSpec,
                bars: list[np.ndarray] | None = None) -> list[Zone]:
    """The six joint zones (mm) of the polyline ``pts`` ``(12, 3)`` (mm) with the resolved
    ``spec``; ``bars[i]`` ``(n, 2, 3)`` (mm): link i's bars in order from ``S_i`` to ``E_i``
    (default the bar ``S_i E_i``), whose directions at the joints place the splits."""
    axes = loops.factor_axes(joint_factors)
    bars = bars if bars is not None else [pts[[2 * i, 2 * i + 1]][None] for i in range(6)]
    out = []
    head = spec.clearance_mm + _head_length(spec) if spec.print_in_place else 0.0
    # Zone margin: beats the polygon error r (1 - cos(pi/n)) of the cylinders (module doc).
    eps = max(0.05, 3.0 * (spec.boss_radius_mm + 1.0) * (1.0 - np.cos(np.pi / spec.segments)))
    for i in range(6):
        e, s = pts[2 * i + 1], pts[(2 * i + 2) % 12]
        length = float(np.linalg.norm(s - e))
        w = (s - e) / length if length > 1e-9 else axes[i, :3]
        lower, upper = bars[i][-1], bars[(i + 1) % 6][0]  # link i's bar ends at E_i, ...
        split, notch = _split(length, lower[0] - lower[1], upper[1] - upper[0], w, spec, eps, i)
        out.append(Zone(e, w, length, -spec.boss_length_mm, length + spec.boss_length_mm + head,
                        spec.boss_radius_mm, eps, spec.clearance_mm, split, notch))
    return out


def _split(length: float, lower: np.ndarray, upper: np.ndarray, w: np.ndarray, spec: PartSpec,
           eps: float, joint: int) -> tuple[float, tuple[float, float]]:
    """Split ``m`` of a joint (module docstring) and the notches left: ``lower`` is link i's
    bar from ``E_i`` (vector, mm), ``upper`` link i+1's bar from ``S_{i+1}``. A bar of radius
    rho leaving the axis at axial slope ``a`` and radial slope ``r`` has material within the
    zone cut's radius ``R + c + eps`` only up to the axial reach
    ``a (R + c + eps + rho) / r + rho`` (at most its length), which must stay on its own side
    of the split."""
    c, b, rho = spec.clearance_mm, spec.boss_length_mm, spec.rho_mm

    def reach(bar: np.ndarray, toward: np.ndarray) -> float:
        n = float(np.linalg.norm(bar))
        a = float(bar @ toward) / n if n > 0 else 0.0
        if a <= 0.0:
            return rho  # leans away: only the bar's rounded end
        r = np.sqrt(max(1.0 - a * a, 0.0))
        return a * min(n, (spec.boss_radius_mm + c + eps + rho) / max(r, 1e-12)) + rho

    floor, ceil = c / 2 - b + 4 * eps, length + b - c / 2 - 4 * eps  # bosses >= 4 eps long
    if floor > ceil:
        raise FabricationError(
            f"joint {joint}: pin {length:.3g} mm is too short for bosses with clearance {c} mm; "
            "raise the offsets or the boss length", "bad-parameters")
    if 2 * spec.wall_mm <= ceil - floor + 8 * eps + 1e-9:  # room for two bosses a wall thick
        floor, ceil = c / 2 - b + spec.wall_mm, length + b - c / 2 - spec.wall_mm
    lo = reach(lower, w) + c / 2 + eps  # link i's bar needs m >= lo
    hi = length - reach(upper, -w) - c / 2 - eps  # link i+1's bar needs m <= hi
    m = float(np.clip(length / 2, lo, hi) if lo <= hi else (lo + hi) / 2)
    m = float(np.clip(m, floor, ceil))
    return m, (max(0.0, lo - m), max(0.0, m - hi))


def _hardware(z: Zone, spec: PartSpec, upper: bool) -> list[tuple]:
    """Hardware pieces of one side of a joint: ``(p0, p1, radius, is_bore)`` cylinders."""
    c, b, length, at = spec.clearance_mm, spec.boss_length_mm, z.length, z.at
    mid = z.split
    # Without print-in-place the bore is blind: it stops c short of the boss's far end, where
    # this link's bar leaves the axis, and the pin stops c short of the bore's bottom. A bore
    # through that end would cut a bar leaving nearly along the axis off its boss (tv8's
    # link 4 fell apart in two pieces). Assembly: from the mid-plane side.
    if upper:
        return [(at(mid + c / 2), at(length + b), spec.boss_radius_mm, False),
                (at(mid + c / 2 - 1.0), at(length + b + (1.0 if spec.print_in_place else -c)),
                 spec.pin_radius_mm + c, True)]
    pieces = [(at(-b), at(mid - c / 2), spec.boss_radius_mm, False)]
    start = (mid - c / 2 - b) / 2  # pin root: middle of its own boss
    if spec.print_in_place:
        end, head = length + b + c, _head_length(spec)
        pieces += [(at(start), at(end + head / 2), spec.pin_radius_mm, False),
                   (at(end), at(end + head), spec.boss_radius_mm - 2 * z.eps, False)]
    else:
        pieces.append((at(start), at(length + b - 2 * c), spec.pin_radius_mm, False))
    return pieces


def build_assembly(joint_factors: np.ndarray, points: np.ndarray, radius: float,
                   spec: PartSpec = PartSpec(), bodies: list[np.ndarray] | None = None,
                   extras: dict[int, list[tuple[m3d.Manifold, np.ndarray, float]]] | None = None,
                   end_link: tuple[np.ndarray, m3d.Manifold] | None = None) -> Assembly:
    """Six parts from the loop ``joint_factors`` ``(6, 8)``, polyline ``points`` ``(12, 3)``
    and bar ``radius`` (design units). ``bodies``: optional carved bodies per link as
    ``(vertices (V, 3) design units, faces)`` pairs, joined with the bar (None: bar only).
    ``extras``: per link, additional solids in mm with a bounding capsule ``(2, 3)`` and radius
    (grounding). ``end_link``: link 3's bars ``(n, 2, 3)`` (design units; replacing ``S_3 E_3``)
    and a solid in mm joined with them (the end-effector P, :mod:`endlink`), bounded by
    :func:`principal_capsules`. Every part is checked to be a valid, non-empty manifold."""
    jf = np.asarray(joint_factors, float)
    pts = np.asarray(points, float)
    if jf.shape != (6, 8) or pts.shape != (12, 3) or not np.all(np.isfinite(pts)):
        raise FabricationError("need joint factors (6, 8) and finite points (12, 3)",
                               "bad-parameters")
    scale = design_scale(pts, spec.size_mm)
    spec = resolve_spec(spec, float(radius), scale)
    pmm = pts * scale
    bars = [pmm[[2 * i, 2 * i + 1]][None] for i in range(6)]
    if end_link is not None:
        bars[3] = np.asarray(end_link[0], float) * scale
    zones = joint_zones(jf, pmm, spec, bars)
    n = spec.segments
    parts = []
    for i in range(6):
        s_i, e_i = pmm[2 * i], pmm[2 * i + 1]
        segs = bars[i]
        body = m3d.Manifold.batch_boolean([capsule(p0, p1, spec.rho_mm, n) for p0, p1 in segs],
                                          m3d.OpType.Add)
        caps = [(p0, p1, spec.rho_mm, -1) for p0, p1 in segs]
        if i == 3 and end_link is not None:
            body = body + end_link[1]
            caps += principal_capsules(end_link[1])
        if bodies is not None and bodies[i] is not None:
            # The bar always stays (it ties the carved shape to the joints); carved islands
            # not touching it would print as loose pieces, so they are dropped.
            carved = _mesh_manifold(bodies[i][0] * scale, bodies[i][1])
            touching = [c for c in carved.decompose() if not (c ^ body).is_empty()]
            body = m3d.Manifold.batch_boolean([body, *touching], m3d.OpType.Add)
            if touching:
                caps += _body_capsules(m3d.Manifold.batch_boolean(touching, m3d.OpType.Add),
                                       s_i, e_i)
        for z, upper in ((zones[i], False), (zones[(i - 1) % 6], True)):
            body = body - zone_cut(z, upper, n)
        bores, hubs = [], []
        for j, upper in ((i, False), ((i - 1) % 6, True)):
            for p0, p1, r, is_bore in _hardware(zones[j], spec, upper):
                if is_bore:
                    bores.append(cylinder(p0, p1, r, n))
                else:
                    hubs.append(cylinder(p0, p1, r, n))
                    body = body + hubs[-1]
                    caps.append((p0, p1, r, j))
        for solid, cap, r in (extras or {}).get(i, []):
            body = body + solid
            caps.append((cap[0], cap[1], r, -1))
        for bore in bores:
            body = body - bore
        body = _joined(body, hubs, i)
        _check_manifold(body, f"link {i}")
        parts.append(Part(f"link_{i}", i, body, np.array([[c[0], c[1]] for c in caps]),
                          np.array([c[2] for c in caps]), np.array([c[3] for c in caps])))
    return Assembly(tuple(parts), scale, spec, tuple(zones), jf)


def _joined(body: m3d.Manifold, hubs: list[m3d.Manifold], link: int) -> m3d.Manifold:
    """``body`` without loose shards: where the cuts split it (a carved island cut off by a
    joint zone), only the piece holding the joint hardware ``hubs`` stays. Raises
    :class:`FabricationError` if the hardware itself ends up in separate pieces."""
    pieces = body.decompose()
    if len(pieces) == 1:
        return body
    keep = [p for p in pieces if any(not (p ^ h).is_empty() for h in hubs)]
    if len(keep) != 1:
        raise FabricationError(f"link {link} falls apart into {len(keep)} pieces between its "
                               "joints (a bar leaning over its pin is notched through); use a "
                               "larger size or a longer pin (realization offset d)",
                               "falls-apart")
    return keep[0]


def principal_capsules(body: m3d.Manifold, pieces: int = 16) -> list[tuple]:
    """:func:`_body_capsules` along the extent of ``body``'s vertices on their principal axis."""
    v = np.asarray(body.to_mesh().vert_properties[:, :3], float)
    c = v.mean(0)
    axis = np.linalg.svd(v - c, full_matrices=False)[2][0]
    s = (v - c) @ axis
    return _body_capsules(body, c + s.min() * axis, c + s.max() * axis, pieces)


def _body_capsules(body: m3d.Manifold, p0: np.ndarray, p1: np.ndarray,
                   pieces: int = 16) -> list[tuple]:
    """Capsules about ``pieces`` consecutive pieces of the bar ``[p0, p1]`` containing
    ``body``: each triangle goes to the piece of its centroid's projection and the radius
    covers its vertices (a triangle lies in the convex hull of its vertices, a capsule is
    convex). A surface inside such a chain of capsules encloses nothing outside it (moving
    away from the bar's line leaves every capsule), so the solid is covered too."""
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


def _mesh_manifold(vertices: np.ndarray, faces: np.ndarray) -> m3d.Manifold:
    """A carved body's mesh as a manifold; empty where manifold3d refuses it or nothing is
    left (a space carved thinner than float32 resolves): the link is then its bar alone."""
    mesh = m3d.Mesh(np.ascontiguousarray(vertices, np.float32),
                    np.ascontiguousarray(faces, np.uint32))
    man = m3d.Manifold(mesh)
    return man if man.status() == m3d.Error.NoError else m3d.Manifold()


def _check_manifold(man: m3d.Manifold, name: str) -> None:
    if man.status() != m3d.Error.NoError or man.is_empty():
        raise FabricationError(f"{name} is not a valid manifold solid ({man.status()})",
                               "not-watertight")


def zone_cut(z: Zone, upper: bool, segments: int) -> m3d.Manifold:
    """What a body loses at a joint: radius ``R - eps`` along its own boss (the boss, radius
    R, overlaps the rest: no coincident faces, no slits) and ``R + c + eps`` towards the
    neighbour, on to ``c + eps`` past the zone's far end: what is left there (a bar that leans
    over the joint) keeps the clearance c from the neighbour's boss and its end face."""
    e, r, mid, c = z.eps, z.radius, z.split, z.gap
    end = z.length - z.s0  # far end of the upper boss
    if upper:
        cuts = [(z.s0 - c - e, mid + c / 2 + e, r + c + e)]
        cuts += [(mid + c / 2 + e, end - e, r - e), (end - e, z.s1 + c + e, r + c + e)] \
            if z.s1 > end else [(mid + c / 2 + e, end - e, r - e)]
    else:
        cuts = [(z.s0 + e, mid - c / 2 - e, r - e), (mid - c / 2 - e, z.s1 + c + e, r + c + e)]
    return m3d.Manifold.batch_boolean([cylinder(z.at(a), z.at(b), rad, segments)
                                       for a, b, rad in cuts], m3d.OpType.Add)


def zone_solid(z: Zone, segments: int) -> m3d.Manifold:
    """Verification zone ``W`` (radius ``R + eps/2``) holding all hardware of the joint."""
    e = z.eps / 2
    return cylinder(z.at(z.s0 - e), z.at(z.s1 + e), z.radius + e, segments)


def zone_hulls(z: Zone, spec: PartSpec) -> tuple[m3d.Manifold, m3d.Manifold]:
    """Solids of revolution (up to the polygon error) containing each side's part inside
    :func:`zone_solid`: the lower side's boss region plus its pin (and head), and the upper
    side's boss region (its material left inside ``W``)."""
    e, n, mid = z.eps / 2, spec.segments, z.split
    lower = cylinder(z.at(z.s0 - e), z.at(mid - z.gap / 2), z.radius + e, n)
    for p0, p1, r, _ in _hardware(z, spec, False)[1:]:
        lower = lower + cylinder(p0, p1, r, n)
    end = z.length - z.s0 if spec.print_in_place else z.s1 + e
    return lower, cylinder(z.at(mid + z.gap / 2), z.at(end), z.radius + e, n)
