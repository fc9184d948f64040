"""One description of a printed part's solid, evaluated by two back-ends.

A part is a small tree of frozen nodes (mm, home frame): :class:`Prism` (manifold3d's
cylinder: a frustum of ``sides`` sides, or a cone's frustum, placed by a ``(3, 4)`` frame),
:class:`Union`, :class:`Cut`, :class:`Hull`, :class:`Trim` (a half-space), :class:`Move`,
:class:`Largest` (the largest piece) and :class:`Mesh` (a solid known only as a mesh: an
end-effector, a carved body). :func:`manifold` evaluates it with manifold3d (the meshes the
export writes and the verification checks); :mod:`step` evaluates the same tree with OCP
into an exact solid (a prism of more than :data:`ROUND_SIDES` sides is a true cylinder or
cone). The parts (:mod:`parts`, :mod:`base`) build only trees, so the two never drift.
"""

from __future__ import annotations

from dataclasses import dataclass

import manifold3d as m3d
import numpy as np

#: A prism of more sides than this stands for a round solid (a cylinder, a cone).
ROUND_SIDES = 12


@dataclass(frozen=True, eq=False)
class Prism:
    """manifold3d's ``cylinder(height, r0, r1, sides)`` (z from 0 to ``height``, a corner
    on +x) mapped by the affine ``frame`` ``(3, 4)``."""

    frame: np.ndarray
    height: float
    r0: float
    r1: float
    sides: int


@dataclass(frozen=True, eq=False)
class Union:
    """The union of ``items`` (one batch boolean)."""

    items: tuple


@dataclass(frozen=True, eq=False)
class Cut:
    """``base`` less each of ``tools`` in turn."""

    base: object
    tools: tuple


@dataclass(frozen=True, eq=False)
class Hull:
    """The convex hull of ``items``."""

    items: tuple


@dataclass(frozen=True, eq=False)
class Trim:
    """What of ``child`` lies where ``normal . x >= offset`` (mm)."""

    child: object
    normal: tuple
    offset: float


@dataclass(frozen=True, eq=False)
class Move:
    """``child`` mapped by the affine ``frame`` ``(3, 4)`` (a rigid motion)."""

    child: object
    frame: np.ndarray


@dataclass(frozen=True, eq=False)
class Largest:
    """The largest piece (by volume) of ``child``."""

    child: object


@dataclass(frozen=True, eq=False)
class Mesh:
    """A solid known only as a triangle mesh (mm, home frame)."""

    solid: m3d.Manifold


Node = Prism | Union | Cut | Hull | Trim | Move | Largest | Mesh


def frame_to(p0: np.ndarray, p1: np.ndarray, roll: np.ndarray | None = None) -> np.ndarray:
    """``(3, 4)`` affine map taking the z axis segment ``[0, |p1 - p0|]`` onto ``[p0, p1]``;
    its x axis along ``roll`` (projected off the segment) when given."""
    d = np.asarray(p1, float) - p0
    z = d / np.linalg.norm(d)
    ref = np.asarray(roll, float) if roll is not None else \
        np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = ref - (ref @ z) * z
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(z, [1.0, 0, 0] if abs(z[0]) < 0.9 else [0, 1.0, 0])
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z, p0])


def shift(x: float, y: float, z: float) -> np.ndarray:
    """``(3, 4)``: the translation by ``(x, y, z)`` (mm)."""
    return np.column_stack([np.eye(3), [x, y, z]])


def prism(p0: np.ndarray, p1: np.ndarray, radius: float, sides: int,
          roll: np.ndarray | None = None) -> Prism:
    """Prism of ``sides`` sides and corner ``radius`` with flat ends at ``p0``, ``p1`` (mm);
    with ``roll`` a corner points along it."""
    h = float(np.linalg.norm(np.asarray(p1, float) - p0))
    return Prism(frame_to(p0, p1, roll), h, float(radius), float(radius), int(sides))


def largest(man: m3d.Manifold) -> tuple[m3d.Manifold, np.ndarray]:
    """The largest piece of ``man`` and the volumes of all its pieces."""
    pieces = man.decompose()
    if len(pieces) <= 1:
        return man, np.array([man.volume()])
    vols = np.array([p.volume() for p in pieces])
    return pieces[int(np.argmax(vols))], vols


def faceted(node: Node) -> bool:
    """True where the tree holds a :class:`Mesh` (its exact solid is then a faceted one)."""
    if isinstance(node, Mesh):
        return True
    if isinstance(node, Prism):
        return False
    kids = node.items if isinstance(node, (Union, Hull)) else \
        (node.base, *node.tools) if isinstance(node, Cut) else (node.child,)
    return any(faceted(k) for k in kids)


def manifold(node: Node) -> m3d.Manifold:
    """The tree evaluated with manifold3d (mm, home frame)."""
    if isinstance(node, Prism):
        return m3d.Manifold.cylinder(node.height, node.r0, node.r1, node.sides).transform(
            node.frame)
    if isinstance(node, Union):
        return m3d.Manifold.batch_boolean([manifold(k) for k in node.items], m3d.OpType.Add)
    if isinstance(node, Cut):
        out = manifold(node.base)
        for t in node.tools:
            out = out - manifold(t)
        return out
    if isinstance(node, Hull):
        return m3d.Manifold.batch_hull([manifold(k) for k in node.items])
    if isinstance(node, Trim):
        return manifold(node.child).trim_by_plane(tuple(node.normal), node.offset)
    if isinstance(node, Move):
        return manifold(node.child).transform(node.frame)
    if isinstance(node, Largest):
        return largest(manifold(node.child))[0]
    return node.solid
