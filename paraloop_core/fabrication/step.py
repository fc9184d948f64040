"""The parts as exact solids (OpenCascade, OCP), written as STEP (mm, home pose).

:func:`shape` evaluates a part's :mod:`csg` tree, the one the meshes come from, with
OpenCascade: a prism of more than :data:`csg.ROUND_SIDES` sides is a true cylinder (a cone
for the plate's countersinks), a hexagonal bar or nut an exact hexagonal prism, the cuts and
unions exact booleans, the print flat a planar cut, a fillet (:class:`csg.Hull` of a boss and
the bar's first millimetres) its true planes, cylinder and oblique cones
(:mod:`step_hull`). Where that hull does not close, the fillet is the polyhedral hull of its
children's corners and of their round ends sampled at :data:`HULL_SAMPLES` points,
:data:`HULL_INSET` inside the circle so that the exact boss covers its round side (the part
is then ``"exact, polyhedral fillet"``). A part whose tree holds a :class:`csg.Mesh` (an
end-effector, a carved body) is written as its mesh's faceted solid (:func:`mesh_solid`,
``"faceted"``). :func:`part_solid` says which: the report's ``step``.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
from OCP.BinTools import BinTools
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Builder
from OCP.BRepAlgoAPI import BRepAlgoAPI_Common, BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepBuilderAPI import (
    BRepBuilderAPI_MakeEdge,
    BRepBuilderAPI_MakeFace,
    BRepBuilderAPI_MakePolygon,
    BRepBuilderAPI_MakeSolid,
    BRepBuilderAPI_MakeVertex,
    BRepBuilderAPI_MakeWire,
    BRepBuilderAPI_Sewing,
    BRepBuilderAPI_Transform,
)
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepPrimAPI import (
    BRepPrimAPI_MakeBox,
    BRepPrimAPI_MakeCone,
    BRepPrimAPI_MakeCylinder,
    BRepPrimAPI_MakePrism,
)
from OCP.collections import List_TopoDS_Shape
from OCP.gp import gp, gp_Ax2, gp_Dir, gp_Pln, gp_Pnt, gp_Trsf, gp_Vec
from OCP.IFSelect import IFSelect_RetDone
from OCP.Message import Message, Message_Gravity
from OCP.Quantity import Quantity_Color, Quantity_TOC_RGB
from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
from OCP.Standard import Standard_Failure
from OCP.STEPCAFControl import STEPCAFControl_Writer
from OCP.STEPControl import STEPControl_AsIs
from OCP.TCollection import TCollection_ExtendedString
from OCP.TDataStd import TDataStd_Name
from OCP.TDocStd import TDocStd_Document
from OCP.TopAbs import TopAbs_SHELL, TopAbs_SOLID
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Shape, TopoDS_Shell, TopoDS_Solid
from OCP.XCAFDoc import XCAFDoc_ColorGen, XCAFDoc_DocumentTool
from scipy.spatial import ConvexHull

from paraloop_core.fabrication import csg, step_hull
from paraloop_core.fabrication.assembly import Assembly

#: Points sampled on each round end of a hull's child (a fillet's boss).
HULL_SAMPLES = 24
#: Share of the radius the sampled ends of a hull lie inside their circle.
HULL_INSET = 1e-3
#: Largest relative difference of an exact solid's volume from its mesh's (the 48-gons of
#: the mesh lie inside the true circles: 0.3 % at most on a round part).
VOLUME_TOL = 0.01
#: Gap (mm) within which OpenCascade's booleans treat two boundaries as one.
FUZZ_MM = 1e-5


def _trsf(frame: np.ndarray) -> gp_Trsf:
    m = np.asarray(frame, float)
    t = gp_Trsf()
    t.SetValues(*m[0], *m[1], *m[2])
    return t


def _moved(s: TopoDS_Shape, frame: np.ndarray) -> TopoDS_Shape:
    return BRepBuilderAPI_Transform(s, _trsf(frame), True).Shape()


def _polygon(points: np.ndarray) -> TopoDS_Shape:
    """The planar face bounded by the closed polygon ``points`` ``(n, 3)``."""
    poly = BRepBuilderAPI_MakePolygon()
    for p in points:
        poly.Add(step_hull.pnt(p))
    poly.Close()
    return BRepBuilderAPI_MakeFace(poly.Wire(), True).Face()


def _corners(sides: int, z: float, r: float) -> np.ndarray:
    """Corners ``(sides, 3)`` of manifold3d's polygon of corner radius ``r`` at height ``z``
    (its local frame: a corner on +x)."""
    a = 2 * np.pi * np.arange(sides) / sides
    return np.column_stack([r * np.cos(a), r * np.sin(a), np.full(sides, z)])


def _prism(n: csg.Prism) -> TopoDS_Shape:
    if n.sides > csg.ROUND_SIDES:
        ax = gp_Ax2(gp_Pnt(0, 0, 0), gp.DZ_s(), gp.DX_s())
        s = BRepPrimAPI_MakeCylinder(ax, n.r0, n.height).Shape() if n.r0 == n.r1 else \
            BRepPrimAPI_MakeCone(ax, n.r0, n.r1, n.height).Shape()
    elif n.r0 == n.r1:
        s = BRepPrimAPI_MakePrism(_polygon(_corners(n.sides, 0.0, n.r0)),
                                  gp_Vec(0, 0, n.height)).Shape()
    else:
        raise ValueError("a polygonal frustum has no exact solid here")
    return _moved(s, n.frame)


def _boolean(op, args: list[TopoDS_Shape], tools: list[TopoDS_Shape]) -> TopoDS_Shape:
    a, t = List_TopoDS_Shape(), List_TopoDS_Shape()
    for s in args:
        a.Append(s)
    for s in tools:
        t.Append(s)
    b = op()
    b.SetArguments(a)
    b.SetTools(t)
    b.SetFuzzyValue(FUZZ_MM)
    b.Build()
    if not b.IsDone():
        raise RuntimeError(f"OpenCascade {op.__name__} failed")
    return b.Shape()


def hull_points(n: csg.Node) -> np.ndarray:
    """``(m, 3)`` points (mm) whose hull stands for ``n``'s (module docstring)."""
    if isinstance(n, csg.Hull):
        return np.concatenate([hull_points(k) for k in n.items])
    if not isinstance(n, csg.Prism):
        raise ValueError(f"no hull of a {type(n).__name__} here")
    m = HULL_SAMPLES if n.sides > csg.ROUND_SIDES else n.sides
    scale = 1.0 - HULL_INSET if n.sides > csg.ROUND_SIDES else 1.0
    local = np.concatenate([_corners(m, 0.0, n.r0 * scale), _corners(m, n.height, n.r1 * scale)])
    return local @ n.frame[:, :3].T + n.frame[:, 3]


