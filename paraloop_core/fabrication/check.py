"""Verification of the built parts over the whole cycle (after every export).

Each link's group is everything rigid with it: its printed parts, the printed pieces and metal
hardware on the axes of joints whose lower link it is (a solid of revolution about a joint axis
is the same in both links' frames), the base and the rod with the grounded link. Every part
must be a valid, watertight solid in one piece. For every pair of groups and each of
``samples`` evenly spaced parameters (plus samples uniform in each norm factor's angle, so a
fast turn gets its share) the moving group is placed by the relative link pose (mm) and

* a broad phase bounds the gap from below by the groups' capsules (each part lies in its
  capsules); only where that bound is below the required gap does manifold3d compute the
  exact gap (``min_gap``) and, on contact, the intersection volume;
* two links of one joint: the joint zone ``W`` (a cylinder about the axis over every piece of
  the joint) is taken out of both; inside it each link lies in a solid of revolution about the
  shared axis on its own side of the split (:mod:`parts`), and the relative motion is a
  rotation about that axis, so their gap there is the same at every angle: measured once
  (``joint_zone_gap_mm``, less the polygon error);
* continuity: the gap anywhere between samples is at least the gap at the nearest sample minus
  a sound bound of the motion between them (:func:`motion_bound.sound_displacement_bounds`);
  cells where that bound eats the gap are refined. ``continuous_min_gap_mm > 0`` for every
  pair proves the parts collision-free over the continuous cycle, and ``gap_ok`` that every
  pair of links without a common joint keeps its required gap (:mod:`stiffness`).
"""

from __future__ import annotations

import functools
import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass

import manifold3d as m3d
import numpy as np

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import keel, parts
from paraloop_core.fabrication.assembly import Assembly
from paraloop_core.fabrication.parts import part_trimesh
from paraloop_core.fabrication.progress import Progress
from paraloop_core.linkage import loops
from paraloop_core.realization.clearance import segment_distance
from paraloop_core.realization.motion_bound import sound_displacement_bounds, try_motion_bound

#: Exact (manifold3d) gap checks one pair may spend refining between samples, and the rounds
#: of refinement.
MAX_EXACT_CHECKS = 3000
REFINE_ROUNDS = 8
#: How far (mm) the gap between the two links of one joint is measured (about the joint).
ZONE_SEARCH = 2.0


@dataclass(frozen=True)
class _Piece:
    """One solid of a link's group with its capsules ``(n, 2, 3)``, radii, joint tags and
    slabs ``(n, 4)`` (:class:`parts.Part`; inf: none)."""

    solid: m3d.Manifold
    caps: np.ndarray
    radii: np.ndarray
    tags: np.ndarray
    slabs: np.ndarray


def _no_slabs(n: int) -> np.ndarray:
    return np.tile([0.0, 0.0, 1.0, np.inf], (n, 1))


def _group(asm: Assembly, link: int) -> list[_Piece]:
    """Link ``link``'s rigid group (module docstring), piece by piece."""
    out = [_Piece(p.manifold, p.capsules, p.radii, p.joint,
                  _no_slabs(len(p.radii)) if p.slabs is None else p.slabs)
           for p in asm.parts if p.link == link]
    return out + [_Piece(h.solid, h.capsule[None], np.array([h.radius]), np.array([h.joint]),
                         _no_slabs(1)) for h in asm.hardware if h.link == link]


def _outside(asm: Assembly, joint: int, pieces: list[_Piece], w: m3d.Manifold
             ) -> list[_Piece]:
    """``pieces`` without joint ``joint``'s zone ``w``: solids cut, the zone's capsules
    dropped and the body capsules that enter it trimmed (:func:`trimmed`); pieces left with
    no capsule lie in the zone and are dropped."""
    out = []
    for q in pieces:
        keep = q.tags != joint
        if keep.any():
            caps = trimmed(asm, joint, q.caps, q.radii, q.tags)[keep]
            out.append(_Piece(q.solid - w, caps, q.radii[keep], q.tags[keep], q.slabs[keep]))
    return out


