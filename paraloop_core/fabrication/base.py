"""A base that stands: the grounding rod, the base plate, the centre of mass over the cycle.

Grounding (paper Sec. 5.2, Fig. 10): one joint's axle is a metal rod (:data:`profiles.RODS`)
that goes on past the grounded link's boss down to a printed base plate. The rod is fixed in
the grounded link (press fit, glued) and in the plate's socket; the neighbour turns on it. The
sculpture stands with the rod vertical: its world is the grounded link's home frame turned so
that the rod points straight down (``Base.world_from_home``).

Every (joint, side) is tried (:func:`ground`):

* the rod (radius + clearance) must keep every moving link's required gap (:mod:`stiffness`)
  over the whole cycle: sampled capsule distances minus the sound displacement bound between
  samples (:mod:`motion_bound`);
* the table plane lies below everything that moves (same bound) by the socket's height and a
  gap, so nothing moving ever goes below the plate;
* the plate is a disc on the table around the rod's socket and the centre of mass: the
  centre of mass of the whole sculpture (links, hardware, rod, plate) over the cycle, projected
  on the table, stays :data:`MARGIN` of the plate's diameter inside its rim (plus how far it
  can move between samples); a heavier (thicker) plate is tried when a thin one would not fit
  the bed;
* the best is the one that stands with the smallest plate (the design's z nearest up as a
  tie-break), then the shortest rod; where none
  stands on a plate that fits the bed, the largest-margin one is kept and ``mount`` says how
  to fix it (screw the plate down through its holes).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from paraloop_core.algebra import dq, poly
from paraloop_core.fabrication import bed, csg, parts, profiles
from paraloop_core.fabrication.assembly import Assembly, Hardware
from paraloop_core.fabrication.parts import Part
from paraloop_core.fabrication.profiles import Rod
from paraloop_core.linkage import loops
from paraloop_core.realization.clearance import segment_distance
from paraloop_core.realization.motion_bound import chain_displacement_bounds

#: Centre of mass margin inside the plate's rim, as a share of the plate's diameter (the
#: issue's floor is 10 %: well inside it).
MARGIN = 0.15
#: Plate thicknesses tried (mm): a heavier plate pulls the centre of mass to its middle.
THICKNESS_MM = (5.0, 8.0, 12.0)
#: Gap (mm) between the plate's socket and anything that moves; socket height in rod diameters.
GAP_MM, SOCKET_D = 3.0, 1.5
#: Samples of the cycle for the centre of mass and the clearances.
SAMPLES = 360
#: The rod's clearance to each moving link per required gap.
GAP_MARGIN = 1.25
#: Wood screws that fix a plate that does not stand on its own (hole diameter, mm).
MOUNT_HOLE_MM = 4.5


@dataclass(frozen=True)
class Base:
    """The grounding: ``link`` (grounded), the rod on ``joint`` leaving past that link's boss,
    its ends ``top``/``bottom`` (mm, link g's home frame), the ``rod``; the standing frame
    ``frame`` ``(3, 3)`` (columns: two table directions and ``up``, along the rod); the plate
    ``center`` (table coordinates), ``radius``, ``thickness`` (mm) with its underside at
    height ``table`` (``up . x``); the centre of mass path ``com`` ``(T, 3)`` (mm, home) and
    ``margin_mm`` (its least distance inside the rim, less the motion between samples);
    ``clearance_mm`` (certified, rod to moving parts); ``stands``; ``mount`` words (None when
    it stands on its own); ``masses_g`` per link."""

    link: int
    joint: int
    top: np.ndarray
    bottom: np.ndarray
    rod: Rod
    frame: np.ndarray
    center: np.ndarray
    radius: float
    thickness: float
    table: float
    com: np.ndarray
    margin_mm: float
    clearance_mm: float
    stands: bool
    mount: str | None
    masses_g: np.ndarray

    @property
    def up(self) -> np.ndarray:
        return self.frame[:, 2]

    @property
    def rod_length_mm(self) -> float:
        return float(np.linalg.norm(self.top - self.bottom))

    @property
    def tilt_deg(self) -> float:
        """Angle between the standing sculpture's up and the design's z (degrees)."""
        return float(np.degrees(np.arccos(np.clip(self.up[2], -1.0, 1.0))))

    def world_from_home(self) -> np.ndarray:
        """``(4, 4)`` T_world_home: the sculpture standing on the table (z = 0, z up)."""
        m = np.eye(4)
        m[:3, :3] = self.frame.T
        m[2, 3] = -self.table
        return m


def standing_frame(up: np.ndarray) -> np.ndarray:
    """``(3, 3)`` columns: two table directions and ``up`` (the first one as near the design's
    x as it can be, so a rod along the design's z keeps the design's axes)."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    ref = np.array([1.0, 0, 0]) if abs(up[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = ref - (ref @ up) * up
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(up, e1), up])