def hull_faces(points: np.ndarray) -> list[np.ndarray]:
    """The faces of the convex hull of ``points`` ``(m, 3)`` as polygons ``(n, 3)``: qhull's
    triangles of one facet (the same plane, to the bit) merged, corners in turn about it."""
    hull = ConvexHull(points)
    facets: dict[bytes, list[int]] = {}
    for tri, eq in zip(hull.simplices, hull.equations, strict=True):
        facets.setdefault(eq.tobytes(), []).extend(tri)
    out = []
    for eq, idx in facets.items():
        v = points[np.unique(idx)]
        normal = np.frombuffer(eq)[:3]
        c = v.mean(axis=0)
        a = csg.frame_to(c, c + normal)[:, :2]  # two directions in the facet's plane
        out.append(v[np.argsort(np.arctan2((v - c) @ a[:, 1], (v - c) @ a[:, 0]))])
    return out


def _sewn(polygons: list[np.ndarray]) -> TopoDS_Shape:
    """The closed solid bounded by the planar ``polygons`` (each ``(n, 3)``, mm)."""
    sew = BRepBuilderAPI_Sewing(1e-6)
    for poly in polygons:
        sew.Add(_polygon(poly))
    sew.Perform()
    shell = step_hull.shapes_of(sew.SewedShape(), TopAbs_SHELL)[0]
    solid = BRepBuilderAPI_MakeSolid(TopoDS.Shell(shell)).Solid()
    if step_hull.volume(solid) < 0:  # the shell faced inwards
        solid.Reverse()
    return solid