def trimmed(asm: Assembly, j: int, caps: np.ndarray, radii: np.ndarray, tags: np.ndarray
            ) -> np.ndarray:
    """``caps`` with each body capsule (tag -1) that ends on joint ``j``'s axis shortened by
    the length whose material lies inside :func:`zone` (removed there): its end moves along
    the capsule by ``t`` while the section of radius ``r`` at ``t`` stays within the zone's
    radius (``t sin(angle) + r``) and axial range (``t |cos(angle)| + r``)."""
    jt = asm.joints[j]
    lo, hi = jt.extent
    wr = jt.reach + parts.EPS_MM / 2
    out = caps.copy()
    for n in np.flatnonzero(tags == -1):
        for end in (0, 1):
            p, q = caps[n, end], caps[n, 1 - end]
            rel = p - jt.origin
            s = float(rel @ jt.w)
            if np.linalg.norm(rel - s * jt.w) > 1e-6 or not lo <= s <= hi:
                continue
            seg = q - p
            length = float(np.linalg.norm(seg))
            if length == 0:
                continue
            cos = float(seg @ jt.w) / length
            sin = np.sqrt(max(1.0 - cos * cos, 0.0))
            room = (hi - s) if cos > 0 else (s - lo)
            t = min((wr - radii[n]) / max(sin, 1e-12),
                    (room - radii[n]) / max(abs(cos), 1e-12), 0.5 * length)
            if t > 0:
                out[n, end] = p + seg * (t / length)
    return out


def zone(asm: Assembly, j: int, grow: float = 0.0) -> m3d.Manifold:
    """Joint ``j``'s zone ``W``: a cylinder of the joint's reach plus half a margin over every
    piece (the rod only as far as the joint's pieces reach)."""
    jt = asm.joints[j]
    lo, hi = jt.extent
    e = parts.EPS_MM / 2 + grow
    return parts.cylinder(jt.at(lo - e), jt.at(hi + e), jt.reach + e)


def zone_hulls(asm: Assembly, j: int) -> tuple[np.ndarray, float]:
    """Axes ``(2, 2, 3)`` and radius of the solids of revolution (cylinders) holding each
    side's material inside :func:`zone` (link j's: up to the split; link j+1's: from it)."""
    jt = asm.joints[j]
    lo, hi = jt.extent
    e = parts.EPS_MM / 2
    return (np.array([[jt.at(lo - e), jt.at(jt.split - jt.gap / 2)],
                      [jt.at(jt.split + jt.gap / 2), jt.at(hi + e)]]), jt.reach + e)


def _zone_gap(axis: np.ndarray, radius: float, out: list[_Piece],
              whole: Callable[[], m3d.Manifold]) -> float:
    """Exact gap (capped at :data:`ZONE_SEARCH`) between one side's hull (a cylinder about
    ``axis`` ``(2, 3)``) and the other side's material outside the zone (``whole()``: its
    group united, less the zone). Cheap first: the pieces ``out`` (that material, piece by
    piece, each already less the zone) whose capsules keep farther than the cap from the
    hull's cannot come within it; where the others alone come nowhere near, nothing does."""
    hull = (axis[None], np.array([radius]))
    near = [q.solid for q in out
            if _capsule_gap(hull, (q.caps, q.radii), np.eye(4)[None])[0] <= ZONE_SEARCH + 1e-6]
    if not near:  # the capsules contain the pieces: nothing within reach
        return ZONE_SEARCH
    solid = parts.cylinder(axis[0], axis[1], radius)
    if solid.min_gap(m3d.Manifold.batch_boolean(near, m3d.OpType.Add),
                     ZONE_SEARCH) >= ZONE_SEARCH:
        return ZONE_SEARCH
    return solid.min_gap(whole(), ZONE_SEARCH)  # measured on the whole, as the report says


