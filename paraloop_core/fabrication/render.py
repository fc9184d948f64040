"""Pictures of triangle meshes for the assembly guide: a CPU renderer to PNG (numpy + Pillow).

* **Camera** (:class:`View`): orthographic, looking along ``-direction`` (``direction``: unit
  vector from the scene towards the eye, world frame; default from ``azimuth_deg`` (from +x
  towards +y) and ``elevation_deg`` (above the xy plane)), world ``up`` drawn upwards, fitted
  to ``fit`` points (default: every vertex and line end) with ``margin`` (a fraction of each
  side) left free.
* **Meshes** (:class:`Item`): closed solids with outward normals (back faces are culled),
  any units; flat Lambert shading with a key light above-left of the eye, ambient and a
  head-light fill; silhouettes, creases sharper than ``View.crease_deg`` and open borders
  outlined dark. Items with ``alpha < 1`` are blended over the opaque ones, nearest last
  (each shows its front layer only).
* **Annotations**: :class:`Line3` (depth-tested: hidden stretches drawn faint), :class:`Arrow3`
  (always on top, with a white halo) and :class:`Label` (boxed text with a leader line to its
  anchor, placed by :func:`annotate.place_labels`: inside the image, never over another
  label, preferring empty background near the anchor).
* **Antialiasing**: everything but the label text is drawn ``View.supersample`` times larger
  and box-filtered down; text is drawn at the final size (Pillow antialiases it).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import trimesh
from PIL import Image, ImageDraw

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import annotate, raster

RGB = tuple[int, int, int]
#: Shading: ambient, key light (Lambert) and head-light fill weights (sum 1: a face turned
#: to both lights shows its full colour).
AMBIENT, KEY, FILL = 0.5, 0.38, 0.12
#: Direction of the key light in the camera frame (right, up, towards the eye).
KEY_LIGHT = (-0.45, 0.65, 0.62)
#: Outline colour as a fraction of the item's colour.
EDGE_SHADE = 0.25


def _point(p, name: str) -> tuple[float, float, float]:
    a = np.asarray(p, float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise FabricationError(f"{name} must be 3 finite numbers, got {p!r}", "bad-parameters")
    return (float(a[0]), float(a[1]), float(a[2]))


def _color(c, name: str) -> RGB:
    a = np.asarray(c)
    if a.shape != (3,) or not np.all((a >= 0) & (a <= 255)):
        raise FabricationError(f"{name} must be 3 numbers in [0, 255], got {c!r}",
                               "bad-parameters")
    return (int(a[0]), int(a[1]), int(a[2]))


@dataclass(frozen=True)
class Item:
    """A closed triangle mesh drawn in ``color`` (RGB 0-255) with opacity ``alpha`` in
    (0, 1]; ``edges``: outline its silhouette and creases (found through shared vertices:
    an unmerged mesh would be outlined along every triangle)."""

    mesh: trimesh.Trimesh
    color: RGB
    alpha: float = 1.0
    edges: bool = True

    def __post_init__(self):
        if not isinstance(self.mesh, trimesh.Trimesh) or \
                not np.all(np.isfinite(self.mesh.vertices)):
            raise FabricationError("Item.mesh must be a trimesh.Trimesh with finite vertices",
                                   "bad-parameters")
        object.__setattr__(self, "color", _color(self.color, "Item.color"))
        if not 0.0 < self.alpha <= 1.0:
            raise FabricationError(f"Item.alpha must be in (0, 1], got {self.alpha}",
                                   "bad-parameters")


@dataclass(frozen=True)
class Label:
    """``text`` in a box with a leader line to ``anchor_xyz`` (world). With ``item`` (an index
    into the rendered items) the anchor moves to the nearest pixel where that item is seen,
    so the leader never points at something hidden."""

    text: str
    anchor_xyz: tuple[float, float, float]
    color: RGB = (60, 60, 60)
    item: int | None = None

    def __post_init__(self):
        object.__setattr__(self, "anchor_xyz", _point(self.anchor_xyz, "Label.anchor_xyz"))
        object.__setattr__(self, "color", _color(self.color, "Label.color"))
        if not self.text.strip():
            raise FabricationError("Label.text must not be empty", "bad-parameters")


@dataclass(frozen=True)
class Line3:
    """A segment ``p0``-``p1`` (world), ``width`` px, solid or ``dashed``; stretches behind
    meshes are drawn faint."""

    p0: tuple[float, float, float]
    p1: tuple[float, float, float]
    color: RGB = (40, 40, 40)
    dashed: bool = False
    width: float = 2.0

    def __post_init__(self):
        object.__setattr__(self, "p0", _point(self.p0, "Line3.p0"))
        object.__setattr__(self, "p1", _point(self.p1, "Line3.p1"))
        object.__setattr__(self, "color", _color(self.color, "Line3.color"))


@dataclass(frozen=True)
class Arrow3:
    """An arrow from ``tail`` to ``head`` (world), shaft ``width`` px, head ``head_px`` long,
    drawn on top of everything."""

    tail: tuple[float, float, float]
    head: tuple[float, float, float]
    color: RGB = (210, 30, 30)
    width: float = 5.0
    head_px: float = 22.0

    def __post_init__(self):
        object.__setattr__(self, "tail", _point(self.tail, "Arrow3.tail"))
        object.__setattr__(self, "head", _point(self.head, "Arrow3.head"))
        object.__setattr__(self, "color", _color(self.color, "Arrow3.color"))


@dataclass(frozen=True)
class View:
    """Camera and picture settings (module docstring); ``size`` ``(width, height)`` px."""

    size: tuple[int, int] = (1000, 750)
    azimuth_deg: float = -60.0
    elevation_deg: float = 30.0
    direction: tuple[float, float, float] | None = None
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    margin: float = 0.08
    fit: np.ndarray | None = field(default=None, compare=False)
    background: RGB = (255, 255, 255)
    supersample: int = 2
    crease_deg: float = 40.0
    edge_px: float = 1.4
    font_px: int = 16

    def __post_init__(self):
        w, h = self.size
        if not (16 <= w <= 8000 and 16 <= h <= 8000):
            raise FabricationError(f"View.size must be 16..8000 px each, got {self.size}",
                                   "bad-parameters")
        if not (1 <= self.supersample <= 4 and 0.0 <= self.margin < 0.5 and self.font_px >= 6):
            raise FabricationError("View: supersample 1..4, margin in [0, 0.5), font_px >= 6",
                                   "bad-parameters")

    def eye(self) -> np.ndarray:
        """Unit vector from the scene towards the eye (world)."""
        if self.direction is not None:
            d = np.asarray(self.direction, float)
            n = float(np.linalg.norm(d))
            if not (np.isfinite(n) and n > 0):
                raise FabricationError(f"View.direction must be a non-zero vector, got "
                                       f"{self.direction}", "bad-parameters")
            return d / n
        az, el = np.radians(self.azimuth_deg), np.radians(self.elevation_deg)
        return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


@dataclass(frozen=True)
class Camera:
    """World -> screen: ``basis`` rows (right, up, towards the eye), ``scale`` px per unit and
    ``offset`` (px) at the render size ``shape`` ``(H, W)``; normalized depth
    ``(top - p.eye) / (top - bottom)`` (0 nearest)."""

    basis: np.ndarray
    scale: float
    offset: np.ndarray
    top: float
    bottom: float
    shape: tuple[int, int]

    def project(self, p: np.ndarray) -> np.ndarray:
        """``(..., 3)`` world -> ``(..., 3)`` (x px, y px down, normalized depth)."""
        q = np.asarray(p, float) @ self.basis.T
        x = q[..., 0] * self.scale + self.offset[0]
        y = self.offset[1] - q[..., 1] * self.scale
        return np.stack([x, y, (self.top - q[..., 2]) / (self.top - self.bottom)], -1)

    def depth_per_px(self) -> float:
        """Normalized depth of one pixel's width (for depth tolerances)."""
        return 1.0 / (self.scale * (self.top - self.bottom))


