"""Pure-Python scalar path (one pair, one t) for the local refinement: fast for
``scipy.optimize.minimize_scalar``; same conventions as :mod:`dq8` and :mod:`segdist`."""

from __future__ import annotations

import math

Vec = tuple[float, float, float]


def pose_at(coef: list[list[float]], c: float, s: float) -> list[float]:
    """Homogeneous ``sum_j coef_j c^j s^(n-j)`` (8 floats) of a DQ polynomial ``(n+1) x 8``."""
    n = len(coef) - 1
    out = [0.0] * 8
    for j, row in enumerate(coef):
        w = c**j * s ** (n - j)
        for k in range(8):
            out[k] += w * row[k]
    return out


def mover(q: list[float]):
    """``x -> (P x P~ + 2 D P~)/|P|^2`` as a function of a point (3-tuple)."""
    w, x, y, z, d0, d1, d2, d3 = q
    n2 = w * w + x * x + y * y + z * z
    r = ((w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
         (2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
         (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z))
    # vec(D P~) with P~ = (w, -x, -y, -z)
    tx = -d0 * x + w * d1 + (-d2 * z + d3 * y)
    ty = -d0 * y + w * d2 + (-d3 * x + d1 * z)
    tz = -d0 * z + w * d3 + (-d1 * y + d2 * x)
    tr = (2 * tx, 2 * ty, 2 * tz)

    def move(p: Vec) -> Vec:
        return tuple((r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2] + tr[i]) / n2
                     for i in range(3))

    return move


def _sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def point_segment(x: Vec, a: Vec, b: Vec) -> float:
    """Distance of point x to segment [a, b]."""
    ab, ax = _sub(b, a), _sub(x, a)
    n2 = _dot(ab, ab)
    s = min(1.0, max(0.0, _dot(ax, ab) / n2)) if n2 > 0 else 0.0
    return math.dist((a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]), x)


def segment_distance(p1: Vec, q1: Vec, p2: Vec, q2: Vec) -> float:
    """Segment-segment distance (boundary cases plus the valid interior critical point)."""
    o = p1
    p1, q1, p2, q2 = _sub(p1, o), _sub(q1, o), _sub(p2, o), _sub(q2, o)
    best = min(point_segment(p1, p2, q2), point_segment(q1, p2, q2),
               point_segment(p2, p1, q1), point_segment(q2, p1, q1))
    d1, d2, r = _sub(q1, p1), _sub(q2, p2), _sub(p1, p2)
    a, e, b = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    c, f = _dot(d1, r), _dot(d2, r)
    den = a * e - b * b
    if den > 1e-12 * a * e:
        s, u = (b * f - c * e) / den, (a * f - b * c) / den
        if 0 < s < 1 and 0 < u < 1:
            best = min(best, math.dist([p1[i] + s * d1[i] for i in range(3)],
                                       [p2[i] + u * d2[i] for i in range(3)]))
    return best