def _mm_poses(asm: Assembly, u: np.ndarray) -> np.ndarray:
    mats = dq.to_matrix(loops.link_poses(asm.joint_factors, poly.param_to_t(u)))
    mats[..., :3, 3] *= asm.scale
    return mats


def _capsule_gap(ca: tuple, cb: tuple, rel: np.ndarray) -> np.ndarray:
    """Lower bound ``(T,)`` of the gap between capsule sets ``(segments, radii)``, b moved."""
    seg_b = np.einsum("tij,nkj->tnki", rel[:, :3, :3], cb[0]) + rel[:, None, None, :3, 3]
    d = segment_distance(ca[0][None, :, None, 0], ca[0][None, :, None, 1],
                         seg_b[:, None, :, 0], seg_b[:, None, :, 1])
    return (d - ca[1][None, :, None] - cb[1][None, None, :]).min(axis=(1, 2))


def _piece_bounds(pa: list[_Piece], pb: list[_Piece], rel: np.ndarray) -> np.ndarray:
    """:func:`_capsule_gap` of every pair of pieces of ``pa`` and ``pb`` (b moved by ``rel``
    ``(T, 4, 4)``), raised by their slabs: ``(A, B, T)``, all capsules in one pass."""
    ca, cb = (np.concatenate([q.caps for q in pieces]) for pieces in (pa, pb))
    ra, rb = (np.concatenate([q.radii for q in pieces]) for pieces in (pa, pb))
    seg_b = np.einsum("tij,nkj->tnki", rel[:, :3, :3], cb) + rel[:, None, None, :3, 3]
    d = segment_distance(ca[None, :, None, 0], ca[None, :, None, 1],
                         seg_b[:, None, :, 0], seg_b[:, None, :, 1])
    d -= ra[None, :, None]
    d -= rb[None, None, :]
    # a capsule with a slab: its material is also that far from the other's segments
    sa, sb = (np.concatenate([q.slabs for q in pieces]) for pieces in (pa, pb))
    for i in np.flatnonzero(np.isfinite(sa[:, 3])):
        s = seg_b @ sa[i, :3] - ca[i].mean(0) @ sa[i, :3]  # (T, B, 2)
        d[:, i, :] = np.maximum(d[:, i, :], _slab_gap(s, sa[i, 3]) - rb[None, :])
    for k in np.flatnonzero(np.isfinite(sb[:, 3])):
        n_t = rel[:, :3, :3] @ sb[k, :3]  # (T, 3): the normal, and the plane's offset, in a's
        off = np.einsum("ti,ti->t", rel[:, :3, :3] @ cb[k].mean(0) + rel[:, :3, 3], n_t)
        s = np.einsum("nkj,tj->tnk", ca, n_t) - off[:, None, None]  # (T, A, 2)
        d[:, :, k] = np.maximum(d[:, :, k], _slab_gap(s, sb[k, 3]) - ra[None, :])
    starts = [np.cumsum([0] + [len(q.caps) for q in pieces])[:-1] for pieces in (pa, pb)]
    d = np.minimum.reduceat(np.minimum.reduceat(d, starts[0], axis=1), starts[1], axis=2)
    return d.transpose(1, 2, 0)


def _slab_gap(s: np.ndarray, half: float) -> np.ndarray:
    """Distance ``(...)`` from the slab ``|x . n| <= half`` to segments whose ends have heights
    ``s`` ``(..., 2)`` over its mid-plane (the heights along a segment are linear)."""
    lo, hi = s.min(-1), s.max(-1)
    return np.maximum(np.maximum(lo - half, -half - hi), 0.0)


def _affine(m: np.ndarray) -> list:
    return [list(map(float, row)) for row in m[:3, :4]]