def _mm_poses(jf: np.ndarray, scale: float, about: int, u: np.ndarray) -> np.ndarray:
    """``(T, 6, 4, 4)``: every link's pose in link ``about``'s home frame (mm)."""
    m = dq.to_matrix(loops.link_poses(jf, poly.param_to_t(u)))
    m[..., :3, 3] *= scale
    return np.linalg.inv(m[:, about, None]) @ m


def _moving(asm: Assembly, g: int) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """Per moving link (relative to ``g``): ``(link, segments (n, 2, 3), radii (n,))`` of its
    parts' and hardware's capsules (mm)."""
    out = []
    for link in range(6):
        if link == g:
            continue
        segs = [p.capsules for p in asm.parts if p.link == link]
        rads = [p.radii for p in asm.parts if p.link == link]
        segs += [h.capsule[None] for h in asm.hardware if h.link == link]
        rads += [np.array([h.radius]) for h in asm.hardware if h.link == link]
        out.append((link, np.concatenate(segs), np.concatenate(rads)))
    return out


def _bounds(asm: Assembly, g: int, link: int, segs: np.ndarray, u: np.ndarray) -> np.ndarray:
    """How far (mm) link ``link``'s capsule ends move, relative to ``g``, about each sample:
    the joint-angle bound (:func:`chain_displacement_bounds`: sound, cheap, and the samples
    here are dense enough that a speed bound would not change the answer)."""
    ends = segs.reshape(-1, 3) / asm.scale
    center = 0.5 * (ends.min(0) + ends.max(0))
    reach = float(np.max(np.linalg.norm(ends - center, axis=1)))
    return asm.scale * chain_displacement_bounds(asm.joint_factors, g, link, center, reach, u)


def _lowest(asm: Assembly, g: int, u: np.ndarray, poses: np.ndarray, up: np.ndarray) -> float:
    """Lowest height ``up . x`` (mm, link g's frame) any part reaches over the cycle, made safe
    between samples."""
    low = np.inf
    for p in asm.parts:
        if p.link == g:
            low = min(low, float(np.min(p.capsules @ up - p.radii[:, None])))
    for link, segs, rads in _moving(asm, g):
        rot = np.einsum("j,tjk->tk", up, poses[:, link, :3, :3])  # up in the link's frame
        z = np.einsum("tk,nmk->tnm", rot, segs) + (poses[:, link, :3, 3] @ up)[:, None, None]
        step = _bounds(asm, g, link, segs, u)
        low = min(low, float(np.min(z - rads[None, :, None] - step[:, None, None])))
    return low


