"""Annotations of the guide's pictures (:mod:`render`): labels, their placement, lines, arrows.

**Placement** (:func:`place_labels`): each label in turn takes the cheapest free box among
candidates on rings around its anchor (and, as a fallback, on a grid over the whole picture).
Hard rules: the box lies inside the picture (``border`` px from its edge) and keeps ``gap`` px
from every box placed before.
Costs (px of leader length): the leader's length, plus :data:`W_CONTENT` times the fraction of
the box over drawn content, :data:`W_ANCHOR` per anchor it covers and per arrow it touches
(``arrows``: an arrow under a label hides which way a piece goes), :data:`W_CROSS` per leader
it crosses or box its leader passes through. Deterministic: ties go to the first candidate.

**Drawing** (Pillow, on the supersampled picture except the label boxes): labels are bold
DejaVu Sans (matplotlib's copy; Pillow's default font where it is missing), dark text in a
white box framed in the label's colour; leaders and anchor dots in that colour; lines dashed
by length along the picture; arrows with a white halo.
"""

from __future__ import annotations

import functools
import importlib.util
from collections.abc import Callable
from pathlib import Path

import numpy as np
from PIL import ImageDraw, ImageFont

from paraloop_core.errors import FabricationError

#: Ring radii (px) and directions of the candidate boxes about an anchor.
RADII = (28.0, 46.0, 70.0, 100.0, 135.0, 180.0, 235.0, 300.0, 380.0)
ANGLES = 24
#: Spacing (px) of the fallback grid of candidate box centres.
GRID_PX = 16
W_CONTENT, W_ANCHOR, W_CROSS = 600.0, 500.0, 250.0
#: Opacity of the stretches of a line hidden behind a mesh.
HIDDEN_ALPHA = 0.3


