"""A link's print flat: the face of its hexagonal bar it is printed on, and what the cut there
leaves its bores.

A link is printed lying on one flat face of its bar (layers along the bar, the strong
direction); which face is a turn about the bar (:data:`TURNS_DEG`). Everything below that face
is cut off, bosses included, so every bore must keep the printer's wall between it and the
flat (:func:`room`; the hardware sits outside the bosses: there are no recesses to keep). A
joint axis is a straight line, so along a boss the distance to the flat is linear and its two
ends decide (:func:`depths`): the deepest point of the cylinder of radius ``room`` about that
stretch of axis is an end's depth plus ``room`` times the sine of the axis' angle to the
flat's normal (exact: a steep axis needs less than a level one). A bar of corner radius ``r``
has its flat ``r sqrt(3) / 2`` below its axis, which passes through the link's joint points:
the flat keeps every wall when that is at least the deepest point a wall needs
(:func:`least_depth`, minimised over the turns), which :mod:`sizing` uses to size the bars and
:mod:`layout` to pick the turn; a turn keeping less room than :data:`WALL_ROOM_MM` but at least
:data:`MIN_ROOM_MM` is taken where none keeps the full room (:func:`lies_flat`). Where the
room between the links does not allow so thick a bar, the link is cut deeper (:func:`lift`)
and lies on a keel down to that cut (:func:`parts.keeled`), or, where the keel does not clear
the other links, stands on its bosses' cut faces with its bar over support.
"""

from __future__ import annotations

import numpy as np

from paraloop_core.fabrication.joints import Joint

#: Turns about the bar tried for its print flat (degrees).
TURNS_DEG = np.arange(0.0, 360.0, 10.0)
#: Room (mm) a flat keeps beyond a bore's wall (:func:`room`): two layers, so that a cut
#: never leaves the printer's minimum wall exactly (polygons and the slicer take a little).
WALL_ROOM_MM = 0.4
#: Least room (mm) beyond a bore's wall a flat keeps where the full :data:`WALL_ROOM_MM` does
#: not fit: one layer. Only a link whose every turn keeps less is lifted onto supports.
MIN_ROOM_MM = 0.2
#: :func:`wall_slack` (mm) down to which a link still lies on its bar's face.
FLAT_SLACK = MIN_ROOM_MM - WALL_ROOM_MM


def down_candidates(bar: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Unit directions ``(K, 3)`` perpendicular to the bar ``(p0, p1)``, one per
    :data:`TURNS_DEG`."""
    p0, p1 = (np.asarray(p, float) for p in bar)
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    a = np.cross(u, [1.0, 0, 0] if abs(u[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(u, a)
    t = np.radians(TURNS_DEG)
    return np.cos(t)[:, None] * a + np.sin(t)[:, None] * b


def room(j: Joint, upper: bool, wall: float) -> float:
    """Radius (mm) about joint ``j``'s axis the flat must leave to one side of it: the bore,
    its ``wall`` and :data:`WALL_ROOM_MM` (a washer a little wider bears on the rest of the
    face)."""
    return j.bore[1 if upper else 0] + wall + WALL_ROOM_MM


def depths(downs: np.ndarray, joints: list[tuple[Joint, bool]], wall: float) -> np.ndarray:
    """``(K,)``: for each unit ``down`` ``(K, 3)``, the largest ``down . x`` (mm) a flat with
    that normal must reach beyond to leave every boss of ``joints`` (a link's ``(joint, upper
    side)`` pairs) its :func:`room`."""
    downs = np.atleast_2d(np.asarray(downs, float))
    deepest = np.full(len(downs), -np.inf)
    for j, upper in joints:
        ends = np.stack([j.at(s) for s in (j.upper if upper else j.lower)])  # (2, 3)
        # the cylinder of radius room about the boss's stretch of axis reaches below an end
        # only across the axis: by room |sin| of the axis' angle to down (the bore is open
        # at the boss's faces, so nothing is kept past them)
        across = np.sqrt(np.clip(1.0 - (downs @ j.w) ** 2, 0.0, 1.0))
        deepest = np.maximum(deepest, (downs @ ends.T).max(axis=1)
                             + room(j, upper, wall) * across)
    return deepest


def wall_slack(down: np.ndarray, flat: float, joints: list[tuple[Joint, bool]],
               wall: float) -> float:
    """Least room (mm) that cutting at ``down . x = flat`` leaves the walls of ``joints``
    (< 0: the cut breaks into a bore)."""
    return float(flat - depths(down, joints, wall)[0])


def least_depth(bar: tuple[np.ndarray, np.ndarray], joints: list[tuple[Joint, bool]],
                wall: float) -> float:
    """Least distance (mm) below the bar's axis (through ``bar[0]``) at which some turn's flat
    keeps every wall of ``joints``: the bar's flat must lie at least this far down."""
    downs = down_candidates(bar)
    return float(np.min(depths(downs, joints, wall) - downs @ np.asarray(bar[0], float)))


def lies_flat(slack: float) -> bool:
    """Whether a link whose print flat has ``slack`` (:func:`wall_slack`) lies on its bar's
    face: every bore keeps its wall and at least :data:`MIN_ROOM_MM` more from the flat."""
    return bool(slack >= FLAT_SLACK)


def lift(slack: float) -> float:
    """How far (mm) below its bar's down face a link whose print flat has ``slack`` is cut:
    0 where it :func:`lies_flat`, else as deep as the deepest wall and :data:`MIN_ROOM_MM`
    need (the bosses' cut faces stand on the bed, the bar over support)."""
    return max(0.0, FLAT_SLACK - float(slack))
