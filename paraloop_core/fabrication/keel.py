"""Where along its bar a lifted link's keel may run: clear of the links on its two joints.

A link cut below its bar's face (a bore needs the room, :func:`flat.lift`) lies on a keel:
its bar swept down past the cut (:func:`parts.keeled`), so far that the cut meets its full
width (the hexagon's corners, two corner radii apart): the link stands on a strip as wide as
its bar. Every point of the keel below the bar's axis lies within the bar's corner radius of
the axis' plane through ``down`` and no deeper than the cut: a box section whose capsule
(:func:`capsule_radius`) bounds it for the verification. Near a joint the keel reaches along
the joint's axis towards the next link, whose bar turns about that axis: in the link's own
frame that bar sweeps the surface of revolution of its segment, so the distance from a point
to everything it ever occupies is a distance in the plane through the axis and the point
(the meridian: ``(distance from the axis, height along it)``), whatever the joint's range.
:func:`span` keeps the keel where its box section (its bottom and sides) stays
:data:`CLEAR_MM` outside that surface for both neighbours: the longest such stretch,
if it is at least :data:`MIN_SHARE` of the bar. This is a prediction only (it ignores the
other four links, and a neighbour's boss, which the joint zone clears): the verification of
the built parts decides, and a keel it fails is narrowed, then taken off
(:func:`in_the_way`, :func:`printable.make`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.fabrication.voxelspace import point_segment_distance

#: How far (mm) a keel's widest section reaches past its print flat (the cut trims it there).
PAST_MM = 0.5
#: Keel levels of a link (:func:`parts.keeled`): as wide as the bar at the cut (two corner
#: radii), narrow (the hexagon's face, one corner radius: the copy's corners stop above the
#: cut), none; a keel the verification fails goes one level down.
WIDE, NARROW, NONE = 2, 1, 0
#: Slope (degrees from the bed) of a shortened keel's ends: steeper than the 45 deg a printer
#: bridges without support.
END_SLOPE_DEG = 55.0
#: Least distance (mm) the keel's deepest section keeps from a neighbour's swept bar.
CLEAR_MM = 1.5
#: Shortest keel, as a share of its bar: a shorter one leaves most of the bar over support.
MIN_SHARE = 0.4
#: Stations along the bar at which the keel's section is tested, and the largest spacing
#: (mm) of the points tested around that section.
STATIONS = 241
SPACING_MM = 0.5


@dataclass(frozen=True)
class Neighbour:
    """The link on one joint of a keeled link: the joint's axis (``origin``, unit ``w``; mm,
    home frame), that link's bar ``(2, 3)`` (mm, home pose) and its corner ``radius``."""

    origin: np.ndarray
    w: np.ndarray
    bar: np.ndarray
    radius: float


def _meridian(x: np.ndarray, origin: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``(..., 2)``: distance of points ``x`` ``(..., 3)`` from the axis, height along it."""
    d = np.asarray(x, float) - origin
    h = d @ w
    return np.stack([np.linalg.norm(d - h[..., None] * w, axis=-1), h], axis=-1)


def capsule_radius(radius: float, bottom: float) -> float:
    """Radius (mm) of the capsule about the bar's axis moved ``bottom / 2`` down that holds
    a keel section ``2 radius`` wide reaching ``bottom`` mm below the axis (its corners lie
    on it: :func:`parts.keeled` adds the capsules' rounding slack)."""
    return float(np.hypot(radius, bottom / 2))


def span(bar: np.ndarray, radius: float, down: np.ndarray, bottom: float,
         neighbours: tuple[Neighbour, ...]) -> tuple[float, float] | None:
    """``(x0, x1)`` (mm from ``bar[0]`` along the bar ``(2, 3)``) where the keel of a hexagonal
    bar of corner ``radius``, a box section ``2 radius`` wide reaching ``bottom`` mm below the
    axis along ``down`` (a face normal, perpendicular to the bar), keeps clear of
    ``neighbours`` (module docstring); None where no stretch of :data:`MIN_SHARE` of the bar
    does."""
    p0, p1 = (np.asarray(p, float) for p in bar)
    length = float(np.linalg.norm(p1 - p0))
    u = (p1 - p0) / length
    d = np.asarray(down, float)
    side = np.cross(u, d)
    # the box's outline below the axis (its bottom and sides) every SPACING_MM at most: a
    # bar passing between two samples comes at most half that nearer than they say
    n_across = int(np.ceil(2 * radius / SPACING_MM)) + 1
    n_down = int(np.ceil(bottom / SPACING_MM)) + 1
    across = np.r_[np.linspace(-radius, radius, n_across), np.full(2 * n_down, radius)
                   * np.repeat([-1.0, 1.0], n_down)]
    depth = np.r_[np.full(n_across, bottom), np.tile(np.linspace(0.0, bottom, n_down), 2)]
    section = across[:, None] * side + depth[:, None] * d  # (P, 3)
    xs = np.linspace(0.0, length, STATIONS)
    deepest = p0 + xs[:, None, None] * u + section  # (X, P, 3)
    clear = np.ones(STATIONS, bool)
    for n in neighbours:
        w = np.asarray(n.w, float) / np.linalg.norm(n.w)
        a, b = _meridian(np.asarray(n.bar, float), n.origin, w)
        # (the distance in the meridian plane: the same formula in two dimensions)
        gap = point_segment_distance(_meridian(deepest, n.origin, w), a, b).min(axis=1) \
            - n.radius
        clear &= gap >= CLEAR_MM
    # the longest run of clear stations
    edges = np.flatnonzero(np.diff(np.r_[0, clear.astype(np.int8), 0]))
    if not len(edges):
        return None
    starts, stops = edges[::2], edges[1::2] - 1
    k = int(np.argmax(stops - starts))
    x0, x1 = float(xs[starts[k]]), float(xs[stops[k]])
    return (x0, x1) if x1 - x0 >= MIN_SHARE * length else None


def fails(pair: dict) -> bool:
    """Whether a pair of the verification (:func:`check.verify`) fails: a collision, no
    positive gap, or less than the sizing's gap between links without a joint."""
    cont = pair["continuous_min_gap_mm"]
    return bool(pair["colliding_samples"] or cont <= 0 or cont < pair["required_gap_mm"] - 1e-9)


def in_the_way(depths: list[float], pairs: list[dict]) -> frozenset:
    """The keels to take off: for each pair of the verification's ``pairs``
    (:func:`check.verify`) that fails (a collision, no positive gap, or less than the
    sizing's gap between links without a joint), the deeper keel of its two links (the first
    link's of equals; none if neither has one; ``depths`` each link's keel, mm). A second
    round takes the other where the pair still fails."""
    return frozenset(i for i in (deeper(depths, p["links"]) for p in pairs if fails(p))
                     if depths[i])


def deeper(depths: list[float], links: list[int]) -> int:
    """Of a pair's two ``links``, the one whose keel :func:`in_the_way` takes off where the
    pair fails: the deeper keel (the first link's of equals)."""
    return max(links, key=lambda i: (depths[i], -i))