def mesh_solid(man) -> TopoDS_Shape:
    """A manifold3d solid's triangles as a faceted OpenCascade solid (mm): its vertices and
    edges shared as in the mesh (no sewing), each triangle a planar face."""
    mesh = man.to_mesh()
    v = np.asarray(mesh.vert_properties[:, :3], float)
    tris = np.asarray(mesh.tri_verts, np.int64)
    normals = np.cross(v[tris[:, 1]] - v[tris[:, 0]], v[tris[:, 2]] - v[tris[:, 0]])
    area = np.linalg.norm(normals, axis=1) > 0
    if not area.all():  # a triangle without area: sew the others
        return _sewn(list(v[tris[area]]))
    vertices = [BRepBuilderAPI_MakeVertex(step_hull.pnt(x)).Vertex() for x in v]
    edges: dict[tuple[int, int], TopoDS_Shape] = {}
    builder, shell = BRep_Builder(), TopoDS_Shell()
    builder.MakeShell(shell)
    for t, n in zip(tris.tolist(), normals, strict=True):
        wire = BRepBuilderAPI_MakeWire()
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):  # each edge made once,
            key = (min(a, b), max(a, b))                           # shared by its two faces
            if key not in edges:
                edges[key] = BRepBuilderAPI_MakeEdge(vertices[key[0]], vertices[key[1]]).Edge()
            wire.Add(edges[key] if a < b else TopoDS.Edge(edges[key].Reversed()))
        plane = gp_Pln(step_hull.pnt(v[t[0]]), gp_Dir(*map(float, n)))
        builder.Add(shell, BRepBuilderAPI_MakeFace(plane, wire.Wire(), True).Face())
    shell.Closed(True)
    solid = TopoDS_Solid()
    builder.MakeSolid(solid)
    builder.Add(solid, shell)
    return solid


def _halfspace(s: TopoDS_Shape, normal: np.ndarray, offset: float) -> TopoDS_Shape:
    """A box holding all of ``s`` where ``normal . x >= offset``."""
    box = Bnd_Box()
    BRepBndLib.Add_s(s, box)
    lo, hi = np.array(box.CornerMin().Coord()), np.array(box.CornerMax().Coord())
    size = 2.0 * float(np.linalg.norm(hi - lo)) + 10.0
    centre = (lo + hi) / 2
    origin = centre - (centre @ normal - offset) * normal
    frame = csg.frame_to(origin, origin + normal)
    local = BRepPrimAPI_MakeBox(gp_Pnt(-size, -size, 0.0), 2 * size, 2 * size, size).Shape()
    return _moved(local, frame)


def solids_of(s: TopoDS_Shape) -> list[TopoDS_Shape]:
    """The solids in ``s``."""
    return step_hull.shapes_of(s, TopAbs_SOLID)


def _flat(n: csg.Union) -> list[csg.Node]:
    return [x for k in n.items for x in (_flat(k) if isinstance(k, csg.Union) else [k])]


def shape(n: csg.Node, fallbacks: list | None = None) -> TopoDS_Shape:
    """The tree ``n`` as an OpenCascade shape (mm, home frame; module docstring); each hull
    built polyhedral is appended to ``fallbacks``."""
    if isinstance(n, csg.Prism):
        return _prism(n)
    if isinstance(n, csg.Union):  # nested unions in one boolean
        kids = [shape(k, fallbacks) for k in _flat(n)]
        return kids[0] if len(kids) == 1 else _boolean(BRepAlgoAPI_Fuse, kids[:1], kids[1:])
    if isinstance(n, csg.Cut):
        return _boolean(BRepAlgoAPI_Cut, [shape(n.base, fallbacks)],
                        [shape(t, fallbacks) for t in n.tools])
    if isinstance(n, csg.Hull):
        exact = step_hull.exact_hull(n.items)
        if exact is not None:
            return exact
        if fallbacks is not None:
            fallbacks.append(n)
        return _sewn(hull_faces(hull_points(n)))
    if isinstance(n, csg.Trim):
        child = shape(n.child, fallbacks)
        normal = np.asarray(n.normal, float) / np.linalg.norm(n.normal)
        off = n.offset / float(np.linalg.norm(n.normal))
        return _boolean(BRepAlgoAPI_Common, [child], [_halfspace(child, normal, off)])
    if isinstance(n, csg.Move):
        return _moved(shape(n.child, fallbacks), n.frame)
    if isinstance(n, csg.Largest):
        return max(solids_of(shape(n.child, fallbacks)), key=step_hull.volume)
    raise ValueError("a mesh has no exact solid: write the part faceted (mesh_solid)")


