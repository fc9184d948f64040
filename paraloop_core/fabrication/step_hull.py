"""The convex hull of prisms as an OpenCascade solid with true surfaces (a fillet web).

The hull of a boss (a cylinder) and a bar's stub (a hexagonal prism) is bounded by planes,
part of the boss's cylinder and of its end discs, and oblique cones from a stub corner to an
arc of an end circle. :func:`exact_hull` finds which from qhull's hull of the corners and of
each end circle sampled at :data:`SAMPLES` points (its triangles grouped by what they touch:
a cone fan, a strip of the cylinder, a disc, a plane), then builds each group's face with
its true surface: planes and discs bounded by lines and circular arcs, the cylinder's
strip a cylindrical face, each cone a ruled face from its apex to its circular arc. Where a
patch meets the next is found to a sample's angle (1 deg: the surfaces are exact, their
seams within ``r (1 - cos 1 deg)`` of the true hull's). Returns None where the groups do not
close into one valid solid (:mod:`step` then takes the polyhedral hull).
"""

from __future__ import annotations

import numpy as np
from OCP.BRep import BRep_Tool
from OCP.BRepBuilderAPI import (
    BRepBuilderAPI_MakeEdge,
    BRepBuilderAPI_MakeFace,
    BRepBuilderAPI_MakeSolid,
    BRepBuilderAPI_MakeVertex,
    BRepBuilderAPI_MakeWire,
    BRepBuilderAPI_Sewing,
)
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.BRepOffsetAPI import BRepOffsetAPI_ThruSections
from OCP.gp import gp_Ax2, gp_Ax3, gp_Circ, gp_Cylinder, gp_Dir, gp_Pnt
from OCP.GProp import GProp_GProps
from OCP.TopAbs import TopAbs_FACE, TopAbs_SHELL
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Shape
from scipy.spatial import ConvexHull

from paraloop_core.fabrication import csg

#: Points sampled on each end circle of a round prism.
SAMPLES = 360
#: Largest share by which the solid's volume may exceed the sampled hull's.
VOLUME_SLACK = 1e-3


def pnt(p: np.ndarray) -> gp_Pnt:
    """A point ``(3,)`` (mm) for OpenCascade."""
    return gp_Pnt(*map(float, p))


def shapes_of(s: TopoDS_Shape, kind) -> list[TopoDS_Shape]:
    """The sub-shapes of ``s`` of type ``kind`` (``TopAbs_SOLID``, ...)."""
    out, ex = [], TopExp_Explorer(s, kind)
    while ex.More():
        out.append(ex.Current())
        ex.Next()
    return out


def volume(s: TopoDS_Shape) -> float:
    """The volume (mm^3) of ``s`` (negative for a solid turned inside out)."""
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(s, props)
    return props.Mass()


def exact_hull(items: tuple) -> TopoDS_Shape | None:
    """The hull of the :class:`csg.Prism` ``items`` (mm; module docstring), or None."""
    pts, circ, circles = [], [], []  # circ: each point's circle (-1: a corner)
    for n in items:
        if not isinstance(n, csg.Prism) or (n.sides > csg.ROUND_SIDES and n.r0 != n.r1):
            return None
        m = SAMPLES if n.sides > csg.ROUND_SIDES else n.sides
        a = 2 * np.pi * np.arange(m) / m
        for z, r in ((0.0, n.r0), (n.height, n.r1)):
            local = np.column_stack([r * np.cos(a), r * np.sin(a), np.full(m, z)])
            pts.append(local @ n.frame[:, :3].T + n.frame[:, 3])
            if n.sides > csg.ROUND_SIDES:
                circles.append((n, z))
                circ += [len(circles) - 1] * m
            else:
                circ += [-1] * m
    p, circ = np.concatenate(pts), np.array(circ)
    k = np.concatenate([np.arange(len(x)) % SAMPLES for x in pts])
    hull = ConvexHull(p)
    tri = hull.simplices.copy()
    t = p[tri]
    flip = np.einsum("ij,ij->i", np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]),
                     hull.equations[:, :3]) < 0  # qhull's triangles face either way
    tri[flip] = tri[flip][:, [0, 2, 1]]
    groups: dict[tuple, list[tuple[int, int, int]]] = {}
    cl, kl = circ.tolist(), k.tolist()
    for a_b_c, eq in zip(tri.tolist(), hull.equations, strict=True):
        groups.setdefault(_kind(cl, kl, circles, tuple(a_b_c), eq), []).append(tuple(a_b_c))
    faces = []
    for key, tris in ((key, part) for key, all_tris in groups.items()
                      for part in _components(all_tris)):
        loops = _loops(tris) or [None]
        if key[0] == "side" and all(_full(x, cl) for x in loops):  # a whole band
            faces.append(_band(circles[key[1]][0], 0.0, 2 * np.pi))
            continue
        for loop in loops:
            face = _face(key, loop, p, cl, kl, circles)
            if face is None:
                return None
            faces.append(face)
    return _solid(faces, hull.volume)