def camera(view: View, points: np.ndarray, ss: int | None = None) -> Camera:
    """The camera of ``view`` framing ``points`` ``(N, 3)`` (``view.fit`` if set; the depth
    range always spans ``points``) at ``ss`` times the picture size (default
    ``view.supersample``)."""
    ss = view.supersample if ss is None else ss
    e = view.eye()
    right = np.cross(np.asarray(view.up, float), e)
    if np.linalg.norm(right) < 1e-6:  # looking along up: any right will do
        right = np.cross([0.0, 1.0, 0.0] if abs(e[1]) < 0.9 else [1.0, 0.0, 0.0], e)
    right /= np.linalg.norm(right)
    basis = np.stack([right, np.cross(e, right), e])
    pts = np.asarray(points, float).reshape(-1, 3)
    frame = pts if view.fit is None else np.asarray(view.fit, float).reshape(-1, 3)
    if len(frame) == 0 or not (np.all(np.isfinite(frame)) and np.all(np.isfinite(pts))):
        raise FabricationError("nothing to frame: no finite points", "bad-parameters")
    q = frame @ basis.T
    lo, hi = q[:, :2].min(0), q[:, :2].max(0)
    w, h = view.size[0] * ss, view.size[1] * ss
    ext = np.maximum(hi - lo, 1e-9 * max(1.0, float(np.abs(q).max())))
    scale = float(min(w * (1 - 2 * view.margin) / ext[0], h * (1 - 2 * view.margin) / ext[1]))
    mid = (lo + hi) / 2
    offset = np.array([w / 2 - mid[0] * scale, h / 2 + mid[1] * scale])
    depth = np.concatenate([pts, frame]) @ e
    pad = 0.01 * max(float(np.ptp(depth)), 1e-9)
    return Camera(basis, scale, offset, float(depth.max()) + pad, float(depth.min()) - pad,
                  (h, w))