def _gaps(asm: Assembly, a: int, b: int, pa: list[_Piece], pb: list[_Piece],
          u: np.ndarray, below: float, stop: float | None = None
          ) -> tuple[np.ndarray, np.ndarray, int]:
    """Gap (the capsule bound where that reaches ``below``, else exact), intersection volume
    ``(T,)`` and the number of exact checks, of pieces ``pa`` (link a) and ``pb`` (link b,
    moved) at ``u``. Exact gaps only between the pieces whose own capsules come within
    ``below`` (a group's plate or hardware is not measured where only a bar comes close).
    With ``stop``, the closest bounds first and none after the first exact gap short of
    ``stop`` (none, or less than it): the pair fails (the others keep their bound)."""
    poses = _mm_poses(asm, u)
    rel = np.linalg.inv(poses[:, a]) @ poses[:, b]
    lbs = _piece_bounds(pa, pb, rel)  # (A, B, T)
    lb = lbs.min(axis=(0, 1))
    gap, vol = lb.copy(), np.zeros(len(u))
    near, n = np.nonzero(lb < below)[0], 0
    for s in near[np.argsort(lb[near], kind="stable")]:
        n += 1
        m = _affine(rel[s])
        vals = lbs[:, :, s].copy()
        for i, k in zip(*np.nonzero(vals < below), strict=True):
            # exact up to 2 mm past the threshold: a capped value must not fake a small gap
            moved = pb[k].solid.transform(m)
            vals[i, k] = max(vals[i, k], pa[i].solid.min_gap(moved, below + 2.0))
            if vals[i, k] <= 0.0:
                vol[s] = max(vol[s], (pa[i].solid ^ moved).volume())
        gap[s] = vals.min()
        if stop is not None and (gap[s] <= 0.0 or gap[s] < stop - 1e-9):
            break
    return gap, vol, n