def _full(loop: list[int] | None, circ: list) -> bool:
    """True where ``loop`` is one whole end circle."""
    return loop is not None and len(loop) == SAMPLES and circ[loop[0]] >= 0 and \
        all(circ[i] == circ[loop[0]] for i in loop)


def _band(n: csg.Prism, u0: float, u1: float):
    """The face of the round prism ``n``'s cylinder between the angles ``u0`` and ``u1``."""
    f = n.frame
    cyl = gp_Cylinder(gp_Ax3(pnt(f[:, 3]), gp_Dir(*f[:, 2]), gp_Dir(*f[:, 0])), float(n.r0))
    return BRepBuilderAPI_MakeFace(cyl, u0, u1, 0.0, float(n.height)).Face()


def _adjacent(k0: int, k1: int) -> int:
    """+1 / -1 when sample ``k1`` follows / precedes ``k0`` on a circle, else 0."""
    d = (k1 - k0) % SAMPLES
    return 1 if d == 1 else -1 if d == SAMPLES - 1 else 0


def _kind(circ: list, k: list, circles: list, tri: tuple, eq: np.ndarray) -> tuple:
    """What a hull triangle lies on: ``("disc", c)``, ``("fan", c, corner)`` (a cone),
    ``("side", c)`` (the cylinder of circles c, c+1), ``("plane", eq)``."""
    for i in range(3):
        a, b, o = tri[i], tri[(i + 1) % 3], tri[(i + 2) % 3]
        c = circ[a]
        if c < 0 or circ[b] != c or not _adjacent(k[a], k[b]):
            continue
        w = circles[c][0].frame[:, 2]
        if circ[o] == c or abs(eq[:3] @ w) > 1 - 1e-12:
            return ("disc", c)
        if circ[o] < 0:
            return ("fan", c, o)
        if circles[circ[o]][0] is circles[c][0] and k[o] in (k[a], k[b]):
            return ("side", c - c % 2)
    return ("plane", eq.tobytes())