def tree_solid(tree: csg.Node, volume_mm3: float) -> tuple[TopoDS_Shape, str] | None:
    """The exact solid of ``tree`` and its kind (``"exact"``, ``"exact, polyhedral
    fillet"``), or None where OpenCascade refuses a boolean or the solid is invalid or off
    the mesh's ``volume_mm3`` by more than :data:`VOLUME_TOL` (module docstring)."""
    fallbacks: list = []
    try:
        s = solids_of(shape(tree, fallbacks))
    except (RuntimeError, ValueError, Standard_Failure):
        return None
    if len(s) != 1:
        return None
    unify = ShapeUpgrade_UnifySameDomain(s[0], True, True, True)
    unify.Build()
    solid = unify.Shape()
    if BRepCheck_Analyzer(solid).IsValid() and \
            abs(step_hull.volume(solid) / volume_mm3 - 1.0) <= VOLUME_TOL:
        return solid, "exact, polyhedral fillet" if fallbacks else "exact"
    return None


def exact_parts(parts) -> list:
    """The parts (or hardware) of ``parts`` whose tree may have an exact solid."""
    return [p for p in parts if _has_exact_tree(p)]


def _has_exact_tree(part) -> bool:
    return part.csg is not None and not csg.faceted(part.csg)


def part_solid(part, made: dict[int, tuple | None] | None = None
               ) -> tuple[TopoDS_Shape, str]:
    """A :class:`parts.Part` (or :class:`assembly.Hardware`) as one OpenCascade solid and
    its kind: :func:`tree_solid`'s (``made``: its answers already made, by the part's
    ``id``), else (or for a mesh) the mesh's faceted solid (``"faceted"``)."""
    man = part.manifold if hasattr(part, "manifold") else part.solid
    if _has_exact_tree(part):
        exact = made[id(part)] if made is not None and id(part) in made else \
            tree_solid(part.csg, man.volume())
        if exact is not None:
            return exact
    return mesh_solid(man), "faceted"


def solid_bytes(solid: TopoDS_Shape) -> bytes:
    """``solid`` in OpenCascade's binary BRep format (every number exact)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "solid.brep")
        BinTools.Write_s(solid, path)
        with open(path, "rb") as f:
            return f.read()


def solid_from_bytes(data: bytes) -> TopoDS_Shape:
    """The solid :func:`solid_bytes` wrote."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "solid.brep")
        with open(path, "wb") as f:
            f.write(data)
        solid = TopoDS_Shape()
        BinTools.Read_s(solid, path)
        return solid


def step_bytes(items: list[tuple[str, TopoDS_Shape, np.ndarray]], label: str) -> bytes:
    """A STEP file (AP214, mm) of one assembly ``label`` holding each ``(name, solid, rgb)``
    as a named, coloured part in place."""
    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colors = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    top = shapes.NewShape()
    TDataStd_Name.Set_s(top, TCollection_ExtendedString(label))
    for name, solid, rgb in items:
        part = shapes.AddShape(solid, False)
        TDataStd_Name.Set_s(part, TCollection_ExtendedString(name))
        r, g, b = (float(c) / 255 for c in rgb)
        colors.SetColor(part, Quantity_Color(r, g, b, Quantity_TOC_RGB), XCAFDoc_ColorGen)
        shapes.AddComponent(top, part, TopLoc_Location())
    shapes.UpdateAssemblies()
    printers = Message.DefaultMessenger_s().Printers()
    for k in range(1, printers.Length() + 1):  # no "Write Done" on stdout
        printers.Value(k).SetTraceLevel(Message_Gravity.Message_Fail)
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    writer.SetColorMode(True)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "out.step")
        if not writer.Transfer(doc, STEPControl_AsIs) or \
                writer.Write(path) != IFSelect_RetDone:
            raise RuntimeError("the STEP writer failed")
        with open(path, "rb") as f:
            return f.read()


def step_files(asm: Assembly, colors: dict[str, np.ndarray], steel: np.ndarray,
               made: dict[int, tuple | None] | None = None
               ) -> tuple[list[tuple[str, bytes]], dict[str, str]]:
    """``parts.step`` (each printed part one named solid, mm, the assembled home pose: as the
    STL files) and ``assembly.step`` (those and the metal hardware, in ``colors`` (RGB by
    part name) and ``steel``), and each part's kind of solid (:func:`part_solid`, ``made``
    its exact solids made before)."""
    printed, kinds = [], {}
    for p in asm.parts:
        s, kinds[p.name] = part_solid(p, made)
        printed.append((p.name, s, colors[p.name]))
    hardware = [(f"{h.role.replace(' ', '_')}_{h.joint}_{k}", part_solid(h, made)[0], steel)
                for k, h in enumerate(asm.hardware)]
    return ([("parts.step", step_bytes(printed, "paraloop parts")),
             ("assembly.step", step_bytes(printed + hardware, "paraloop assembly"))], kinds)
