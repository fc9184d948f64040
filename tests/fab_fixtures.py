"""Shared fabrication fixtures: realized loops and their printed assemblies, built once per
session (cached), at modest fixed sizes so the default tier stays fast; and small independent
measuring helpers (ray casting, segment distances) the fabrication tests use.

* :func:`example_loop`: the carving tests' loop (a random generic cubic, loop 4, thin bars),
  rotated so that its axis A_0 points down;
* :func:`real`: the same cubic's loop realized as ``printed.candidates`` realizes a printed
  loop (joint offsets 7.5 % of the extent, bars half the offset);
* :func:`plan` / :func:`assembly`: that loop sized at :data:`SIZES` with ``kind`` joints
  (``sizing.plan``, ``assembly.assemble``), not grounded;
* :func:`printed`: the whole printable stage on it (``printable.make`` with that one candidate:
  sized, built, grounded on a rod and plate, verified at :data:`SAMPLES` samples).
"""

from __future__ import annotations

import functools

import numpy as np
import trimesh
from conftest import random_rotation_factors

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.fabrication import assembly as assembly_mod
from paraloop_core.fabrication import check, choice, printable, profiles, sizing
from paraloop_core.linkage import loops
from paraloop_core.realization import polyline, realize

#: Size (mm, longest side of the polyline) of the test assemblies per joint kind: level 0 (the
#: aims) holds there (an M4 screw or a 5 mm printed pin needs more room than an M3 screw; the
#: washers and nuts outside the bosses need room past the joints' ends).
SIZE_MM = 220.0
SIZES = {"m3": SIZE_MM, "m4": 260.0, "printed-pin": 260.0}
#: Verification samples of :func:`printed` (the export's default is 720).
SAMPLES = 90
GENERIC = profiles.PRINTERS["generic"]
PLA = profiles.MATERIALS["pla"]


@functools.lru_cache(maxsize=1)
def loop_factors() -> np.ndarray:
    """Joint factors ``(6, 8)`` of loop 4 of a random generic cubic (seed 1)."""
    c = poly.from_factors(random_rotation_factors(np.random.default_rng(1)))
    return loops.loop_joint_factors(factor.all_factorizations_batch(c).factors)[4]


@functools.lru_cache(maxsize=1)
def example_loop() -> tuple[np.ndarray, np.ndarray, float]:
    """A realized loop ``(joint_factors, points, radius)`` with thin bars, rotated so that its
    base link's axis A_0 points down."""
    jf = loop_factors()
    r = realize.realize(jf, d_fraction=0.08, rho_fraction=0.25)
    d = r.points[1] - r.points[2]
    d /= np.linalg.norm(d)
    axis = np.cross(d, [0.0, 0.0, -1.0])
    g = dq.rotation_about_line(axis / np.linalg.norm(axis), np.zeros(3),
                               np.arccos(np.clip(-d[2], -1.0, 1.0)))
    jf2 = dq.mul(dq.mul(g, r.joint_factors), dq.conj(g))
    return jf2, dq.transform_points(g, r.points), r.radius


@functools.lru_cache(maxsize=1)
def real():
    """The loop realized for printing: offset d = 7.5 % of the polyline's extent, bars 0.5 d."""
    jf = loop_factors()
    _, pts6 = polyline.shortest_polyline(jf)
    ext = float(np.max(np.ptp(pts6, axis=0)))
    return realize.realize(jf, d_fraction=0.075 * ext / polyline.polyline_length(pts6),
                           rho_fraction=0.5)


@functools.lru_cache(maxsize=4)
def plan(kind: str = "m3") -> sizing.Plan:
    return sizing.plan(real(), GENERIC, PLA, kind, profiles.DEFAULT_ROD, size_mm=SIZES[kind])


@functools.lru_cache(maxsize=4)
def assembly(kind: str = "m3") -> assembly_mod.Assembly:
    r = real()
    return assembly_mod.assemble(plan(kind), r.points, r.joint_factors, GENERIC, kind)


@functools.lru_cache(maxsize=1)
def printed() -> printable.Printed:
    """The printable stage on :func:`real` at :data:`SIZE_MM`: grounded, verified."""
    cand = choice.Candidate("test loop", 4, lambda: (real(), None))
    return printable.make([cand], printable.Options(size_mm=SIZE_MM, samples=SAMPLES))


_MESHES: dict[int, tuple] = {}


def mesh_of(solid) -> trimesh.Trimesh:
    """:func:`check.part_trimesh` of a manifold ``solid``, cached (the solid kept alive)."""
    if id(solid) not in _MESHES:
        _MESHES[id(solid)] = (solid, check.part_trimesh(solid))
    return _MESHES[id(solid)][1]


def float32_slack(v: np.ndarray) -> float:
    """How far (mm) float32 rounding may move points of the size of ``v``: manifold3d keeps
    its vertices in float32."""
    return 2.0 * float(np.finfo(np.float32).eps) * float(np.abs(v).max())


def point_segment(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance ``(n,)`` of points ``x`` ``(n, 3)`` to the segment ``a b`` (own code)."""
    ab = np.asarray(b, float) - a
    s = np.clip((x - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(x - (a + s[:, None] * ab), axis=1)


def ray_hits(tris: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Sorted distances along ``direction`` (unit) from ``origin`` at which the ray crosses
    triangles ``tris`` ``(f, 3, 3)`` (Moeller-Trumbore, both sides), duplicates on shared
    edges merged."""
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(direction, e2)
    det = np.einsum("nk,nk->n", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tv = origin - v0
    a = np.einsum("nk,nk->n", tv, p) * inv
    q = np.cross(tv, e1)
    b = (q @ direction) * inv
    t = np.einsum("nk,nk->n", e2, q) * inv
    hit = np.sort(t[ok & (a >= 0) & (b >= 0) & (a + b <= 1) & (t > 0)])
    return hit[np.r_[True, np.diff(hit) > 1e-6]] if len(hit) else hit


def relative_poses(jf: np.ndarray, scale: float, about: int, u: np.ndarray) -> np.ndarray:
    """``(T, 6, 4, 4)``: every link's pose in link ``about``'s home frame, lengths times
    ``scale`` (straight from ``loops.link_poses``)."""
    m = dq.to_matrix(loops.link_poses(np.asarray(jf, float), poly.param_to_t(u)))
    m[..., :3, 3] *= scale
    return np.linalg.inv(m[:, about, None]) @ m