def _subsamples(u: np.ndarray, idx: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """``counts[i]`` (at most 64) new parameters spread over the cell of sample ``u[idx[i]]``."""
    nxt = np.append(u[1:], u[0] + 1.0)
    prv = np.insert(u[:-1], 0, u[-1] - 1.0)
    n = np.clip(counts, 1, 64).astype(int)
    cell = np.repeat(np.asarray(idx), n)
    k = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    lo, hi = (u[cell] + prv[cell]) / 2, (u[cell] + nxt[cell]) / 2
    return np.unique((lo + (hi - lo) * (k + 0.5) / np.repeat(n, n)) % 1.0)


class _Steps:
    """How far (mm) group b's points (within its capsules ``caps``, ``radii``) move relative
    to group a about each sample: the joint angles' bound, cheap and finite everywhere; after
    :meth:`tighten`, the smaller of it and the speed bound (costly where the motion passes
    near a singular pose, so computed only where the first leaves a sample unproven). Both
    are sound (:func:`motion_bound.sound_displacement_bounds`)."""

    def __init__(self, asm: Assembly, a: int, b: int, caps: np.ndarray, radii: np.ndarray):
        ends = caps.reshape(-1, 3) / asm.scale
        self.center = 0.5 * (ends.min(0) + ends.max(0))
        self.reach = float(np.max(np.linalg.norm(ends - self.center, axis=1))) + \
            radii.max() / asm.scale
        self.asm, self.a, self.b = asm, a, b
        self.bound, self.tight = None, False

    def __call__(self, u: np.ndarray) -> np.ndarray:
        jf = self.asm.joint_factors
        return self.asm.scale * sound_displacement_bounds(jf, self.a, self.b, self.center,
                                                          self.reach, u, self.bound)

    def tighten(self) -> bool:
        """Take the speed bound in too; True the first time (the bounds then change)."""
        if self.tight:
            return False
        self.tight = True
        self.bound = try_motion_bound(self.asm.joint_factors, self.a, self.b, self.center)
        return True


def _unproven(gap: np.ndarray, delta: np.ndarray, required: float) -> np.ndarray:
    """Indices of the samples whose gap keeps the required one there but not, less the
    motion bound ``delta``, over their whole cell."""
    return np.nonzero((gap - delta <= required) & (gap > required))[0]


def _printed(asm: Assembly, link: int) -> m3d.Manifold:
    """Link ``link``'s printed parts (not the hardware: a thrust washer touches both links by
    design), for the clearance between two printed links of one joint."""
    return m3d.Manifold.batch_boolean([p.manifold for p in asm.parts if p.link == link],
                                      m3d.OpType.Add)


def solid_info(asm: Assembly) -> list[dict]:
    """Per printed part: watertight, pieces, manifold status, volume, triangles."""
    out = []
    for p in asm.parts:
        tm = part_trimesh(p.manifold)
        out.append({"name": p.name, "watertight": bool(tm.is_watertight),
                     "pieces": len(p.manifold.decompose()),
                     "manifold_status": str(p.manifold.status()),
                     "volume_mm3": float(p.manifold.volume()),
                     "triangles": int(p.manifold.num_tri())})
    return out


def verify(asm: Assembly, samples: int = 720, progress: Progress | None = None,
           keels: list[float] | None = None) -> dict:
    """The verification report (module docstring), JSON-ready. ``keels`` (each link's keel,
    mm): only the keels to take off (:func:`keel.in_the_way`) are wanted where one is (the
    parts are then built again and verified anew): the pairs of a keeled link first, each
    left as soon as it fails; once one has, the pairs whose failure would take off no other
    keel (:func:`keel.deeper`: already taken off, or none) are left out and the report says
    ``partial``."""
    if samples < 8:
        raise FabricationError("verification needs at least 8 samples", "bad-parameters")
    t0 = time.perf_counter()
    info = solid_info(asm)
    groups = [_group(asm, i) for i in range(6)]

    @functools.cache
    def united(link: int) -> m3d.Manifold:  # a link's group as one solid, built once
        return m3d.Manifold.batch_boolean([q.solid for q in groups[link]], m3d.OpType.Add)

    jf = asm.joint_factors
    u0 = loops.cycle_samples(jf, samples)
    need = asm.plan.gaps
    pairs_out, joint_gaps, off = [], [], set()
    links = list(itertools.combinations(range(6), 2))
    if keels is not None:  # the keeled pairs first (stable: each kind in order)
        links.sort(key=lambda ab: not (keels[ab[0]] or keels[ab[1]]))
    for k, (a, b) in enumerate(links):
        keeled = keels is not None and bool(keels[a] or keels[b])
        if off and (not keeled or keel.deeper(keels, [a, b]) in off):
            continue
        if progress is not None:
            progress(k / 15, f"verifying links {a} and {b}")
        joint = a if b == a + 1 else (5 if (a, b) == (0, 5) else None)
        pa, pb = groups[a], groups[b]
        const = np.inf
        required = 0.0 if joint is not None else float(need[a, b])
        if joint is not None:
            w = zone(asm, joint)
            pa, pb = _outside(asm, joint, pa, w), _outside(asm, joint, pb, w)
            axes, radius = zone_hulls(asm, joint)
            (lo, lo_out), (up, up_out) = ((a, pa), (b, pb)) if joint == a else ((b, pb), (a, pa))
            jt = asm.joints[joint]
            poly_err = (jt.reach + parts.EPS_MM) * (1.0 - np.cos(np.pi / parts.SEGMENTS))
            raw = min(_zone_gap(axes[0], radius, up_out, lambda up=up, w=w: united(up) - w),
                      _zone_gap(axes[1], radius, lo_out, lambda lo=lo, w=w: united(lo) - w))
            const = raw - poly_err if raw < ZONE_SEARCH else np.inf
            joint_gaps.append(_printed(asm, a).min_gap(_printed(asm, b), ZONE_SEARCH))
        # exact gaps only where the capsules do not prove the required gap by themselves
        search = required + 0.05
        cb = np.concatenate([q.caps for q in pb])
        rb = np.concatenate([q.radii for q in pb])
        stop = required if keeled else None  # a keel's pair: only whether it fails
        gap, vol, n_exact = _gaps(asm, a, b, pa, pb, u0, search, stop)
        u, steps = u0, _Steps(asm, a, b, cb, rb)
        for _ in range(REFINE_ROUNDS):  # refine cells whose motion bound eats their margin
            # a sample (exact there) at no gap or closer than the required one fails the pair
            # whatever the cells between do (continuous <= gap - delta <= gap): refine only
            # to prove the parts apart (cells short of the required gap spent every exact
            # check on a verdict already taken), and a keel's pair not at all (it comes off)
            short = gap.min() <= 0.0 or gap.min() < required - 1e-9
            target = 0.0 if short else required
            delta = steps(u)
            if short and keeled:
                break
            bad = _unproven(gap, delta, target)
            if len(bad) and steps.tighten():  # the speed bound first, then finer samples
                delta = steps(u)
                bad = _unproven(gap, delta, target)
            if not len(bad) or np.any(vol > 1e-9):
                break
            new = _subsamples(u, bad, np.ceil(2 * delta[bad] / (gap[bad] - target)))
            if n_exact + len(new) > MAX_EXACT_CHECKS:
                break
            g_new, v_new, n_new = _gaps(asm, a, b, pa, pb, new, search, stop)
            n_exact += n_new
            order = np.argsort(np.concatenate([u, new]))
            u = np.concatenate([u, new])[order]
            gap, vol = np.concatenate([gap, g_new])[order], np.concatenate([vol, v_new])[order]
        else:
            delta = steps(u)
        i_min = int(np.argmin(gap))
        pairs_out.append({
            "links": [a, b], "adjacent": joint is not None,
            "min_gap_mm": float(min(gap[i_min], const)), "at_u": float(u[i_min]),
            "continuous_min_gap_mm": float(min(np.min(gap - delta), const)),
            "required_gap_mm": required,
            "joint_zone_gap_mm": float(min(const, ZONE_SEARCH)) if joint is not None else None,
            "max_step_motion_mm": float(delta.max()), "samples": int(len(u)),
            "exact_checks": n_exact, "colliding_samples": int(np.sum(vol > 1e-9)),
            "max_intersection_mm3": float(vol.max())})
        if keeled and keel.fails(pairs_out[-1]):
            off.add(keel.deeper(keels, [a, b]))
    pairs_out.sort(key=lambda p: p["links"])
    sound = all(p["watertight"] and p["manifold_status"] == "Error.NoError"
                and p["pieces"] == 1 for p in info)
    collisions = sum(p["colliding_samples"] for p in pairs_out)
    cont = min(p["continuous_min_gap_mm"] for p in pairs_out)
    gap_ok = all(p["continuous_min_gap_mm"] >= p["required_gap_mm"] - 1e-9
                 for p in pairs_out if not p["adjacent"])
    if progress is not None:
        progress(1.0, "verification done")
    return {
        "ok": bool(sound and collisions == 0 and cont > 0),
        "gap_ok": bool(gap_ok), "watertight": sound, "samples": samples,
        "min_gap_mm": min(p["min_gap_mm"] for p in pairs_out),
        "continuous_min_gap_mm": cont,
        "min_non_adjacent_gap_mm": min((p["continuous_min_gap_mm"] for p in pairs_out
                                        if not p["adjacent"]), default=np.inf),  # (partial)
        "joint_clearance_mm": float(min(joint_gaps, default=np.inf)),
        "collisions": int(collisions),
        "method": "gaps at evenly spaced u (and uniform in each norm factor's angle) by "
                  "capsule bounds, exact manifold3d min_gap where those come within the "
                  "required gap; continuous bound = gap - sound motion bound between samples; "
                  "two links of one joint without its zone, whose contents are solids of "
                  "revolution about the axis",
        "parts": info, "pairs": pairs_out, "seconds": time.perf_counter() - t0,
        **({"partial": True} if off else {})}