def attach(anchor: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Point of ``box`` ``(..., 4)`` (x0, y0, x1, y1) nearest ``anchor`` ``(..., 2)``: where
    the leader meets the box."""
    return np.stack([np.clip(anchor[..., 0], box[..., 0], box[..., 2]),
                     np.clip(anchor[..., 1], box[..., 1], box[..., 3])], -1)


def _crosses(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """Whether segments ``a0 a1`` ``(C, 2)`` properly cross the segment ``b0 b1`` ``(2,)``."""
    def orient(p, q, r):
        return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
                       - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))
    return (orient(a0, a1, b0) * orient(a0, a1, b1) < 0) & \
        (orient(b0, b1, a0) * orient(b0, b1, a1) < 0)


def _through(p0: np.ndarray, p1: np.ndarray, box: np.ndarray, samples: int = 12,
             ends: bool = False) -> np.ndarray:
    """Whether segments ``p0 p1`` ``(C, 2)`` pass through ``box`` ``(4,)`` (sampled; their
    ends too where ``ends``)."""
    t = np.linspace(0.0, 1.0, samples)[:, None] if ends else \
        np.linspace(0.08, 0.92, samples)[:, None]
    x = p0[:, 0] + t * (p1[:, 0] - p0[:, 0])  # (samples, C), per coordinate
    y = p0[:, 1] + t * (p1[:, 1] - p0[:, 1])
    return ((x > box[0]) & (x < box[2]) & (y > box[1]) & (y < box[3])).any(0)


def _candidates(anchor: np.ndarray, w: float, h: float, size: tuple[int, int]) -> np.ndarray:
    """Candidate boxes ``(C, 4)``: on the rings (the box's side or corner facing the anchor
    at the ring) and the grid."""
    ang = 2 * np.pi * np.arange(ANGLES) / ANGLES
    u = np.stack([np.cos(ang), np.sin(ang)], -1)
    r = np.asarray(RADII)[:, None, None]
    centre = (anchor + r * u + u * [w / 2, h / 2]).reshape(-1, 2)
    gx, gy = np.meshgrid(np.arange(GRID_PX / 2, size[0], GRID_PX),
                         np.arange(GRID_PX / 2, size[1], GRID_PX))
    centre = np.concatenate([centre, np.stack([gx.ravel(), gy.ravel()], -1)])
    return np.concatenate([centre - [w / 2, h / 2], centre + [w / 2, h / 2]], -1)


def place_labels(anchors: np.ndarray, sizes: np.ndarray, size: tuple[int, int],
                 occupied: np.ndarray | None = None, gap: float = 6.0,
                 border: float = 4.0, arrows: np.ndarray | None = None
                 ) -> np.ndarray:
    """Boxes ``(n, 4)`` (x0, y0, x1, y1, px, y down) for labels of ``sizes`` ``(n, 2)``
    (width, height) pointing at ``anchors`` ``(n, 2)`` in a picture of ``size`` (width,
    height) whose drawn pixels are ``occupied`` ``(height, width)``, avoiding ``arrows``
    ``(m, 2, 2)`` (tail, head, px; module docstring).
    Raises :class:`FabricationError` (``bad-parameters``) when a label has no free place."""
    anchors = np.asarray(anchors, float).reshape(-1, 2)
    sizes = np.asarray(sizes, float).reshape(-1, 2)
    wid, hei = size
    if len(anchors) != len(sizes) or not (np.all(np.isfinite(anchors)) and np.all(sizes > 0)):
        raise FabricationError("labels need one finite anchor and a positive size each",
                               "bad-parameters")
    occ = np.zeros((hei, wid), bool) if occupied is None else np.asarray(occupied, bool)
    if occ.shape != (hei, wid):
        raise FabricationError(f"occupied mask {occ.shape} does not match the picture "
                               f"{(hei, wid)}", "bad-parameters")
    sat = np.zeros((hei + 1, wid + 1))
    sat[1:, 1:] = occ.cumsum(0).cumsum(1)
    placed: list[np.ndarray] = []
    leaders: list[tuple[np.ndarray, np.ndarray]] = []
    for i, (anchor, (w, h)) in enumerate(zip(anchors, sizes, strict=True)):
        box = _candidates(anchor, w, h, size)
        ok = (box[:, 0] >= border) & (box[:, 1] >= border) & \
            (box[:, 2] <= wid - border) & (box[:, 3] <= hei - border)
        for b in placed:
            ok &= (box[:, 0] >= b[2] + gap) | (box[:, 2] <= b[0] - gap) | \
                (box[:, 1] >= b[3] + gap) | (box[:, 3] <= b[1] - gap)
        box = box[ok]
        if len(box) == 0:
            raise FabricationError(
                f"label {i} ({w:.0f} x {h:.0f} px) finds no free place in a {wid} x {hei} px "
                f"picture beside {len(placed)} others: use a larger picture or fewer labels",
                "bad-parameters")
        end = attach(anchor, box)
        cost = np.linalg.norm(end - anchor, axis=1)
        x0, y0 = np.floor(box[:, 0]).astype(int), np.floor(box[:, 1]).astype(int)
        x1, y1 = np.ceil(box[:, 2]).astype(int), np.ceil(box[:, 3]).astype(int)
        drawn = sat[y1, x1] - sat[y0, x1] - sat[y1, x0] + sat[y0, x0]
        cost += W_CONTENT * drawn / ((x1 - x0) * (y1 - y0))
        pad = np.array([-gap, -gap, gap, gap])
        for a in anchors:
            cost += W_ANCHOR * ((a[0] > box[:, 0] - gap) & (a[0] < box[:, 2] + gap)
                                & (a[1] > box[:, 1] - gap) & (a[1] < box[:, 3] + gap))
        for tail, head in np.asarray([] if arrows is None else arrows, float).reshape(-1, 2, 2):
            cost += W_ANCHOR * _through(np.broadcast_to(tail, end.shape),
                                        np.broadcast_to(head, end.shape), box.T + pad[:, None],
                                        ends=True)
        for b, (p, q) in zip(placed, leaders, strict=True):
            cost += W_CROSS * (_crosses(np.broadcast_to(anchor, end.shape), end, p, q)
                               + _through(np.broadcast_to(anchor, end.shape), end, b + pad)
                               + _through(np.broadcast_to(p, end.shape),
                                          np.broadcast_to(q, end.shape), box.T + pad[:, None]))
        best = int(np.argmin(cost))
        placed.append(box[best])
        leaders.append((anchor, end[best]))
    return np.array(placed).reshape(-1, 4)


@functools.lru_cache(maxsize=8)
def font(px: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """Bold DejaVu Sans of ``px`` pixels, matplotlib's copy found without importing
    matplotlib (Pillow's default font if it cannot be found)."""
    spec = importlib.util.find_spec("matplotlib")
    if spec is not None and spec.origin is not None:
        path = Path(spec.origin).parent / "mpl-data" / "fonts" / "ttf" / "DejaVuSans-Bold.ttf"
        try:
            return ImageFont.truetype(str(path), px)
        except OSError:
            pass
    return ImageFont.load_default(px)


def _pad(f) -> tuple[float, float]:
    px = getattr(f, "size", 12)
    return 0.45 * px, 0.25 * px


def box_size(text: str, f) -> tuple[float, float]:
    """Width and height (px) of the box of a label ``text`` in font ``f``."""
    left, top, right, bottom = f.getbbox(text)
    asc, desc = f.getmetrics() if hasattr(f, "getmetrics") else (bottom, 0)
    px, py = _pad(f)
    return right - left + 2 * px, asc + desc + 2 * py


def label_box(draw: ImageDraw.ImageDraw, box: np.ndarray, text: str, color: tuple,
              f) -> None:
    """The label's framed box with its text."""
    px, py = _pad(f)
    x0, y0, x1, y1 = (float(v) for v in box)
    draw.rounded_rectangle((x0, y0, x1, y1), radius=4, fill=(255, 255, 255), outline=color,
                           width=2)
    draw.text((x0 + px - f.getbbox(text)[0], y0 + py), text, font=f, fill=(20, 20, 20))


def leader(draw: ImageDraw.ImageDraw, anchor: np.ndarray, end: np.ndarray, color: tuple,
           ss: int) -> None:
    """Leader line from ``anchor`` to ``end`` (px) with a dot at the anchor."""
    dark = tuple(int(0.8 * c) for c in color)
    draw.line([tuple(anchor), tuple(end)], fill=(255, 255, 255), width=4 * ss)
    draw.line([tuple(anchor), tuple(end)], fill=dark, width=2 * ss)
    r = 4.0 * ss
    draw.ellipse((anchor[0] - r, anchor[1] - r, anchor[0] + r, anchor[1] + r), fill=dark,
                 outline=(255, 255, 255), width=ss)


def snap(xy: np.ndarray, who: np.ndarray, item: int | None, inset: int) -> np.ndarray:
    """``xy`` moved to the nearest pixel centre where ``who`` ``(H, W)`` shows ``item``, at
    least ``inset`` px inside its outline when it is that wide; unchanged without ``item`` or
    where the item is not seen."""
    if item is None:
        return xy
    rows, cols = np.nonzero(who == item)
    if len(rows) == 0:
        return xy
    r0, c0 = rows.min(), cols.min()
    mine = np.zeros((rows.max() - r0 + 1 + 2 * inset, cols.max() - c0 + 1 + 2 * inset), bool)
    mine[rows - r0 + inset, cols - c0 + inset] = True
    core = mine.copy()
    for k in range(1, inset + 1):
        core[k:] &= mine[:-k]
        core[:-k] &= mine[k:]
        core[:, k:] &= mine[:, :-k]
        core[:, :-k] &= mine[:, k:]
    if core.any():
        rows, cols = np.nonzero(core)
        rows, cols = rows + r0 - inset, cols + c0 - inset
    k = int(np.argmin((cols + 0.5 - xy[0]) ** 2 + (rows + 0.5 - xy[1]) ** 2))
    return np.array([cols[k] + 0.5, rows[k] + 0.5])


def line(draw: ImageDraw.ImageDraw, ends: np.ndarray, color: tuple, width: float,
         dashed: bool, ss: int, visible: Callable[[np.ndarray], np.ndarray]) -> None:
    """A projected segment ``ends`` ``(2, 3)`` (px, depth): stretches that ``visible`` passes
    drawn solid, the others at :data:`HIDDEN_ALPHA`; dashes of ``4 width + 4`` px (picture
    size) with gaps of ``2.5 width + 2``."""
    n = max(2, int(np.ceil(np.linalg.norm(ends[1, :2] - ends[0, :2]))) + 1)
    t = np.linspace(0.0, 1.0, n)[:, None]
    pts = ends[0] + t * (ends[1] - ends[0])
    state = np.where(visible(pts), 2, 1)
    if dashed:
        arc = t[:, 0] * np.linalg.norm(ends[1, :2] - ends[0, :2]) / ss
        on, off = 4 * width + 4, 2.5 * width + 2
        state[arc % (on + off) >= on] = 0
    cut = np.flatnonzero(np.diff(state)) + 1
    for run in np.split(np.arange(n), cut):
        s = int(state[run[0]])
        if s and len(run) > 1:
            alpha = 255 if s == 2 else int(255 * HIDDEN_ALPHA)
            draw.line([tuple(pts[run[0], :2]), tuple(pts[run[-1], :2])],
                      fill=(*color, alpha), width=max(1, round(width * ss)))


def arrow(draw: ImageDraw.ImageDraw, ends: np.ndarray, color: tuple, width: float,
          head_px: float, ss: int) -> None:
    """An arrow ``ends[0] -> ends[1]`` (px) with a white halo."""
    d = ends[1] - ends[0]
    length = float(np.linalg.norm(d))
    if length < 1e-9:
        return
    u = d / length
    n = np.array([-u[1], u[0]])
    hl = min(head_px * ss, length)
    base = ends[1] - u * hl
    head = [tuple(ends[1]), tuple(base + 0.45 * hl * n), tuple(base - 0.45 * hl * n)]
    halo = 2.5 * ss
    big = [tuple(ends[1] + u * 2 * halo), tuple(base - u * halo + (0.45 * hl + 2 * halo) * n),
           tuple(base - u * halo - (0.45 * hl + 2 * halo) * n)]
    w = max(1, round(width * ss))
    draw.line([tuple(ends[0]), tuple(base)], fill=(255, 255, 255), width=w + round(2 * halo))
    draw.polygon(big, fill=(255, 255, 255))
    draw.line([tuple(ends[0]), tuple(base + u)], fill=color, width=w)
    draw.polygon(head, fill=color)