def _rod_clearance(asm: Assembly, g: int, joint: int, top: np.ndarray, bottom: np.ndarray,
                   r: float, u: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Certified least distance (mm) ``(6,)`` between the rod (radius ``r``) and each moving
    link over the cycle (inf for ``g``; joint ``joint``'s own pieces are coaxial with the rod:
    left out)."""
    out = np.full(6, np.inf)
    for link, segs, rads in _moving(asm, g):
        moved = np.einsum("tij,nkj->tnki", poses[:, link, :3, :3], segs) + \
            poses[:, link, None, None, :3, 3]
        d = segment_distance(top, bottom, moved[..., 0, :], moved[..., 1, :]) - rads - r
        tags = np.concatenate([p.joint for p in asm.parts if p.link == link] +
                              [np.array([h.joint]) for h in asm.hardware if h.link == link])
        keep = tags != joint
        if keep.any():
            step = _bounds(asm, g, link, segs, u)
            out[link] = float(np.min(d[:, keep] - step[:, None]))
    return out


def _com(asm: Assembly, masses: np.ndarray, centers: np.ndarray, g: int, poses: np.ndarray,
         fixed_mass: float, fixed_center: np.ndarray) -> np.ndarray:
    """Centre of mass ``(T, 3)`` (mm, link g's frame): link masses ``(6,)`` (g) at home
    ``centers`` ``(6, 3)`` moved by ``poses``, plus a fixed mass (rod, plate) at its centre."""
    moved = np.einsum("tlij,lj->tli", poses[:, :, :3, :3], centers) + poses[:, :, :3, 3]
    total = masses.sum() + fixed_mass
    return (np.einsum("l,tli->ti", masses, moved) + fixed_mass * fixed_center) / total


def link_masses(asm: Assembly, density_g_cm3: float) -> tuple[np.ndarray, np.ndarray]:
    """Mass (g) and home centre of mass (mm) per link ``(6,), (6, 3)``: its printed parts at
    ``density_g_cm3`` and the steel hardware it carries."""
    mass, moment = np.zeros(6), np.zeros((6, 3))
    for solid, link, rho in [(p.manifold, p.link, density_g_cm3) for p in asm.parts
                             if 0 <= p.link < 6] + \
            [(h.solid, h.link, profiles.STEEL_G_CM3) for h in asm.hardware if 0 <= h.link < 6]:
        mesh = solid.to_mesh()
        v = np.asarray(mesh.vert_properties[:, :3], float)
        tri = v[np.asarray(mesh.tri_verts)]
        vol6 = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
        vol = vol6.sum() / 6.0  # mm^3
        c = (vol6[:, None] * tri.sum(1)).sum(0) / (4.0 * vol6.sum())
        m = vol * 1e-3 * rho
        mass[link] += m
        moment[link] += m * c
    return mass, moment / np.maximum(mass, 1e-12)[:, None]


def _plate(com_xy: np.ndarray, foot: np.ndarray, socket_r: float, step: float
           ) -> tuple[np.ndarray, float]:
    """Centre and radius of the smallest disc holding the socket and with every centre of
    mass point, grown by ``step`` (its motion between samples), :data:`MARGIN` of its diameter
    inside the rim (an enclosing-circle search on a grid of centres around the points)."""
    try:  # the farthest point from any centre is a vertex of the points' convex hull
        com_xy = com_xy[ConvexHull(com_xy).vertices]
    except QhullError:  # all on a line (or one point): every point stays
        pass
    pts = np.vstack([com_xy, foot[None]])
    lo, hi = pts.min(0), pts.max(0)
    span = max(float(np.max(hi - lo)), 1.0)
    g = np.linspace(-0.2, 1.2, 29)
    cx, cy = np.meshgrid(lo[0] + g * (hi[0] - lo[0] + 1e-9), lo[1] + g * (hi[1] - lo[1] + 1e-9))
    cand = np.stack([cx.ravel(), cy.ravel()], 1)
    floor = np.maximum(np.linalg.norm(foot - cand, axis=1) + socket_r + 2.0, 0.25 * span)

    def need(idx: np.ndarray, points: np.ndarray) -> np.ndarray:
        # radius needed at centres cand[idx] for points: the farthest point by the largest
        # square (sqrt is monotone), per component (a reduction over pairs is slow)
        d = points[None] - cand[idx, None]
        far = np.sqrt((d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]).max(1))
        return np.maximum((far + step) / (1 - 2 * MARGIN), floor[idx])

    # a quarter of the points bounds every centre's need from below; the exact need only
    # where that bound does not exceed the best of the likeliest centres: the same argmin
    low = need(np.arange(len(cand)), com_xy[::4])
    best = need(np.argsort(low, kind="stable")[:16], com_xy).min()
    todo = np.flatnonzero(low <= best)
    exact = need(todo, com_xy)
    k = int(np.argmin(exact))
    return cand[todo[k]], float(exact[k])


@dataclass(frozen=True)
class _Candidate:
    joint: int
    side: int
    link: int
    top: np.ndarray
    down: np.ndarray


def candidates(asm: Assembly) -> list[_Candidate]:
    """Every (joint, side): the rod leaves past the grounded link's boss along the axis; the
    sculpture then stands with that rod vertical."""
    out = []
    for j in asm.joints:
        for side, sign in ((0, -1.0), (1, 1.0)):
            top = j.at(j.extent[0] if side == 0 else j.extent[1])
            out.append(_Candidate(j.index, side, (j.index + side) % 6, top,
                                  sign * np.asarray(j.w, float)))
    return out


def ground(asm: Assembly, density_g_cm3: float, bed_mm: tuple[float, float, float],
           rod: Rod = profiles.DEFAULT_ROD, clearance_mm: float = 0.3,
           only: tuple[int, int] | None = None, need: np.ndarray | None = None
           ) -> list[Base]:
    """Every :class:`Base` (module docstring) of ``asm`` whose rod clears the moving parts,
    best first (its joints still screws: the caller lays the grounded joint out for the rod);
    ``only``: ``(joint, side)`` to try just that one; ``need`` ``(6, 6)`` the gap the rod keeps
    to each moving link (default the sizing's required gaps). The best stands, rests the
    link the sizing planned the motor torque for, has the smallest plate (the design's z
    nearest up as a tie-break), then the shortest rod."""
    # the required gaps with the sizing's margin: the rod is checked on capsules, like the
    # parts, and should not sit at the limit either
    need = asm.plan.gaps * GAP_MARGIN if need is None else need
    u = loops.cycle_samples(asm.joint_factors, SAMPLES)
    masses, centers = link_masses(asm, density_g_cm3)
    room = plate_room(bed_mm)
    found = []
    r_rod = rod.d_mm / 2
    socket_r, socket_h = r_rod + 2 * asm.printer.wall_mm, SOCKET_D * rod.d_mm
    for c in candidates(asm):
        if only is not None and (c.joint, c.side) != tuple(only):
            continue
        up = -c.down
        frame = standing_frame(up)
        poses = _mm_poses(asm.joint_factors, asm.scale, c.link, u)
        plate_top = _lowest(asm, c.link, u, poses, up) - socket_h - GAP_MM
        height = float(c.top @ up) - plate_top
        socket_top = c.top + (height - socket_h) * c.down
        per_link = _rod_clearance(asm, c.link, c.joint, c.top, socket_top,
                                  r_rod + clearance_mm, u, poses)
        if np.any(per_link < need[c.link]):
            continue
        clear = float(per_link.min())
        foot = frame[:, :2].T @ (c.top + height * c.down)
        step = max(float(np.max(_bounds(asm, c.link, k, centers[k][None, None], u)))
                   for k in range(6) if k != c.link)
        for t in THICKNESS_MM:
            bottom = c.top + (height + t) * c.down
            rod_len = height + t + 10.0
            rod_g = np.pi * r_rod**2 * rod_len * 1e-3 * rod.density_g_cm3
            center, radius = foot, 0.25 * float(np.ptp(centers, axis=0).max())
            for _ in range(4):  # the plate's own mass pulls the centre of mass to its middle
                plate_g = np.pi * radius**2 * t * 1e-3 * density_g_cm3
                mid = frame @ np.r_[center, plate_top - t / 2]
                fixed_c = (rod_g * (c.top + bottom) / 2 + plate_g * mid) / (rod_g + plate_g)
                com = _com(asm, masses, centers, c.link, poses, rod_g + plate_g, fixed_c)
                com2 = com @ frame[:, :2]
                center, radius = _plate(com2, foot, socket_r, step)
            stands = radius <= room
            if stands or t == THICKNESS_MM[-1]:
                break
        if radius > room:  # the bed's plate, moved as little as keeps the socket on it
            radius = room
            off = center - foot
            hold = radius - socket_r - 2.0
            if float(np.linalg.norm(off)) > hold:
                center = foot + off * (hold / float(np.linalg.norm(off)))
        inside = radius - float(np.linalg.norm(com2 - center, axis=1).max()) - step
        stands = bool(stands and inside >= MARGIN * 2 * radius * 0.999)
        tilt = float(np.degrees(np.arccos(np.clip(up[2], -1.0, 1.0))))
        key = (not stands, c.link != asm.plan.rest,
               radius * (1.0 + tilt / 180.0) if stands else -inside, rod_len)
        mount = None if stands else (
            f"the centre of mass comes within {max(inside, 0):.0f} mm of the plate's rim (or "
            "beyond it) in some pose: screw the plate to a board or a table through its four "
            f"{MOUNT_HOLE_MM:g} mm holes (wood screws, 4 mm)")
        found.append((key, Base(c.link, c.joint, c.top, bottom, rod, frame, center,
                                float(radius), t, plate_top - t, com, float(inside), clear,
                                stands, mount, masses)))
    return [b for _, b in sorted(found, key=lambda kb: kb[0])]


def final(asm: Assembly, b: Base, density_g_cm3: float, samples: int = 720) -> Base:
    """``b`` with the centre of mass path, margin and ``stands`` measured again on the built
    assembly (its plate, rod, re-laid grounded joint and every piece of hardware included):
    the figures the report gives and the guide trusts."""
    u = loops.cycle_samples(asm.joint_factors, samples)
    masses, centers = link_masses(asm, density_g_cm3)
    poses = _mm_poses(asm.joint_factors, asm.scale, b.link, u)
    com = _com(asm, masses, centers, b.link, poses, 0.0, np.zeros(3))
    step = max(float(np.max(_bounds(asm, b.link, k, centers[k][None, None], u)))
               for k in range(6) if k != b.link)
    far = float(np.linalg.norm(com @ b.frame[:, :2] - b.center, axis=1).max())
    inside = b.radius - far - step
    stands = bool(inside >= MARGIN * 2 * b.radius * 0.999)
    mount = None if stands else (
        f"the centre of mass comes within {max(inside, 0):.0f} mm of the plate's rim (or "
        "beyond it) in some pose: screw the plate to a board or a table through its four "
        f"{MOUNT_HOLE_MM:g} mm holes (wood screws, 4 mm)")
    return replace(b, com=com, margin_mm=float(inside), stands=stands, mount=mount,
                   masses_g=masses)


def plate_room(bed_mm: tuple[float, float, float]) -> float:
    """Largest plate radius (mm) a bed holds, :data:`bed.EDGE_MM` from its edges."""
    return float(min(bed.room_xy(bed_mm))) / 2


def refit(b: Base, rod: Rod, wall_mm: float, bed_mm: tuple[float, float, float]
          ) -> Base | None:
    """``b`` (measured by :func:`final`) with the plate re-centred and grown for the built
    parts' centre of mass path, where the masses predicted when it was chosen put it short of
    the margin: the smallest disc :func:`_plate` gives; None when the bed cannot hold it."""
    com2 = b.com @ b.frame[:, :2]
    far = float(np.linalg.norm(com2 - b.center, axis=1).max())
    step = b.radius - far - b.margin_mm  # the parts' motion between samples, as measured
    foot = b.frame[:, :2].T @ b.bottom
    center, radius = _plate(com2, foot, rod.d_mm / 2 + 2 * wall_mm, step)
    if radius <= b.radius:  # the path's disc is no larger (the samples' motion was
        # overestimated): the same disc grown until the measured margin is a point over the
        # limit, every point of the path then that much farther from the rim
        aim = MARGIN + 0.01
        center = b.center
        radius = b.radius + max(aim * 2 * b.radius - b.margin_mm, 0.0) / (1 - 2 * aim)
    if radius > plate_room(bed_mm) or radius <= b.radius:
        return None
    return replace(b, center=center, radius=radius)


def plate_part(b: Base, wall_mm: float, segments: int = 96) -> Part:
    """The printed plate: a disc with the rod's socket (a boss along the rod, its bore a press
    fit) and four countersunk holes for fixing it down; it moves with the grounded link."""
    up = b.up
    r_rod = b.rod.d_mm / 2
    socket_r, socket_h = r_rod + 2 * wall_mm, SOCKET_D * b.rod.d_mm
    place = np.column_stack([b.frame, b.frame @ np.r_[b.center, b.table]])  # (3, 4)
    disc = csg.Prism(csg.shift(0.0, 0.0, 0.0), b.thickness, b.radius, b.radius, segments)
    mounts = []
    for a in np.radians([45.0, 135.0, 225.0, 315.0]):
        p = 0.78 * b.radius * np.array([np.cos(a), np.sin(a)])
        foot = b.frame[:, :2].T @ b.bottom - b.center
        if np.linalg.norm(p - foot) < socket_r + MOUNT_HOLE_MM + 3:
            continue
        x, y = float(p[0]), float(p[1])
        mounts += [csg.Prism(csg.shift(x, y, -1.0), b.thickness + 2, MOUNT_HOLE_MM / 2,
                             MOUNT_HOLE_MM / 2, 48),  # the hole and its countersink
                   csg.Prism(csg.shift(x, y, b.thickness - MOUNT_HOLE_MM / 2),
                             MOUNT_HOLE_MM / 2 + 0.01, MOUNT_HOLE_MM / 2, MOUNT_HOLE_MM, 48)]
    top = b.table + b.thickness
    d = (b.bottom - b.top) / np.linalg.norm(b.bottom - b.top)
    at_top = b.top + (float(b.top @ up) - top - socket_h) * d
    socket = csg.Trim(csg.prism(at_top, b.bottom, socket_r, parts.SEGMENTS), tuple(up), b.table)
    tree = csg.Cut(csg.Union((csg.Move(csg.Cut(disc, tuple(mounts)), place), socket)),
                   (csg.prism(at_top - 5 * d, b.bottom + 5 * d, r_rod, parts.SEGMENTS),))
    solid = csg.manifold(tree)
    if parts.pinched(solid) and segments < 102:  # a boolean pinched two vertices onto one
        return plate_part(b, wall_mm, segments + 2)  # point: another tessellation
    parts.check_solid(solid, "base plate")
    mid = b.frame @ np.r_[b.center, b.table + b.thickness / 2]
    caps = np.array([[mid, mid], [at_top, b.bottom]])
    # the disc lies in its ball and in the slab of its thickness (the verification's bound),
    # both a little grown: its vertices stray ~1e-6 mm through the frame's rounding
    slabs = np.array([[*up, b.thickness / 2 + parts.CAPSULE_SLACK_MM], [*up, np.inf]])
    return Part("base_plate", b.link, solid, caps,
                np.array([np.hypot(b.radius, b.thickness / 2) + parts.CAPSULE_SLACK_MM,
                          socket_r + parts.CAPSULE_SLACK_MM]),
                np.array([-1, -1]), -up, "base", tree, slabs)


def rod_hardware(b: Base, cap_end: np.ndarray) -> Hardware:
    """The whole rod, from inside its cap (``cap_end``, mm) to the plate's underside; it
    reaches beyond its joint's zone, so it is tagged as the grounded link's body (-1)."""
    node = csg.prism(cap_end, b.bottom, b.rod.d_mm / 2, parts.SEGMENTS)
    return Hardware(b.rod.name, -1, b.link, csg.manifold(node), np.stack([cap_end, b.bottom]),
                    b.rod.d_mm / 2, node)


def to_dict(b: Base, bed_mm: tuple[float, float, float]) -> dict:
    """The report's ``base`` entry."""
    return {"grounded_link": b.link, "rod_joint": b.joint, "rod": b.rod.name,
            "rod_length_mm": b.rod_length_mm + 10.0, "rod_clearance_mm": b.clearance_mm,
            "tilt_from_design_z_deg": b.tilt_deg, "up_in_home_frame": b.up.tolist(),
            "world_from_home": b.world_from_home().tolist(),
            "plate_diameter_mm": 2 * b.radius, "plate_thickness_mm": b.thickness,
            "com_margin_mm": b.margin_mm, "com_margin_share": b.margin_mm / (2 * b.radius),
            "stands": b.stands, "mount": b.mount,
            "fits_bed": bool(b.radius <= plate_room(bed_mm)),
            "masses_g": b.masses_g.tolist(),
            "method": f"the sculpture stands with its rod vertical; centre of mass of the "
                      f"links, hardware, rod and plate at {SAMPLES} evenly spaced points of "
                      "the cycle, projected on the table; the margin is its least distance "
                      "inside the plate's rim less the farthest a link's centre moves between "
                      "samples (sound bound); the rod's clearance is certified the same way"}