def _components(tris: list) -> list[list]:
    """The triangles in groups joined across edges (two fans of one apex touch only there)."""
    parent = list(range(len(tris)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    owner: dict = {}
    for i, t in enumerate(tris):
        for e in range(3):
            edge = frozenset((t[e], t[(e + 1) % 3]))
            if edge in owner:
                parent[root(i)] = root(owner[edge])
            owner[edge] = i
    parts: dict = {}
    for i, t in enumerate(tris):
        parts.setdefault(root(i), []).append(t)
    return list(parts.values())


def _loops(tris: list) -> list[list[int]] | None:
    """The closed boundaries of a group of oriented triangles (a cylinder's strips may be
    several), or None where a vertex starts two."""
    edges = {(t[i], t[(i + 1) % 3]) for t in tris for i in range(3)}
    nxt = {}
    for a, b in edges:
        if (b, a) not in edges:
            if a in nxt:
                return None
            nxt[a] = b
    loops, left = [], set(nxt)
    while left:
        loop = [left.pop()]
        while nxt[loop[-1]] != loop[0]:
            loop.append(nxt[loop[-1]])
            if loop[-1] not in left:
                return None
            left.remove(loop[-1])
        loops.append(loop)
    return loops or None


def _edges(loop: list[int], p, circ, k, circles) -> list[tuple]:
    """The loop as runs: ``("arc", c, k_first, steps (signed), i_first, i_last)`` along a
    circle, ``("line", i, j)``."""
    def step_of(a: int, b: int) -> int:
        return _adjacent(k[a], k[b]) if circ[a] >= 0 and circ[a] == circ[b] else 0

    # start where no arc runs in, so that no arc is split at the loop's start
    first = next((i for i in range(len(loop)) if not step_of(loop[i - 1], loop[i])), 0)
    loop = loop[first:] + loop[:first]
    runs = []
    for a, b in zip(loop, loop[1:] + loop[:1], strict=True):
        step = step_of(a, b)
        if step and runs and runs[-1][0] == "arc" and runs[-1][1] == circ[a] and \
                np.sign(runs[-1][3]) == step:
            r = runs[-1]
            runs[-1] = ("arc", r[1], r[2], r[3] + step, r[4], b)
        elif step:
            runs.append(("arc", int(circ[a]), int(k[a]), step, a, b))
        else:
            runs.append(("line", a, b))
    return runs


def _circle(circles: list, c: int) -> gp_Circ:
    n, z = circles[c]
    f = n.frame
    return gp_Circ(gp_Ax2(pnt(f[:, 3] + z * f[:, 2]), gp_Dir(*f[:, 2]), gp_Dir(*f[:, 0])),
                   float(n.r0))


def _edge(run: tuple, p: np.ndarray, circles: list):
    if run[0] == "line":
        return BRepBuilderAPI_MakeEdge(pnt(p[run[1]]), pnt(p[run[2]])).Edge()
    _, c, _, steps, i, j = run
    if abs(steps) == SAMPLES:  # a whole circle
        e = BRepBuilderAPI_MakeEdge(_circle(circles, c)).Edge()
        return e if steps > 0 else TopoDS.Edge(e.Reversed())
    if steps > 0:
        return BRepBuilderAPI_MakeEdge(_circle(circles, c), pnt(p[i]), pnt(p[j])).Edge()
    e = BRepBuilderAPI_MakeEdge(_circle(circles, c), pnt(p[j]), pnt(p[i])).Edge()
    return TopoDS.Edge(e.Reversed())


def _wire(runs: list, p: np.ndarray, circles: list):
    wire = BRepBuilderAPI_MakeWire()
    for r in runs:
        e = _edge(r, p, circles)
        if e is None:
            return None
        wire.Add(e)
    return wire.Wire() if wire.IsDone() else None


def _face(key: tuple, loop: list[int] | None, p, circ, k, circles):
    """The group's face with its true surface (module docstring), or None."""
    if loop is None:
        return None
    runs = _edges(loop, p, circ, k, circles)
    arcs = [r for r in runs if r[0] == "arc"]
    if key[0] in ("disc", "plane"):
        wire = _wire(runs, p, circles)
        return None if wire is None else BRepBuilderAPI_MakeFace(wire, True).Face()
    if key[0] == "fan":
        if len(arcs) != 1 or len(runs) not in (1, 3):  # 1: the apex sees the whole circle
            return None
        arc = _wire(arcs, p, circles)
        sections = BRepOffsetAPI_ThruSections(False, True)
        sections.AddVertex(BRepBuilderAPI_MakeVertex(pnt(p[key[2]])).Vertex())
        sections.AddWire(arc)
        sections.Build()
        faces = shapes_of(sections.Shape(), TopAbs_FACE) if sections.IsDone() else []
        return faces[0] if len(faces) == 1 else None
    # the cylinder's strip: between the angles of its arc on the first end circle
    first = [r for r in arcs if r[1] == key[1]]
    if len(first) != 1 or len(arcs) != 2 or len(runs) != 4:
        return None
    _, c, k0, steps, _, _ = first[0]
    u0 = 2 * np.pi * (k0 if steps > 0 else k0 + steps) / SAMPLES
    return _band(circles[c][0], u0, u0 + 2 * np.pi * abs(steps) / SAMPLES)


def _solid(faces: list, sampled_volume: float) -> TopoDS_Shape | None:
    """The faces sewn into one closed, valid solid whose volume is the sampled hull's (to
    :data:`VOLUME_SLACK`), or None."""
    sew = BRepBuilderAPI_Sewing(1e-5)
    for f in faces:
        sew.Add(f)
    sew.Perform()
    shells = shapes_of(sew.SewedShape(), TopAbs_SHELL)
    if len(shells) != 1 or not BRep_Tool.IsClosed_s(shells[0]):
        return None
    solid = BRepBuilderAPI_MakeSolid(TopoDS.Shell(shells[0])).Solid()
    v = volume(solid)
    if v < 0:
        solid.Reverse()
    ok = BRepCheck_Analyzer(solid).IsValid() and \
        0.0 <= abs(v) / sampled_volume - 1.0 <= VOLUME_SLACK
    return solid if ok else None
