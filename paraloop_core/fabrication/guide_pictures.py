"""What the assembly guide's pictures show: pieces, colours, labels, arrows and the camera.

Composition only (drawing is :mod:`render`), over plain inputs so it outlives any one way of
building parts: :class:`Piece` (a rigid solid with a name and colour, mm) and :class:`Joint`
(a numbered axis with the axial range and radius of its hardware).

* :func:`loop_scene`: the assembled loop, every piece named (leader in its colour) and every
  joint numbered; the view is the candidate (azimuth every 30 deg, elevation 20 / 50 deg,
  world z up) that sees the most joints, then shows every piece best with the joints spread
  apart (room for their labels).
* :func:`exploded_scene`: one joint pulled apart along its axis: groups of pieces shifted by
  their own offsets (mm along the axis), the axis dashed, an arrow back to their places per
  direction (the farthest group's), framed on the joint. The axis is drawn left to right
  (positive offsets to the right); the eye turns about it (every 45 deg, tilted 15 deg either
  way along it) to see the pieces flagged ``focus`` (pin, bore) best, preferring views from
  above.
* :func:`locator_scene`: where one joint is: its two pieces in colour, the rest faint.
* :func:`assembly_scenes`: the guide's pictures of a printed :class:`assembly.Assembly`.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import trimesh

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import render
from paraloop_core.fabrication.assembly import Assembly
from paraloop_core.fabrication.check import part_trimesh
from paraloop_core.fabrication.export import LINK_COLORS
from paraloop_core.fabrication.render import RGB, Arrow3, Item, Label, Line3, View

#: Colours of the joint hardware in the pictures (apart from every link colour).
PIN_COLOR: RGB = (250, 205, 30)
BORE_COLOR: RGB = (40, 205, 220)
#: The bore itself, seen through its boss drawn translucent in BORE_COLOR.
BORE_DARK: RGB = (0, 95, 120)
JOINT_COLOR: RGB = (30, 30, 30)
NUT_COLOR: RGB = (240, 120, 20)
STEEL: RGB = (170, 175, 185)
ARROW_COLOR: RGB = (215, 30, 30)
#: Pieces not involved in a step.
FAINT: RGB = (190, 190, 190)
#: Size (px) of the pictures and of the quick renders that choose their views.
SIZE = (900, 675)
#: Elevation (deg) of the eye over an upright exploded view (:func:`exploded_scene`).
UPRIGHT_TILT = 10.0
PROBE = (200, 150)


@dataclass(frozen=True)
class Piece:
    """A rigid solid: ``mesh`` (mm, assembled pose), ``color``, opacity ``alpha``; labelled
    ``name`` (empty: no label); ``focus``: an exploded view is chosen to show it."""

    name: str
    mesh: trimesh.Trimesh
    color: RGB
    focus: bool = False
    alpha: float = 1.0


@dataclass(frozen=True)
class Joint:
    """Joint ``number``: axis through ``point`` along unit ``axis`` (mm); its hardware spans
    ``point + s axis`` for ``s`` in ``[s0, s1]`` within ``radius``; ``piece``: index of a piece
    holding it (its number's label points there)."""

    number: int
    point: np.ndarray
    axis: np.ndarray
    s0: float
    s1: float
    radius: float
    piece: int = 0
    #: the axis's label in an exploded view (default "axis of joint <number>")
    name: str = ""


@dataclass(frozen=True)
class Scene:
    """Everything one picture shows; :meth:`png` renders it."""

    items: tuple[Item, ...]
    labels: tuple[Label, ...]
    lines: tuple[Line3 | Arrow3, ...]
    view: View

    def png(self) -> bytes:
        return render.render(self.items, self.labels, self.lines, self.view)


def _seen_score(cover: render.Coverage, view: View, targets: Sequence[int]) -> float:
    """How well ``view`` shows ``targets``: log(1 + pixels where an item is seen), the least
    of the targets' plus a fifth of the mean over all items."""
    who, _ = cover.seen(view)
    seen = np.log1p(np.bincount(who[who >= 0].ravel(), minlength=len(cover.geometry)))
    return float(seen[list(targets)].min(initial=0.0) + 0.2 * seen.mean())


def loop_scene(pieces: Sequence[Piece], joints: Sequence[Joint], size=SIZE) -> Scene:
    """The assembled loop, pieces named and joints numbered (module docstring)."""
    if not pieces:
        raise FabricationError("a loop picture needs pieces", "bad-parameters")
    items = tuple(Item(p.mesh, p.color) for p in pieces)
    best, eye = -np.inf, None
    cover = render.Coverage(items)
    points = np.array([j.point for j in joints], float).reshape(-1, 3)
    for el in (20.0, 50.0):
        for az in range(0, 360, 30):
            probe = View(size=PROBE, azimuth_deg=az, elevation_deg=el, supersample=1)
            who, cam = cover.seen(probe)
            xy = cam.project(points)[:, :2]
            col = np.clip(xy[:, 0].astype(int), 0, PROBE[0] - 1)
            row = np.clip(xy[:, 1].astype(int), 0, PROBE[1] - 1)
            # a joint is seen when its own piece (or nothing) is what shows at its point
            seen = (who[row, col] == [j.piece for j in joints]) | (who[row, col] == -1)
            gaps = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(len(xy)) * 1e9
            spread = gaps.min(initial=np.hypot(*PROBE)) / np.hypot(*PROBE)
            counts = np.bincount(who[who >= 0].ravel(), minlength=len(items))
            score = seen.sum() + float(np.log1p(counts).mean()) + 10.0 * spread
            if score > best:
                best, eye = score, (az, el)
    view = View(size=size, azimuth_deg=eye[0], elevation_deg=eye[1], margin=0.1)
    labels = [Label(p.name, p.mesh.centroid, p.color, item=k)
              for k, p in enumerate(pieces) if p.name]
    labels += [Label(f"joint {j.number}", j.point, JOINT_COLOR, item=j.piece) for j in joints]
    return Scene(items, tuple(labels), (), view)


def locator_scene(pieces: Sequence[Piece], joint: Joint, shown: Sequence[int],
                  view: View) -> Scene:
    """Where joint ``joint`` is in the loop: the pieces ``shown`` in colour and named, the
    others faint grey, the joint numbered; seen as ``view`` (e.g. the loop picture's)."""
    items, labels = [], []
    for k, p in enumerate(pieces):
        if k in shown:
            items.append(Item(p.mesh, p.color))
            if p.name:
                labels.append(Label(p.name, p.mesh.centroid, p.color, item=k))
        else:
            items.append(Item(p.mesh, FAINT, alpha=0.3, edges=False))
    labels.append(Label(f"joint {joint.number}", joint.point, JOINT_COLOR, item=joint.piece))
    return Scene(tuple(items), tuple(labels), (), view)


def exploded_scene(groups: Sequence[tuple[Sequence[Piece], float]], joint: Joint,
                   size: tuple[int, int] | None = None, upright: bool = False) -> Scene:
    """Joint ``joint`` pulled apart: each group of pieces shifted by its offset (mm along
    the axis), framed on the joint (module docstring); ``size`` (px, None: :data:`SIZE`'s
    width and the height the frame needs, at least 64 % of SIZE's); ``upright``: the axis
    drawn top to bottom, seen from a little above (the base: the rod stands on its plate)."""
    w = np.asarray(joint.axis, float)
    w = w / np.linalg.norm(w)
    at = np.asarray(joint.point, float)
    offsets = [float(off) for _, off in groups]
    lo, hi = joint.s0 + min(offsets), joint.s1 + max(offsets)
    margin = 2.5 * joint.radius
    items, labels, targets = [], [], []
    for pieces, offset in groups:
        for p in pieces:
            mesh = p.mesh.copy()
            mesh.apply_translation(offset * w)
            if p.focus:
                targets.append(len(items))
            if p.name:
                labels.append(Label(p.name, _near(mesh.vertices, at, w, lo - margin,
                                                  hi + margin, 2 * margin),
                                    p.color, item=len(items)))
            items.append(Item(mesh, p.color, p.alpha))
    u = np.cross(w, [1.0, 0.0, 0.0] if abs(w[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(w, u)
    best, pick = -np.inf, None
    cover = render.Coverage(items)
    for tilt in ((UPRIGHT_TILT,) if upright else (15.0, -15.0)):
        for phi in np.radians(np.arange(0, 360, 45)):
            eye = np.cos(np.radians(tilt)) * (np.cos(phi) * u + np.sin(phi) * v) \
                - np.sin(np.radians(tilt)) * w
            up = -w if upright else np.cross(eye, w)
            ring = _frame(joint.point, w, np.cross(w, eye), lo - margin, hi + margin, margin)
            if upright:  # the whole of every piece in the frame (a plate reaches far out)
                ring = np.concatenate([ring, *(it.mesh.bounding_box.vertices for it in items)])
            probe = View(size=PROBE, direction=tuple(eye), up=tuple(up), fit=ring, supersample=1)
            score = _seen_score(cover, probe, targets) + 0.3 * eye[2]
            if score > best:
                best, pick = score, (eye, up, ring)
    eye, up, ring = pick
    if size is None and upright:  # as high as the default, as wide as the frame needs
        size = (int(np.clip(SIZE[1] * 2.5 * margin / (hi - lo + 2 * margin), 0.64 * SIZE[1],
                            SIZE[0])), SIZE[1])
    elif size is None:  # as wide as the default, as high as the joint's frame needs
        size = (SIZE[0], int(np.clip(SIZE[0] * 2.5 * margin / (hi - lo + 2 * margin),
                                     0.64 * SIZE[1], SIZE[1])))
    view = View(size=size, direction=tuple(eye), up=tuple(up), fit=ring, margin=0.06)
    side = np.cross(w, eye)
    side /= np.linalg.norm(side)
    lines: list[Line3 | Arrow3] = [Line3(at + (lo - margin) * w, at + (hi + margin) * w,
                                         JOINT_COLOR, dashed=True, width=2.0)]
    probe = View(size=PROBE, direction=tuple(eye), up=tuple(up), fit=ring, supersample=1)
    who, cam = cover.seen(probe)
    # one arrow per direction, the farthest group's (the nearer groups' arrows lay on its
    # shaft, a row of heads that read as a glitch); two directions on opposite sides of the
    # axis (else one shaft runs through the other's head), the sides with less in the way
    far = [o for o in (min(min(offsets), 0.0), max(max(offsets), 0.0)) if o != 0.0]

    def arrow(off: float, sign: float) -> Arrow3:
        base = at + sign * side * 1.8 * joint.radius + (joint.s0 if off > 0 else joint.s1) * w
        return Arrow3(base + off * w, base + 0.25 * off * w, ARROW_COLOR)

    signs = [(1.0, -1.0), (-1.0, 1.0)] if len(far) == 2 else [(1.0,), (-1.0,)]
    lines += min(([arrow(off, sg) for off, sg in zip(far, pick, strict=True)] for pick in signs),
                 key=lambda arrows: sum(_covered(who, cam, a) for a in arrows))
    labels.append(Label(joint.name or f"axis of joint {joint.number}",
                        at + (lo - 0.9 * margin) * w,
                        JOINT_COLOR))
    return Scene(tuple(items), tuple(labels), tuple(lines), view)


def _covered(who: np.ndarray, cam: render.Camera, arrow: Arrow3) -> int:
    """Pixels of ``who`` (a coverage) under the arrow's shaft, 20 samples."""
    p = cam.project(np.linspace(arrow.tail, arrow.head, 20))
    col = np.clip(p[:, 0].astype(int), 0, who.shape[1] - 1)
    row = np.clip(p[:, 1].astype(int), 0, who.shape[0] - 1)
    return int((who[row, col] >= 0).sum())


def _near(v: np.ndarray, at: np.ndarray, w: np.ndarray, lo: float, hi: float,
          reach: float) -> np.ndarray:
    """Mean of the vertices ``v`` within ``reach`` of the axis ``at + s w``, ``s`` in
    ``[lo, hi]`` (what a close-up of the joint shows of a piece); all of them if none is."""
    s = (v - at) @ w
    radial = np.linalg.norm(v - at - s[:, None] * w, axis=1)
    near = (s >= lo) & (s <= hi) & (radial <= reach)
    return v[near].mean(0) if near.any() else v.mean(0)


def _frame(at: np.ndarray, w: np.ndarray, side: np.ndarray, lo: float, hi: float,
           half: float) -> np.ndarray:
    """Points ``(4, 3)`` spanning the axial range ``[lo, hi]`` and ``half`` either side."""
    side = side / max(float(np.linalg.norm(side)), 1e-12)
    return np.array([at + s * w + k * half * side for s in (lo, hi) for k in (-1.0, 1.0)])


def _tm(solid) -> trimesh.Trimesh:
    return part_trimesh(solid)


def _rgb(c) -> RGB:
    return tuple(int(v) for v in c)


def assembly_scenes(asm: Assembly) -> list[tuple[str, Scene]]:
    """The pictures of the guide for a printed :class:`assembly.Assembly`:
    ``guide_loop.png`` (the assembled loop on its base, links named, joints numbered),
    ``guide_joint_<j>.png`` (joint j pulled apart: the screw or pin, link j, the thrust washer,
    link j+1, the nut or cap; axle and nut highlighted, each boss see-through so its bore and
    faces show) and ``guide_base.png`` (the rod and the plate)."""
    by_link = {i: [p for p in asm.parts if p.link == i and p.role == "link"] for i in range(6)}
    # pictures of the standing sculpture: everything in the world of its base
    world = np.eye(4) if asm.base is None else asm.base.world_from_home()
    meshes = {p.name: _tm(p.manifold).apply_transform(world) for p in asm.parts}
    pieces = [Piece(f"link {i}", meshes[by_link[i][0].name], _rgb(LINK_COLORS[i]))
              for i in range(6)]
    for p in asm.parts:
        if p.role == "base":
            pieces.append(Piece("base plate", meshes[p.name], _rgb(LINK_COLORS[6])))
    for h in asm.hardware:
        if h.role.endswith(" rod"):
            pieces.append(Piece("rod", _tm(h.solid).apply_transform(world), STEEL))
    rot = world[:3, :3]
    joints = [Joint(j.index, rot @ j.at(j.split) + world[:3, 3], rot @ j.w,
                    j.extent[0] - j.split, j.extent[1] - j.split, j.reach, piece=j.index)
              for j in asm.joints]
    out = [("guide_loop.png", loop_scene(pieces, joints))]
    for jt, pic in zip(asm.joints, joints, strict=True):
        out.append((f"guide_joint_{jt.index}.png",
                    exploded_scene(_groups(asm, jt, meshes, world), pic)))
    if asm.base is not None:
        b = asm.base
        plate = next(p for p in asm.parts if p.role == "base")
        rod = next(h for h in asm.hardware if h.role.endswith(" rod"))
        d = (b.bottom - b.top) / np.linalg.norm(b.bottom - b.top)
        length = float(np.linalg.norm(b.bottom - b.top))
        pull = 0.4 * length
        # the rod lifted out of the plate's socket, the plate where it stands: seen upright,
        # the arrow beside the rod points down into the socket
        groups = [([Piece("rod", _tm(rod.solid).apply_transform(world), PIN_COLOR,
                          focus=True)], -pull),
                  ([Piece("base plate: glue the rod in its socket", meshes[plate.name],
                          _rgb(LINK_COLORS[6]), focus=True)], 0.0)]
        foot = rot @ (b.bottom - 0.3 * length * d) + world[:3, 3]
        out.append(("guide_base.png", exploded_scene(groups, Joint(
            0, foot, rot @ d, -0.7 * length, 0.3 * length, 2.5 * b.rod.d_mm,
            name="the rod's axis"), upright=True)))
    return out


def _groups(asm: Assembly, jt, meshes: dict, world: np.ndarray
            ) -> list[tuple[list[Piece], float]]:
    """Joint ``jt`` pulled apart along its axis (module docstring), in the ``world``."""
    a, b = jt.index, (jt.index + 1) % 6
    pull = 1.2 * (jt.extent[1] - jt.extent[0]) / 2 + jt.reach
    hard = [h for h in asm.hardware if h.joint == jt.index or
            (jt.kind == "rod" and h.role.endswith(" rod"))]

    def _tm(solid) -> trimesh.Trimesh:
        return part_trimesh(solid).apply_transform(world)

    printed = [p for p in asm.parts if p.role in ("pin", "cap") and p.joint[0] == jt.index]
    near = [Piece(f"link {a}", meshes[f"link_{a}"], _rgb(LINK_COLORS[a]), alpha=0.45)]
    far = [Piece(f"link {b}", meshes[f"link_{b}"], _rgb(LINK_COLORS[b]), alpha=0.45)]
    groups: list[tuple[list[Piece], float]] = [(near, 0.0), (far, pull)]
    names = {"screw": "screw", "screw head": "", "lock nut": "lock nut",
             "thrust washer": "washer", "dowel": "dowel"}
    axle = [h for h in hard if h.role in ("screw", "screw head", "dowel")
            or h.role.endswith(" rod")]
    if axle:
        groups.insert(0, ([Piece(names.get(h.role, "rod"), _tm(h.solid), PIN_COLOR,
                                 focus=h.role != "screw head") for h in axle],
                          -pull if jt.kind != "rod" else 0.0))
    for h in hard:
        if h.role == "thrust washer":
            groups.append(([Piece("washer", _tm(h.solid), STEEL)], 0.5 * pull))
        if h.role == "washer":  # under the head (before link j) or the nut (after link j+1)
            head_side = float((h.capsule[0] - jt.origin) @ jt.w) < jt.split
            groups.append(([Piece("washer", _tm(h.solid), STEEL)],
                           -0.5 * pull if head_side else 1.5 * pull))
        if h.role == "lock nut":
            groups.append(([Piece(names[h.role], _tm(h.solid), NUT_COLOR, focus=True)],
                           2.0 * pull))
    for p in printed:  # a cap pulled out on the side it sits (a rod's or dowel's: either)
        beyond = float((p.capsules[0, 0] - jt.origin) @ jt.w) >= jt.length / 2
        off = -pull if p.role == "pin" else (2.0 if beyond else -2.0) * pull
        groups.append(([Piece(p.name.replace("_", " "), meshes[p.name], PIN_COLOR,
                              focus=True)], off))
    return groups


def glue_scenes(asm: Assembly, parts: list[dict], meshes: dict[str, trimesh.Trimesh]
                ) -> list[tuple[str, Scene]]:
    """``guide_glue_<link>_<k>.png``: each dowel of a link printed in pieces (report
    ``parts``' ``printed_as``, :mod:`split`; ``meshes`` the pieces, home frame) pulled apart
    along the bar: the arm, the steel pin, the end piece."""
    world = np.eye(4) if asm.base is None else asm.base.world_from_home()
    rot, out = world[:3, :3], []
    for part in parts:
        spec = part.get("printed_as")
        for k, dw in enumerate(spec["dowels"] if spec else []):
            arm, end = dw["pieces"]
            axis = rot @ np.asarray(dw["axis"], float)
            at = rot @ np.asarray(dw["origin_mm"], float) + world[:3, 3]
            depth = max(dw["depth_mm"])
            pin = trimesh.creation.cylinder(radius=float(dw["pin"].split()[0]) / 2,
                                            segment=[at - depth * axis, at + depth * axis])
            color = _rgb(LINK_COLORS[part["link"]])
            groups = [([Piece(arm.replace("_", " "), meshes[arm].copy().apply_transform(world),
                              color, focus=True)], -3.0 * depth),
                      ([Piece("dowel pin", pin, PIN_COLOR, focus=True)], -1.5 * depth),
                      ([Piece(end.replace("_", " "), meshes[end].copy().apply_transform(world),
                              color, alpha=0.6)], 0.0)]
            out.append((f"guide_glue_{part['link']}_{k + 1}.png", exploded_scene(groups, Joint(
                0, at, axis, -depth, depth, 2.0 * depth, name="the bar's axis"))))
    return out


def assembly_pictures(asm: Assembly, parts: list[dict] | None = None,
                      meshes: dict[str, trimesh.Trimesh] | None = None
                      ) -> list[tuple[str, bytes]]:
    """:func:`assembly_scenes` (and with the report's ``parts`` and the export's ``meshes``
    :func:`glue_scenes`) rendered: ``(file name, PNG bytes)``, two at a time (the renderer's
    numpy and Pillow work runs outside the interpreter lock)."""
    scenes = assembly_scenes(asm) + (glue_scenes(asm, parts, meshes) if parts else [])
    with ThreadPoolExecutor(max_workers=2) as pool:
        pngs = list(pool.map(lambda ns: ns[1].png(), scenes))
    return [(name, png) for (name, _), png in zip(scenes, pngs, strict=True)]
