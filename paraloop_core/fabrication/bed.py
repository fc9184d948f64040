"""Fitting parts on a printer's bed: box footprints turned about the vertical.

A long thin part that does not fit the bed square-on may fit diagonally; a part may rest on any
face of its box. Parts are fitted to the bed less an :data:`EDGE_MM` border (many printers
cannot print at the very edge, and a part filling the bed to the last millimetre is one a
slicer's skirt or a slightly off homing pushes over it).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from paraloop_core.fabrication.profiles import Printer

#: Turns about the vertical (radians, 0.5 degree steps) tried for a footprint: a long thin
#: part that does not fit the bed square-on may fit diagonally.
TURNS = np.radians(np.arange(0.0, 90.01, 0.5))
#: Border (mm) kept free along the bed's edges (and the layout's gap between parts).
EDGE_MM = 5.0


def room_xy(bed_mm: tuple[float, ...] | np.ndarray) -> np.ndarray:
    """``(2,)`` the part of a bed ``bed_mm`` (x, y, z) parts may occupy (mm): less
    :data:`EDGE_MM` on every side."""
    return np.asarray(bed_mm, float)[:2] - 2 * EDGE_MM


def footprint_turn(size_xy: np.ndarray, bed_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(factor, turn)`` ``(...)`` for footprints ``size_xy`` ``(..., 2)`` (mm) on a bed
    ``bed_xy`` ``(2,)``: the largest factor by which a footprint may grow and still fit, turned
    by ``turn`` (radians, one of :data:`TURNS`) about the vertical."""
    w = np.asarray(size_xy, float)[..., None, :]
    c, s = np.cos(TURNS), np.sin(TURNS)
    fx = bed_xy[0] / np.maximum(w[..., 0] * c + w[..., 1] * s, 1e-12)
    fy = bed_xy[1] / np.maximum(w[..., 0] * s + w[..., 1] * c, 1e-12)
    f = np.minimum(fx, fy)
    best = np.argmax(f, axis=-1)
    return np.take_along_axis(f, best[..., None], -1)[..., 0], TURNS[best]


def fit_factor(extents_mm: np.ndarray, printer: Printer) -> np.ndarray:
    """Largest factor ``(P,)`` by which parts with box extents ``(P, 3)`` may grow and still
    fit the bed, the box resting on any of its faces and turned about the vertical (a long bar
    fits diagonally); at least 1 where the part fits."""
    ext = np.asarray(extents_mm, float)
    bed = np.asarray(printer.bed_mm, float)
    best = np.zeros(ext.shape[:-1])
    for up in range(3):  # which box side stands vertical
        flat = np.delete(ext, up, axis=-1)
        f, _ = footprint_turn(flat, room_xy(bed))
        best = np.maximum(best, np.minimum(f, bed[2] / np.maximum(ext[..., up], 1e-12)))
    return best


def laid_fit_factor(extents_mm: np.ndarray, printer: Printer) -> np.ndarray:
    """:func:`fit_factor` of parts laid as they will print (box extents ``(P, 3)`` with z up:
    only turned about the vertical, not stood on another side)."""
    ext = np.asarray(extents_mm, float)
    bed = np.asarray(printer.bed_mm, float)
    f, _ = footprint_turn(ext[..., :2], room_xy(bed))
    return np.minimum(f, bed[2] / np.maximum(ext[..., 2], 1e-12))


def fits_bed(extents_mm: np.ndarray, printer: Printer) -> np.ndarray:
    """Mask ``(P,)``: parts with box extents ``(P, 3)`` fit the bed in some orientation
    (:func:`fit_factor`)."""
    return fit_factor(extents_mm, printer) >= 1.0 - 1e-9


def bed_scale(points: np.ndarray, printer: Printer) -> float:
    """mm per unit at which every link's skeleton (its bar and half of each pin) would just
    fit the bed, flat: a first guess refined by the caller's ``fit``."""
    pts = np.asarray(points, float)
    s, e = pts[0::2], pts[1::2]
    link = np.stack([(np.roll(e, 1, axis=0) + s) / 2, s, e, (e + np.roll(s, -1, axis=0)) / 2], 1)
    centred = link - link.mean(axis=1, keepdims=True)
    _, _, vt = np.linalg.svd(centred)
    ext = np.ptp(np.einsum("pnk,pjk->pnj", centred, vt), axis=1)
    return float(fit_factor(ext, printer).min())


def predicted_fit(plan: Any, points: np.ndarray, printer: Printer,
                  extra: dict[int, np.ndarray] | None = None) -> float:
    """By how much the links of ``plan`` (a :class:`sizing.Plan`, untyped here: sizing
    imports this module) may still grow and fit the bed (<= 1: they do not fit): each link's
    bar (with its width) and bosses, a box along its principal axes; ``extra`` more points
    per link (design units: the end-effector's vertices on link 3)."""
    pts = np.asarray(points, float) * plan.scale
    worst = np.inf
    for i in range(6):
        cloud = [pts[2 * i], pts[2 * i + 1], *(np.asarray((extra or {}).get(i, np.zeros((0, 3))),
                                                          float) * plan.scale)]
        for j, (s0, s1) in ((plan.layouts[i], plan.layouts[i].lower),
                            (plan.layouts[(i - 1) % 6], plan.layouts[(i - 1) % 6].upper)):
            cloud += [j.at(s0), j.at(s1)]
        c = np.asarray(cloud)
        centred = c - c.mean(0)
        vt = np.linalg.svd(centred, full_matrices=False)[2]
        ext = np.ptp(centred @ vt.T, axis=0) + 2 * max(plan.boss.max(), plan.radii[i])
        worst = min(worst, float(fit_factor(ext[None], printer)[0]))
    return worst
