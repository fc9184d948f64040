"""MJCF (MuJoCo's XML) of a :class:`physics_model.PhysicsModel`: the model :mod:`physics`
simulates, and the file robotics users get beside the parts.

**Units**: the model is in mm; MuJoCo runs in metres, kg, s (``physics_model.M_PER_MM``).

**Tree.** Every MuJoCo body's frame is the world frame at home (identity at ``qpos0``), so
mesh vertices, centres of mass, hinge points and anchors are written in home coordinates. The
base group (base bodies, link -1, and the grounded link's bodies; the first base body, else the
grounded link's first body, is its root) carries a free joint: it stands on the table plane and
can slide or tip. From the grounded link g two branches of hinges reach the closure joint c
(:func:`closure_joint`: in the middle of the loop, never the motor): links g+1 .. c forward
(hinge i, axis +a_i), links g-1 .. c+1 backward (hinge i turns link i relative to link i+1:
axis -a_i, the same angle). Further bodies of a link hang welded (no joint) below its first.
Hinge c closes the loop by two ``connect`` equality constraints at two points on its axis
(:data:`ANCHOR_SPAN` apart, centred on the hinge's point): together a revolute joint.

**Contacts.** Bodies of one rigid group never collide (MuJoCo's weld filter); each adjacent
pair of links is excluded explicitly (``filterparent`` is off, so the base's bodies do collide
with the grounded link's neighbours: a moving link must not touch the base). Collision geoms
are the bodies' convex pieces; only the base group collides with the table (a body without
convex pieces gets its mesh's hull for that, and nothing else). Bit masks: table
``contype 1``; parts ``contype 2``, ``conaffinity 2`` (+1 in the base group); hulls
``conaffinity 1``.

**Motor**: three actuators on the motor hinge whose forces sum to the motor torque: a torque
motor fed the rigid prediction of the torque (:func:`physics_model.rigid_dynamics`,
feedforward), a position servo (``kp``) and a velocity servo (``kv``) fed the schedule's angle
and speed. The servos correct what the prediction misses (the closure's and the table's
compliance, a base that moves); at perfect tracking the damping term is 0.

**Hand** (``hand=k``, instead of the motor): the base is held (anchored) and a hand holds
link k (:func:`physics_model.hand_links`: across the loop from the grounded link): a mocap
body ``hand`` welded to link k's first body (the closure's stiffness), which the caller moves
along link k's path. With two links held, each half of the loop is a chain of 2 - 4 hinges
between fixed ends, rigid where its screws are independent: the way paradoxical loops are
turned by hand.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

import numpy as np

from paraloop_core.fabrication.export import LINK_COLORS
from paraloop_core.fabrication.physics_model import (
    GRAVITY_WORLD,
    M_PER_MM,
    Body,
    PhysicsModel,
    mass_properties,
    rigid_dynamics,
    size_mm,
)

#: Distance of the two closure anchors on hinge c's axis, as a fraction of the model's size:
#: the constraint's resistance to tilting the hinge grows with its square; any span is exact.
ANCHOR_SPAN = 0.1
#: Time constant (s) and damping ratio with which the closure constraints correct a violation
#: (MuJoCo needs timeconst >= 2 timesteps) and their impedance (``solimp``: 0.9999, the
#: hardest MuJoCo allows; the rest regularizes the overconstrained loop). Near a singular pose
#: a paradoxical loop with its motor held is nearly a mechanism, and the links far from the
#: motor follow any closure gap magnified: at MuJoCo's default impedance 0.9 - 0.95 tv8's links
#: were 9 mm off the prediction for a 0.15 mm gap; TV6 (tests) 2.5 mm for a 0.013 mm gap at
#: 0.999 and 0.14 mm at 0.9999.
CLOSURE_SOLREF = (0.001, 1.0)
CLOSURE_SOLIMP = (0.9999, 0.9999, 0.001)
#: Servo bandwidth times the timestep (:func:`servo_gains`). Both gains are integrated
#: explicitly (semi-implicit Euler): MuJoCo's implicit integrators apply the implicit velocity
#: gain to the motor's degree of freedom alone, after the constraint solve, which pulls the
#: closed loop apart (sun-disc's closure opened by 35 mm at rest). 0.25 keeps the explicit step
#: well inside its stability region (``2 w dt + (w dt)^2 = 0.56 < 2``) and the servo at half
#: the closure's correction rate ``1 / timeconst``, so the two do not couple.
SERVO_STEP = 0.25
#: Names of the MJCF's joints and actuators.
FREE_JOINT, FEEDFORWARD, POSITION, VELOCITY = \
    "base_free", "motor_feedforward", "motor_position", "motor_velocity"


@dataclass(frozen=True)
class Tree:
    """The kinematic tree of a model (module docstring): ``root`` body, ``parent`` of every
    other body, the ``joint`` of each link's first body (hinge index, axis sign), the
    ``closure`` hinge and ``anchors`` ``(2, 3)`` (mm, home) of its two connect constraints."""

    root: str
    parent: dict[str, str]
    joint: dict[str, tuple[int, float]]
    closure: int
    first: dict[int, str]
    anchors: np.ndarray


def closure_joint(grounded: int, motor: int) -> int:
    """The hinge closed by equality constraints: opposite the grounded link, not the motor."""
    order = [(grounded + k) % 6 for k in (2, 3, 1, 4, 0, 5)]
    return next(j for j in order if j != motor)


def tree(model: PhysicsModel) -> Tree:
    """The tree of ``model`` (module docstring)."""
    g, c = model.grounded_link, closure_joint(model.grounded_link, model.motor_joint)
    first: dict[int, str] = {}
    for b in model.bodies:
        first.setdefault(b.link, b.name)
    root = first.get(-1, first[g])
    parent: dict[str, str] = {}
    joint: dict[str, tuple[int, float]] = {}
    for k in range(1, (c - g) % 6 + 1):  # forward branch: links g+1 .. c
        link = (g + k) % 6
        parent[first[link]] = first[(link - 1) % 6] if k > 1 else root
        joint[first[link]] = ((link - 1) % 6, 1.0)
    for k in range(1, (g - c - 1) % 6 + 1):  # backward branch: links g-1 .. c+1
        link = (g - k) % 6
        parent[first[link]] = first[(link + 1) % 6] if k > 1 else root
        joint[first[link]] = (link, -1.0)
    for b in model.bodies:  # the rest hang welded below their group's first body
        if b.name != root and b.name not in parent:
            group = g if b.link in (-1, g) else b.link
            parent[b.name] = root if group == g else first[group]
    h = next(h for h in model.hinges if h.joint == c)
    p, a = np.asarray(h.point_mm, float), np.asarray(h.axis, float)
    anchors = p + np.outer([-0.5, 0.5], ANCHOR_SPAN * size_mm(model) * a)
    return Tree(root, parent, joint, c, first, anchors)


def servo_gains(inertia: float, timestep: float) -> tuple[float, float]:
    """``(kp N m/rad, kv N m s/rad)``: bandwidth ``SERVO_STEP / timestep``, critically damped,
    for the least ``inertia`` (kg m^2) the motor hinge sees (where explicit integration is
    least stable; where it is larger the servo is slower and less damped, still stable)."""
    omega = SERVO_STEP / timestep
    return inertia * omega**2, 2.0 * inertia * omega


def _floats(values) -> str:
    return " ".join(f"{v:.9g}" for v in np.ravel(values))


def _full_inertia(i: np.ndarray) -> str:
    return _floats([i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]])


def mjcf(model: PhysicsModel, mesh_names: Mapping[str, str] | None = None, *,
         timestep: float = 5e-4, anchored: bool = False,
         servo: tuple[float, float] | None = None, hand: int | None = None) -> str:
    """The MJCF of ``model`` (module docstring) at ``timestep`` (s). ``mesh_names``: body name
    -> STL file (mm, home pose; written by the caller beside the MJCF) of a visual geom per
    body (None: no visual geoms, as :mod:`physics` simulates). ``anchored``: the base is fixed
    to the world (a mounted loop) instead of standing free on the table. ``servo``: the gains
    ``(kp, kv)`` (None: :func:`servo_gains` of the least rigid inertia along the prediction,
    right for an anchored base; :func:`physics.simulate` reports the gains it used). ``hand``:
    link held by the hand instead of the motor (module docstring; the base anchored)."""
    tr = tree(model)
    anchored = anchored or hand is not None
    by_name = {b.name: b for b in model.bodies}
    children: dict[str, list[str]] = {}
    for child, parent in tr.parent.items():
        children.setdefault(parent, []).append(child)
    group = {b.name: b.link in (-1, model.grounded_link) for b in model.bodies}
    assets: list[str] = []

    def geoms(b: Body) -> list[str]:
        out = []
        rgba = _floats(np.append(LINK_COLORS[max(b.link, 0)] / 255.0, 1.0))
        if mesh_names is not None and b.name in mesh_names:
            assets.append(f'<mesh name="{b.name}_visual" file={quoteattr(mesh_names[b.name])} '
                          f'scale="{M_PER_MM} {M_PER_MM} {M_PER_MM}"/>')
            out.append(f'<geom name="{b.name}_visual" type="mesh" mesh="{b.name}_visual" '
                       f'contype="0" conaffinity="0" group="1" rgba="{rgba}"/>')
        pieces = [(f"{b.name}_c{k}", p.vertices, 2, 3 if group[b.name] else 2)
                  for k, p in enumerate(b.convex)]
        if not pieces and group[b.name]:
            pieces = [(f"{b.name}_hull", b.mesh.convex_hull.vertices, 0, 1)]
        for name, verts, ctype, caff in pieces:
            assets.append(f'<mesh name="{name}" vertex="{_floats(verts * M_PER_MM)}"/>')
            out.append(f'<geom name="{name}" type="mesh" mesh="{name}" contype="{ctype}" '
                       f'conaffinity="{caff}" group="3" rgba="{rgba[:-1]}0.5"/>')
        return out

    def body_xml(name: str, depth: int) -> list[str]:
        b, pad = by_name[name], "  " * depth
        com, inertia = mass_properties(b)
        lines = [f'{pad}<body name="{name}">']
        if name == tr.root and not anchored:
            lines.append(f'{pad}  <freejoint name="{FREE_JOINT}"/>')
        if name in tr.joint:
            j, sign = tr.joint[name]
            h = next(h for h in model.hinges if h.joint == j)
            lines.append(f'{pad}  <joint name="hinge_{j}" type="hinge" '
                         f'pos="{_floats(np.asarray(h.point_mm) * M_PER_MM)}" '
                         f'axis="{_floats(sign * np.asarray(h.axis, float))}"/>')
        lines.append(f'{pad}  <inertial pos="{_floats(com * M_PER_MM)}" mass="{b.mass_kg:.9g}" '
                     f'fullinertia="{_full_inertia(inertia * M_PER_MM**2)}"/>')
        lines += [f"{pad}  {g}" for g in geoms(b)]
        for child in children.get(name, []):
            lines += body_xml(child, depth + 1)
        return lines + [f"{pad}</body>"]

    bodies = body_xml(tr.root, 2)
    names, first = list(by_name), tr.first
    excludes = [f'    <exclude body1="{a}" body2="{b}"/>'
                for i, a in enumerate(names) for b in names[i + 1:]
                if _adjacent(by_name[a].link, by_name[b].link)]
    c = tr.closure
    connects = [f'    <connect name="closure_{k}" body1="{first[c]}" '
                f'body2="{first[(c + 1) % 6]}" anchor="{_floats(p * M_PER_MM)}" '
                f'solref="{_floats(CLOSURE_SOLREF)}" solimp="{_floats(CLOSURE_SOLIMP)}"/>'
                for k, p in enumerate(tr.anchors)]
    if hand is not None:
        connects.append(f'    <weld name="hand" body1="hand" body2="{first[hand]}" '
                        f'solref="{_floats(CLOSURE_SOLREF)}" solimp="{_floats(CLOSURE_SOLIMP)}"/>')
        bodies.append('    <body name="hand" mocap="true"/>')
    motor = f"hinge_{model.motor_joint}"
    actuators = []
    if hand is None:
        kp, kv = servo if servo is not None else \
            servo_gains(float(rigid_dynamics(model, GRAVITY_WORLD)[0].min()), timestep)
        actuators = [
            f'    <motor name="{FEEDFORWARD}" joint="{motor}"/>',
            f'    <position name="{POSITION}" joint="{motor}" kp="{kp:.9g}"/>',
            f'    <velocity name="{VELOCITY}" joint="{motor}" kv="{kv:.9g}"/>']
    table_z = model.table_z_mm * M_PER_MM
    return "\n".join([
        '<mujoco model="paraloop">',
        '  <compiler angle="radian" inertiafromgeom="false" balanceinertia="true"/>',
        f'  <option timestep="{timestep:.9g}" gravity="{_floats(GRAVITY_WORLD)}" '
        'integrator="Euler">',
        '    <flag filterparent="disable"/>',
        '  </option>',
        '  <asset>', *[f"    {a}" for a in assets], '  </asset>',  # filled by body_xml
        '  <worldbody>',
        f'    <geom name="table" type="plane" pos="0 0 {table_z:.9g}" size="0 0 0.01"'
        ' contype="1" conaffinity="0" rgba="0.8 0.8 0.75 1"/>',  # infinite, 1 cm grid
        *bodies,
        '  </worldbody>',
        '  <contact>', *excludes, '  </contact>',
        '  <equality>', *connects, '  </equality>',
        '  <actuator>', *actuators, '  </actuator>',
        '</mujoco>', ""])


def _adjacent(a: int, b: int) -> bool:
    """Links a, b (-1: base) are neighbours in the loop: their contact is excluded."""
    return a >= 0 and b >= 0 and (a - b) % 6 in (1, 5)
