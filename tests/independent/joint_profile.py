"""Profiles of a part around a joint axis, measured on its mesh (independent of paraloop_core).

At axial stations ``s`` (every :data:`STEP_MM`) the mesh is cut by the plane through
``origin + s axis`` perpendicular to the axis and :data:`N_ANGLES` rays are cast in that plane
from the axis outward. Along each ray the first material interval ``[r_in, r_out]`` is the bore
(r_in, 0 when the axis point is inside the material, inf when the ray meets nothing) and the
wall around it (r_out - r_in).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .meshgeom import Sections, first_run

#: Station spacing along the axis (mm); lengths measured by counting stations are lower
#: bounds: a run of n stations spans at least (n - 1) STEP_MM.
STEP_MM = 0.1
#: Rays per station (every 1.5 deg: 0.08 mm apart at 3 mm radius).
N_ANGLES = 240
#: Material may reach this far inside an axle's or a hardware piece's radius (the facets of a
#: bore polygon whose corners are on the circle: 0.006 mm for a 32-gon of 3 mm).
FIT_TOL_MM = 0.05
#: Rays look this far from the axis (a wall reaching farther reads as infinitely thick).
REACH_MM = 40.0
#: A bore holds an axle when it is at most this much wider than the axle (radius).
HOLD_SLACK_MM = 0.5


@dataclass
class Profile:
    """``s`` (S,), ``inside`` (S,) axis point in the material, ``rin`` and ``rout`` (S, K)."""

    s: np.ndarray
    inside: np.ndarray
    rin: np.ndarray
    rout: np.ndarray

    def near(self, s: float) -> int:
        """Index of the station nearest to ``s``."""
        return int(np.argmin(np.abs(self.s - s)))


def profile(mesh, origin: np.ndarray, axis: np.ndarray, lo: float, hi: float) -> Profile:
    """Profile of ``mesh`` (home frame, mm) around the line ``origin + s axis`` for
    ``s`` in [lo, hi] (mm)."""
    # off the round levels of the design's faces (a plane on a face meets its float32 noise)
    s = (np.arange(np.floor(lo / STEP_MM), np.ceil(hi / STEP_MM) + 1) + 0.371) * STEP_MM
    sec = Sections(mesh.vertices, mesh.faces, origin, axis, s)
    ang = np.arange(N_ANGLES) * (2 * np.pi / N_ANGLES)
    rin = np.full((len(s), N_ANGLES), np.inf)
    rout = np.full((len(s), N_ANGLES), np.inf)
    inside = np.zeros(len(s), bool)
    for k in range(len(s)):
        ins, rin[k], rout[k] = first_run(sec.segments[k], np.zeros(2), ang, REACH_MM)
        inside[k] = ins[0]
    return Profile(s, inside, rin, rout)


def runs_of(mask: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges ``[i, j]`` (inclusive) of the True runs of a 1D mask."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.flatnonzero(np.diff(m.astype(int)))
    return [(int(a), int(b) - 1) for a, b in zip(d[::2], d[1::2], strict=True)]


def run_length(mask: np.ndarray) -> float:
    """Lower bound (mm) of the length covered by the True stations: (n - 1) steps a run."""
    return float(sum((j - i) * STEP_MM for i, j in runs_of(mask)))


def held(p: Profile, axle_r: float) -> np.ndarray:
    """Stations (S,) where the material surrounds the axle at every angle, no wider than
    ``axle_r + HOLD_SLACK_MM`` and not inside ``axle_r - FIT_TOL_MM``."""
    return np.all((p.rin >= axle_r - FIT_TOL_MM) & (p.rin <= axle_r + HOLD_SLACK_MM), axis=1)


def surrounded(p: Profile) -> np.ndarray:
    """Stations (S,) where every ray from the axis meets material (and the axis is free)."""
    return np.all(np.isfinite(p.rin), axis=1) & ~p.inside


def thinnest_wall(p: Profile, mask: np.ndarray, edge_mm: float = 0.3
                  ) -> tuple[float, float | None, float | None]:
    """Least ``rout - rin`` over the ``mask`` stations, leaving out ``edge_mm`` at both ends of
    each run (the faces' chamfers), with its station (mm) and ray angle (deg); inf, None, None
    when nothing is left."""
    keep = np.zeros(len(p.s), bool)
    cut = int(round(edge_mm / STEP_MM))
    for i, j in runs_of(mask):
        keep[i + cut: j - cut + 1] = True
    if not keep.any():
        return float("inf"), None, None
    with np.errstate(invalid="ignore"):
        w = np.where(keep[:, None], p.rout - p.rin, np.inf)
    k, a = np.unravel_index(np.argmin(w), w.shape)
    return float(w[k, a]), float(p.s[k]), float(a * 360.0 / w.shape[1])


def floor(p: Profile, mask: np.ndarray) -> float | None:
    """Thinnest floor (mm, lower bound) under a blind bore among the ``mask`` stations: a run
    of stations with the axis in the material next to a station whose bore is open; None
    when there is none (through bores)."""
    open_bore = surrounded(p)
    runs = [(i, j) for i, j in runs_of(p.inside & mask)
            if (i > 0 and open_bore[i - 1]) or (j + 1 < len(p.s) and open_bore[j + 1])]
    return min(((j - i) * STEP_MM for i, j in runs), default=None)


def intrusion(p: Profile, lo: float, hi: float, free_r: float) -> float:
    """Length (mm) of the stations strictly inside [lo, hi] (0.1 mm in from each end) where
    the material comes inside ``free_r - FIT_TOL_MM`` of the axis: a piece there would not fit."""
    sel = (p.s > lo + 0.1) & (p.s < hi - 0.1)
    bad = sel & np.any(p.rin < free_r - FIT_TOL_MM, axis=1)
    return float(np.count_nonzero(bad) * STEP_MM)


def hex_fit(p: Profile, lo: float, hi: float, across_flats: float) -> tuple[float, float]:
    """How a hexagon of ``across_flats`` sits in the stations inside [lo, hi]: the least
    clearance ``min(r_in - hexagon)`` (mm) over the best of 240 turns of the hexagon, and the
    share of those stations where the material comes inside the hexagon's corner circle
    (the nut cannot turn there)."""
    sel = (p.s > lo + 0.1) & (p.s < hi - 0.1)
    if not sel.any():
        return float("-inf"), 0.0
    rin = p.rin[sel]
    ang = np.arange(p.rin.shape[1]) * (2 * np.pi / p.rin.shape[1])
    a = across_flats / 2
    phis = np.arange(240) * (np.pi / 3 / 240)
    rel = (ang[None, :] - phis[:, None]) % (np.pi / 3) - np.pi / 6
    hexr = a / np.cos(rel)  # (phi, K) hexagon boundary radius
    clear = np.min(rin[None, :, :] - hexr[:, None, :], axis=(1, 2))
    corner = a / np.cos(np.pi / 6)
    turn_blocked = np.mean(np.min(rin, axis=1) < corner - FIT_TOL_MM)
    return float(np.max(clear)), float(turn_blocked)


def bearing_face(p: Profile, radius: float, start: float, direction: int) -> float | None:
    """Axial position (mm) of the first face met going from ``start`` in ``direction`` (+1 or
    -1) where the material closes inside ``radius`` at every angle (a head or nut bears on
    it); the station reached, so the true face is at most one step before it. None if none."""
    order = np.argsort(direction * p.s)
    for k in order:
        if direction * (p.s[k] - start) < 0:
            continue
        if np.all(p.rin[k] < radius) and not p.inside[k]:
            return float(p.s[k])
    return None
