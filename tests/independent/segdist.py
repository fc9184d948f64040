"""Exact segment-segment distance, vectorized (independent of ``paraloop_core``).

The minimum of ``|a(s) - b(u)|`` over ``s, u in [0, 1]`` is attained either at an interior
critical point (both parameters strictly inside, lines not parallel) or on the boundary of the
square, i.e. at an endpoint of one segment against the other segment. We take the minimum of the
four clamped point-segment distances and, where valid, the interior line-line solution; every
candidate is a true distance between points of the segments, so the result never underestimates.
"""

from __future__ import annotations

import numpy as np


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _point_segment(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Squared distance of points to segments, component-first arrays ``(3, ...)``."""
    ab = b - a
    n2 = _dot(ab, ab)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.clip(np.where(n2 > 0, _dot(x - a, ab) / np.where(n2 > 0, n2, 1.0), 0.0), 0, 1)
    r = a + s * ab - x
    return _dot(r, r)


def point_segment(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance ``(...)`` of points ``x`` ``(..., 3)`` to segments ``[a, b]`` ``(..., 3)``."""
    x, a, b = (np.moveaxis(np.asarray(v, float), -1, 0) for v in (x, a, b))
    return np.sqrt(_point_segment(x, a, b))


def segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray
                     ) -> np.ndarray:
    """Distance ``(...)`` between segments ``[p1, q1]`` and ``[p2, q2]`` (each ``(..., 3)``)."""
    p1, q1, p2, q2 = np.broadcast_arrays(*(np.asarray(v, float) for v in (p1, q1, p2, q2)))
    # component-first, relative to p1 (keeps large coordinates well conditioned)
    o = np.moveaxis(p1, -1, 0)
    p1, q1, p2, q2 = (np.moveaxis(v, -1, 0) - o for v in (p1, q1, p2, q2))
    best = np.minimum(np.minimum(_point_segment(p1, p2, q2), _point_segment(q1, p2, q2)),
                      np.minimum(_point_segment(p2, p1, q1), _point_segment(q2, p1, q1)))
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, b = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    c, f = _dot(d1, r), _dot(d2, r)
    den = a * e - b * b
    ok = den > 1e-12 * a * e
    safe = np.where(ok, den, 1.0)
    s = (b * f - c * e) / safe
    u = (a * f - b * c) / safe
    ok &= (s > 0) & (s < 1) & (u > 0) & (u < 1)
    w = p1 + s * d1 - p2 - u * d2
    return np.sqrt(np.where(ok, np.minimum(best, _dot(w, w)), best))