@dataclass(frozen=True)
class _Layer:
    """One item's culled front faces on screen: ``xy`` ``(F, 3, 2)``, ``depth`` ``(F, 3)``
    and shaded ``rgb`` ``(F, 3)``; ``edges`` ``(E, 2, 3)`` screen end points to outline."""

    xy: np.ndarray
    depth: np.ndarray
    rgb: np.ndarray
    edges: np.ndarray


def _geometry(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices ``(V, 3)``, faces ``(F, 3)`` and unit face normals ``(F, 3)`` of ``mesh``."""
    v = np.asarray(mesh.vertices, float)
    f = np.asarray(mesh.faces, np.int64)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return v, f, n


def _layer(item: Item, cam: Camera, crease_cos: float) -> _Layer:
    v, f, n = _geometry(item.mesh)
    eye = cam.basis[2]
    front = n @ eye > 0.0
    key = np.asarray(KEY_LIGHT) @ cam.basis  # above-left of the eye
    key /= np.linalg.norm(key)
    shade = AMBIENT + KEY * np.clip(n @ key, 0.0, 1.0) + FILL * np.clip(n @ eye, 0.0, 1.0)
    rgb = np.asarray(item.color, float) * shade[:, None]
    s = cam.project(v)
    edges = np.empty((0, 2, 3))
    if item.edges and len(f):
        edges = s[raster.feature_edges(f, n, front, crease_cos)]
    return _Layer(s[f[front]][..., :2], s[f[front]][..., 2], rgb[front], edges)


def _outline(img: np.ndarray, layer: _Layer, keys: np.ndarray, cam: Camera, color: np.ndarray,
             width: float, alpha: float) -> None:
    """Draw ``layer``'s visible edges into ``img`` ``(H * W, 3)`` ``uint8``."""
    if len(layer.edges) == 0:
        return
    pts, _ = raster.segment_samples(layer.edges[:, 0], layer.edges[:, 1], 0.7)
    pts = pts[raster.visible(pts, keys, cam.shape, 2.5 * cam.depth_per_px())]
    pix = raster.stamp(pts[:, :2], width / 2, cam.shape)
    img[pix] = np.round((1 - alpha) * img[pix] + alpha * color).astype(np.uint8)


def _all_points(items: Sequence[Item], lines: Sequence[Line3 | Arrow3]) -> np.ndarray:
    pts = [np.asarray(it.mesh.vertices, float).reshape(-1, 3) for it in items]
    for ln in lines:
        pts.append(np.array([ln.p0, ln.p1] if isinstance(ln, Line3) else [ln.tail, ln.head]))
    return np.concatenate(pts) if pts else np.empty((0, 3))


def _check(items: Sequence[Item], labels: Sequence[Label],
           lines: Sequence[Line3 | Arrow3]) -> None:
    if not all(isinstance(i, Item) for i in items):
        raise FabricationError("items must be Item instances", "bad-parameters")
    if not all(isinstance(ln, (Line3, Arrow3)) for ln in lines):
        raise FabricationError("lines must be Line3 or Arrow3 instances", "bad-parameters")
    for lab in labels:
        if lab.item is not None and not 0 <= lab.item < len(items):
            raise FabricationError(f"label {lab.text!r}: item {lab.item} is not one of the "
                                   f"{len(items)} items", "bad-parameters")


def _opaque(items: Sequence[Item], cam: Camera, crease_cos: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[_Layer]]:
    """Z-buffer keys, face colours ``(F, 3)`` and face -> item ``(F,)`` of the opaque items."""
    layers = [_layer(it, cam, crease_cos) for it in items]
    keys = np.full(cam.shape[0] * cam.shape[1], raster.EMPTY, np.int64)
    first = 0
    for it, layer in zip(items, layers, strict=True):
        if it.alpha == 1.0:
            raster.rasterize(layer.xy, layer.depth, cam.shape, keys, first)
        first += len(layer.xy)
    rgb = np.concatenate([la.rgb for la in layers]) if layers else np.empty((0, 3))
    owner = np.repeat(np.arange(len(layers)), [len(la.xy) for la in layers])
    return keys, rgb, owner, layers


class Coverage:
    """Which of ``items`` is seen at each pixel of a view (every item taken as opaque, no
    supersampling): for choosing views. The items' geometry is taken once, so that many views
    of one scene cost a projection and a z-buffer each."""

    def __init__(self, items: Sequence[Item]):
        _check(items, (), ())
        self.geometry = [_geometry(it.mesh) for it in items]
        self.points = _all_points(items, ())

    def seen(self, view: View) -> tuple[np.ndarray, Camera]:
        """``(who, camera)``: the item seen at each pixel ``(H, W)`` ``int`` (-1: background)
        at the picture size of ``view``, and the camera that drew it."""
        cam = camera(view, self.points, 1)
        xy, depth = [], []
        for v, f, n in self.geometry:  # each item's front faces, keyed in order
            s = cam.project(v)[f[n @ cam.basis[2] > 0.0]]
            xy.append(s[..., :2])
            depth.append(s[..., 2])
        owner = np.repeat(np.arange(len(xy)), [len(a) for a in xy])
        keys = raster.rasterize(np.concatenate(xy), np.concatenate(depth), cam.shape)
        seen = keys != raster.EMPTY
        out = np.full(keys.shape, -1, np.int64)
        out[seen] = owner[keys[seen] & raster.FACE_MASK]
        return out.reshape(cam.shape), cam


def render_image(items: Sequence[Item], labels: Sequence[Label] = (),
                 lines: Sequence[Line3 | Arrow3] = (), view: View = View()) -> Image.Image:
    """The picture (RGB, ``view.size``) of ``items`` with ``labels`` and ``lines``
    (module docstring). Raises :class:`FabricationError` (``bad-parameters``) for bad input
    or labels that do not fit."""
    _check(items, labels, lines)
    ss = view.supersample
    cam = camera(view, _all_points(items, lines))
    h, w = cam.shape
    keys, rgb, owner, layers = _opaque(items, cam, float(np.cos(np.radians(view.crease_deg))))
    img = np.empty((h * w, 3), np.uint8)
    img.reshape(h, 3 * w)[:] = np.tile(np.asarray(view.background, np.uint8), w)  # row by row
    seen = np.flatnonzero(keys != raster.EMPTY)
    face = keys[seen] & raster.FACE_MASK
    img[seen] = np.round(rgb).astype(np.uint8)[face]
    edge_w = view.edge_px * ss
    for it, layer in zip(items, layers, strict=True):
        if it.alpha == 1.0:
            _outline(img, layer, keys, cam, EDGE_SHADE * np.asarray(it.color), edge_w, 1.0)
    glass = [k for k, it in enumerate(items) if it.alpha < 1.0 and len(layers[k].xy)]
    for k in sorted(glass, key=lambda k: -float(layers[k].depth.mean())):  # far to near
        layer, a = layers[k], items[k].alpha
        own = raster.rasterize(layer.xy, layer.depth, cam.shape)
        front = np.flatnonzero(own < keys)
        img[front] = np.round((1 - a) * img[front]
                              + a * layer.rgb[own[front] & raster.FACE_MASK]).astype(np.uint8)
        _outline(img, layer, keys, cam, EDGE_SHADE * np.asarray(items[k].color), edge_w, a)
    im = Image.fromarray(img.reshape(h, w, 3))
    draw = ImageDraw.Draw(im, "RGBA")
    for ln in lines:
        if isinstance(ln, Line3):
            annotate.line(draw, cam.project(np.array([ln.p0, ln.p1])), ln.color, ln.width,
                          ln.dashed, ss, lambda p: raster.visible(
                              p, keys, cam.shape, 2.5 * cam.depth_per_px()))
    for ln in lines:
        if isinstance(ln, Arrow3):
            annotate.arrow(draw, cam.project(np.array([ln.tail, ln.head]))[:, :2], ln.color,
                           ln.width, ln.head_px, ss)
    if not labels:
        return im.reduce(ss) if ss > 1 else im
    # anchors and free space at the picture's size (the item seen at one sample per pixel)
    sub = keys.reshape(h, w)[ss // 2::ss, ss // 2::ss]
    who = np.full(sub.shape, -1, np.int64)
    who[sub != raster.EMPTY] = owner[sub[sub != raster.EMPTY] & raster.FACE_MASK]
    anchors = np.array([annotate.snap(cam.project(np.array(lab.anchor_xyz))[:2] / ss, who,
                                      lab.item, 2) for lab in labels])
    small = np.asarray(im.reduce(ss) if ss > 1 else im)
    drawn = np.zeros(small.shape[:2], bool)
    for k, level in enumerate(view.background):  # per channel: no reduction over 3 values
        drawn |= small[..., k] != level
    font = annotate.font(view.font_px)
    sizes = np.array([annotate.box_size(lab.text, font) for lab in labels])
    arrows = np.array([cam.project(np.array([ln.tail, ln.head]))[:, :2] / ss
                       for ln in lines if isinstance(ln, Arrow3)]).reshape(-1, 2, 2)
    boxes = annotate.place_labels(anchors, sizes, view.size, drawn, arrows=arrows)
    for lab, a, box in zip(labels, anchors, boxes, strict=True):
        annotate.leader(draw, a * ss, annotate.attach(a, box) * ss, lab.color, ss)
    im = im.reduce(ss) if ss > 1 else im
    draw = ImageDraw.Draw(im)
    for lab, box in zip(labels, boxes, strict=True):
        annotate.label_box(draw, box, lab.text, lab.color, font)
    return im


def render(items: Sequence[Item], labels: Sequence[Label] = (),
           lines: Sequence[Line3 | Arrow3] = (), view: View = View()) -> bytes:
    """:func:`render_image` as PNG bytes."""
    buf = io.BytesIO()
    render_image(items, labels, lines, view).save(buf, format="PNG", compress_level=3)
    return buf.getvalue()
