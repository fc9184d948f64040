"""Physics check of the printed mechanism with MuJoCo (issue 26, point 7).

:func:`simulate` runs one cycle of a :class:`PhysicsModel` (the parts as rigid bodies with
their masses, the hinges, gravity; :mod:`physics_model`) as :mod:`mjcf` describes it: the base
free on a table (friction 1; or ``anchored``), the loop closed by two connect constraints on
one hinge's axis, the motor hinge driven along the schedule. The run:

1. *settle* (``settle_s``): the mechanism at home, the motor held at 0, so the base sinks into
   its soft table contact and the loop takes up its weight; the base pose then is the
   reference of tilt, lift and slide;
2. *cycle*: the clock restarts at 0, every tree hinge gets the speed of the prediction at
   time 0 (the schedule starts moving), and the motor follows ``motor_angle(t)`` (a cubic
   spline of the samples) until the last sample time.

**The motor** (:mod:`mjcf`): a feedforward torque (the rigid prediction,
:func:`physics_model.rigid_dynamics`) plus a position and a velocity servo. The servos'
gains (:func:`mjcf.servo_gains`) come from the least inertia the motor hinge sees in MuJoCo's
model along the prediction (:func:`_least_inertia`: with a free base, the light base turning
against the loop). The reported dynamic torque is the sum of the three actuator forces: what
gravity, inertia, the constraints and a moving base ask of the motor. It is measured, not
copied: with the feedforward set to zero the servos alone give the same torque (tests).

**By hand** (``hand=True``; :func:`printed.physics_check` chooses it where one motor cannot
hold the loop, ``drive.HOLD_RATIO``): no motor; the base is held and a hand holds a link
across the loop (:func:`physics_model.hand_links`: the one that keeps both halves of the
loop the most rigid, the next where that hold loses the loop; :mod:`mjcf`), moved along that
link's path (:func:`physics_model.link_path`) on the same schedule. The weld that carries
the hand trails a moving target by ``2 timeconst dampratio^2`` (MuJoCo's reference
acceleration damps the relative velocity, and a mocap body has none), so the hand leads its
path by that time (:data:`HAND_LEAD_S`): tv8's and random loops' links then follow the
prediction to 0.01 - 0.3 mm instead of 3 - 4 mm. No torque is reported (the hand's effort is
not the motor's).

**Checks** (:class:`PhysicsReport`):

* ``completed``: no numerical blow-up, and at every sample time each link's pose relative to
  the grounded link within ``pose_tolerance_mm`` = :data:`POSE_FRACTION` of the model's size
  of the prediction (at the corners of the link's bounding box, so rotation errors count at
  the part's extent). The simulation's own compliance (the soft closure magnified near
  singular poses, the servo's lag) moved links by at most 0.01 mm on the five examples and
  0.14 mm on the tests' pendulum (1/50 to 1/1000 of the tolerance); a loop that jams, falls
  over, flips to another branch or comes apart moves them by a sizeable fraction of its size;
* non-adjacent contacts: every contact MuJoCo finds between the convex pieces of bodies that
  are neither one rigid group nor neighbouring links (the base is in the grounded link's
  group, not its neighbours'), with the steps, first time and deepest penetration per pair;
  the pieces contain the parts (capsule hulls), so for each such pair the parts' own meshes
  are measured as simulated at up to :data:`EXACT_STEPS` of its steps (``parts_gap_mm``),
  and only a pair whose parts touch counts (random 62205: link 2's hulls reached 1.66 mm
  into the rod's cap, the parts 1.39 mm apart); bodies without convex pieces are listed as
  not checked;
* the table: the moving parts' mesh hull vertices stay above it at every sample time;
* ``stands``: the base tilts by at most :data:`TILT_LIMIT_DEG` and its lowest point rises by at
  most :data:`LIFT_LIMIT_MM` from the settled pose;
* the dynamic peak torque beside the rigid prediction's and the quasi-static one the caller
  computed (gravity only).

**Timestep and solver** (:data:`TIMESTEP`): 0.5 ms, and the closure's time constant the
least MuJoCo allows at that step (two steps, ``mjcf.CLOSURE_SOLREF``); the servo's bandwidth
``0.25 / timestep`` is then 500 rad/s, far above the schedule's content, and half the
closure's rate. A gear ratio g between the motor and a far joint multiplies the servo's lag
by g at the links: at 1 ms random loop 62013 (g up to 14, standing free, where the light
base lowers the servo's gains) trailed its prediction by 12 mm (tolerance 8), at 0.5 ms by
0.9 mm. Integrator ``Euler`` (semi-implicit; MuJoCo's implicit integrators open the closed
loop, see :data:`mjcf.SERVO_STEP`), the default Newton solver (a few iterations for 11
degrees of freedom). A 10 s cycle is 20 000 steps.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import mujoco
import numpy as np
from scipy.interpolate import CubicSpline

from paraloop_core.algebra import dq
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import mjcf as mjcf_mod
from paraloop_core.fabrication import physics_measure as measure
from paraloop_core.fabrication.mjcf import mjcf
from paraloop_core.fabrication.parts import mesh_manifold
from paraloop_core.fabrication.physics_model import (
    GRAVITY_WORLD,
    M_PER_MM,
    Body,
    Hinge,
    PhysicsModel,
    check_model,
    hand_links,
    hinge_angles,
    link_path,
    rigid_dynamics,
    size_mm,
)

__all__ = ["Body", "Hinge", "PhysicsModel", "PhysicsReport", "simulate", "mjcf"]

#: Default timestep (s), see the module docstring.
TIMESTEP = 5e-4
#: Pose tolerance as a fraction of the model's size (``completed``).
POSE_FRACTION = 0.02
#: Steps of a pair's contact (evenly spread) at which the parts' own meshes are measured.
EXACT_STEPS = 40
#: The base tips when it tilts by more than this (deg) from its settled pose ...
TILT_LIMIT_DEG = 2.0
#: ... or when its lowest point rises by more than this (mm).
LIFT_LIMIT_MM = 1.0
#: Settling time (s) before the cycle.
SETTLE_S = 0.2
#: Samples of the torque curve in the report.
CURVE_SAMPLES = 128
#: How far (s) the hand leads its link's path: the weld's lag (module docstring, By hand).
HAND_LEAD_S = 2.0 * mjcf_mod.CLOSURE_SOLREF[0] * mjcf_mod.CLOSURE_SOLREF[1] ** 2


@dataclass(frozen=True)
class PhysicsReport:
    """What :func:`simulate` found (module docstring); lengths mm, torques N m, times s."""

    ok: bool
    completed: bool
    max_pose_error_mm: float
    pose_tolerance_mm: float
    max_motor_error_rad: float
    max_closure_gap_mm: float
    non_adjacent_contacts: int  # simulation steps with at least one
    contact_pairs: tuple[dict, ...]  # per pair: bodies, steps, first_time_s, max_depth_mm
    unchecked_bodies: tuple[str, ...]  # no convex pieces: contacts not checked
    min_table_clearance_mm: float | None  # moving parts above the table (None: anchored)
    stands: bool | None  # None: anchored
    base_tilt_deg_max: float
    base_lift_mm_max: float
    base_slide_mm_max: float
    drive: str  # "motor" or "hand" (module docstring)
    hand_link: int | None  # the link the hand holds (None: the motor drives)
    peak_torque_dynamic_nm: float | None  # None: turned by hand
    peak_torque_quasi_static_nm: float | None  # as the caller computed it
    peak_torque_rigid_nm: float | None  # rigid prediction (physics_model.rigid_dynamics)
    torque_time_s: tuple[float, ...]
    torque_nm: tuple[float, ...]
    motor_joint: int
    grounded_link: int
    closure_joint: int
    anchored: bool
    timestep: float
    steps: int
    sim_seconds: float
    wall_seconds: float
    servo_kp: float | None  # None: turned by hand
    servo_kv: float | None
    mujoco_warnings: tuple[str, ...]
    method: str

    def to_dict(self) -> dict:
        """JSON-ready (non-finite numbers as None)."""
        def clean(x):
            if isinstance(x, dict):
                return {k: clean(v) for k, v in x.items()}
            if isinstance(x, (list, tuple)):
                return [clean(v) for v in x]
            if isinstance(x, (float, np.floating)):
                return float(x) if math.isfinite(x) else None
            if isinstance(x, (np.integer, np.bool_)):
                return x.item()
            return x

        return clean(asdict(self))


def simulate(model: PhysicsModel, *, timestep: float = TIMESTEP,
             quasi_static_peak_nm: float | None = None, anchored: bool = False,
             settle_s: float = SETTLE_S, hand: bool = False) -> PhysicsReport:
    """Run one cycle of ``model`` (module docstring) and check it. ``anchored``: the base is
    fixed in the world (a mounted loop; no table, no tipping check). ``hand``: turned by hand
    instead of the motor (module docstring; anchored). Raises
    :class:`FabricationError` (``bad-parameters``) for a malformed model or option."""
    wall = time.perf_counter()
    check_model(model)
    limit = mjcf_mod.CLOSURE_SOLREF[0] / 2
    if not (math.isfinite(timestep) and 0 < timestep <= limit):
        raise FabricationError(f"timestep must be in (0, {limit:g}] s (the closure's time "
                               f"constant is {2 * limit:g} s), got {timestep!r}",
                               "bad-parameters")
    if not (math.isfinite(settle_s) and settle_s >= 0):
        raise FabricationError(f"settle_s must be >= 0, got {settle_s!r}", "bad-parameters")
    # MuJoCo's warnings (a blow-up) go to the report, not to stdout and MUJOCO_LOG.TXT; the
    # handler is process-wide, so it is restored at once
    messages: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(messages.append)
    try:
        if not hand:
            return _simulate(model, timestep, quasi_static_peak_nm, anchored, settle_s, wall,
                             messages, None)
        # the links across the loop in turn, the most rigid hold first; as a maker would,
        # another hold where one loses the loop (the report names the link held)
        first = None
        for held in hand_links(model):
            rep = _simulate(model, timestep, quasi_static_peak_nm, True, settle_s, wall,
                            messages, held)
            if rep.completed:
                return rep
            first = first or rep
        return first
    finally:
        mujoco.set_mju_user_warning(previous)


def _simulate(model: PhysicsModel, timestep: float, quasi_static_peak_nm: float | None,
              anchored: bool, settle_s: float, wall: float, messages: list[str],
              held: int | None) -> PhysicsReport:
    hand = held is not None
    tree = mjcf_mod.tree(model)
    times = np.asarray(model.time_s, float)
    inertia, rigid, gravity = rigid_dynamics(model, GRAVITY_WORLD)
    servo = None if hand else mjcf_mod.servo_gains(float(inertia.min()), timestep)
    m = mujoco.MjModel.from_xml_string(mjcf(model, timestep=timestep, anchored=anchored,
                                            servo=servo, hand=held))
    d = mujoco.MjData(m)
    if not hand:  # the gains for the least inertia the motor sees in this model
        servo = mjcf_mod.servo_gains(
            min(float(inertia.min()), _least_inertia(m, d, model, tree)), timestep)
        m = mujoco.MjModel.from_xml_string(mjcf(model, timestep=timestep, anchored=anchored,
                                                servo=servo))
        d = mujoco.MjData(m)
    ids = _Ids(m, model, tree)
    ref = CubicSpline(times, hinge_angles(model), axis=0)
    steps = int(math.ceil(times[-1] / timestep)) + 1
    t_step = np.minimum(np.arange(steps) * timestep, times[-1])
    if hand:
        ctrl = np.zeros((steps, 0))
        path = link_path(model, held, np.minimum(t_step + HAND_LEAD_S, times[-1]))
        mocap = (path[:, :3, 3] * M_PER_MM, dq.matrix_to_wxyz(path[:, :3, :3]))
    else:
        ctrl = np.stack([np.interp(t_step, times, rigid), ref(t_step)[:, model.motor_joint],
                         ref(t_step, 1)[:, model.motor_joint]], axis=1)
        mocap = None
        d.ctrl[:] = gravity[0], 0.0, 0.0  # hold the home pose
    for _ in range(int(round(settle_s / timestep))):
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)
    settled = (d.xpos[ids.root].copy(), d.xmat[ids.root].reshape(3, 3).copy())
    d.time = 0.0
    rates = ref(0.0, 1)
    for joint, _ in tree.joint.values():
        d.qvel[m.jnt_dofadr[m.joint(f"hinge_{joint}").id]] = rates[joint]
    run = _run(m, d, ids, ctrl, steps, mocap)
    return _report(model, tree, run, settled, ref(t_step)[:, model.motor_joint], anchored,
                   timestep, quasi_static_peak_nm, None if hand else float(np.abs(rigid).max()),
                   servo, held, wall, messages)



def _least_inertia(m: mujoco.MjModel, d: mujoco.MjData, model: PhysicsModel,
                   tree: mjcf_mod.Tree, samples: int = 32) -> float:
    """Least inertia (kg m^2) the motor hinge sees in MuJoCo's model at ``samples`` poses of
    the prediction, the loop closed, the base (if free) in the air: ``1 / (P)_mm`` with ``P =
    M^-1 - M^-1 J^T (J M^-1 J^T)^+ J M^-1`` (M the tree's mass matrix, J the closure's
    Jacobian). With a free base the motor turns the light base against the loop, which the
    rigid inertia (base still) overstates several-fold (tv8: 8.5x)."""
    angles = hinge_angles(model)
    dof = m.jnt_dofadr[m.joint(f"hinge_{model.motor_joint}").id]
    least = np.inf
    inv, eye = np.zeros((m.nv, m.nv)), np.eye(m.nv)
    for k in np.linspace(0, len(angles) - 1, samples).astype(int):
        d.qpos[:] = m.qpos0
        for joint, _ in tree.joint.values():
            d.qpos[m.jnt_qposadr[m.joint(f"hinge_{joint}").id]] = angles[k, joint]
        mujoco.mj_forward(m, d)
        mujoco.mj_solveM(m, d, inv, eye)  # M^-1 (symmetric)
        eq = d.efc_type[:d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        jac = d.efc_J.reshape(d.nefc, m.nv)[eq]
        proj = inv - inv @ jac.T @ np.linalg.pinv(jac @ inv @ jac.T, rcond=1e-10) @ jac @ inv
        least = min(least, 1.0 / proj[dof, dof])
    mujoco.mj_resetData(m, d)
    return float(least)


class _Ids:
    """MuJoCo ids the run needs: each link's first body, the root, the motor's qpos address,
    geom -> body name (-1: the table)."""

    def __init__(self, m: mujoco.MjModel, model: PhysicsModel, tree: mjcf_mod.Tree):
        self.link = np.array([m.body(tree.first[k]).id for k in range(6)])
        self.root = m.body(tree.root).id
        self.motor = m.jnt_qposadr[m.joint(f"hinge_{model.motor_joint}").id]
        self.table = m.geom("table").id
        self.geom_body = [m.body(int(b)).name for b in m.geom_bodyid]


@dataclass
class _Run:
    xpos: np.ndarray  # (steps, 6, 3) m, each link's first body
    xmat: np.ndarray  # (steps, 6, 3, 3)
    root: np.ndarray  # (steps, 4, 4) root body, mm
    torque: np.ndarray  # (steps,) N m
    motor: np.ndarray  # (steps,) motor hinge angle, rad
    contacts: dict  # (body a, body b) -> [steps, first step, max depth mm, last step, steps]
    done: int  # steps run (fewer on a blow-up)
    diverged: bool


def _run(m, d, ids: _Ids, ctrl: np.ndarray, steps: int,
         mocap: tuple[np.ndarray, np.ndarray] | None) -> _Run:
    """Step the cycle with the actuators' controls ``ctrl`` ``(steps, nu)`` and the hand's
    ``mocap`` (positions m, ``wxyz``; None: no hand), recording the state at the start of
    each step (what ``mj_step`` computes its forces and contacts from)."""
    xpos, xmat = np.zeros((steps, 6, 3)), np.zeros((steps, 6, 3, 3))
    root, torque, motor = np.zeros((steps, 4, 4)), np.zeros(steps), np.zeros(steps)
    contacts: dict = {}
    bad = mujoco.mjtWarning.mjWARN_BADQACC
    done = steps
    for k in range(steps):
        motor[k] = d.qpos[ids.motor]
        d.ctrl[:] = ctrl[k]
        if mocap is not None:
            d.mocap_pos[0], d.mocap_quat[0] = mocap[0][k], mocap[1][k]
        mujoco.mj_step(m, d)
        if d.warning[bad].number:
            done = k
            break
        xpos[k], xmat[k] = d.xpos[ids.link], d.xmat[ids.link].reshape(6, 3, 3)
        root[k, :3, :3] = d.xmat[ids.root].reshape(3, 3)
        root[k, :3, 3] = d.xpos[ids.root] / M_PER_MM
        torque[k] = d.actuator_force.sum()
        for g, dist in zip(d.contact.geom[:d.ncon], d.contact.dist[:d.ncon], strict=True):
            if ids.table in g:
                continue
            pair = tuple(sorted((ids.geom_body[g[0]], ids.geom_body[g[1]])))
            rec = contacts.setdefault(pair, [0, k, 0.0, -1, []])
            if rec[3] != k:  # count steps, not contact points
                rec[0], rec[3] = rec[0] + 1, k
                rec[4].append(k)
            rec[2] = max(rec[2], -dist / M_PER_MM)
    root[:, 3, 3] = 1.0
    return _Run(xpos[:done], xmat[:done], root[:done], torque[:done], motor[:done], contacts,
                done, done < steps)


def _report(model: PhysicsModel, tree: mjcf_mod.Tree, run: _Run,
            settled: tuple[np.ndarray, np.ndarray], target: np.ndarray, anchored: bool,
            dt: float, quasi_static: float | None, rigid: float | None,
            gains: tuple[float, float] | None, held: int | None, wall: float,
            messages: list[str]) -> PhysicsReport:
    n, g = run.done, model.grounded_link
    tol = POSE_FRACTION * size_mm(model)
    poses = np.zeros((n, 6, 4, 4))  # simulated T_world_link, mm
    poses[..., :3, :3], poses[..., :3, 3], poses[..., 3, 3] = run.xmat, run.xpos / M_PER_MM, 1.0
    corners = np.array([measure.corners([b for b in model.bodies if b.link == k])
                        for k in range(6)])
    # pose error at the sample times reached, relative to the grounded link, the simulated
    # points interpolated linearly between the steps around each sample time
    times = np.asarray(model.time_s, float)
    reached = times <= (n - 1) * dt  # none if the run blew up at once
    k0 = np.minimum((times[reached] / dt).astype(int), max(n - 2, 0))
    w = (times[reached] / dt - k0)[:, None, None, None]
    sim = measure.points(np.linalg.inv(poses[:, g:g + 1]) @ poses, corners)
    sim = (1 - w) * sim[k0] + w * sim[np.minimum(k0 + 1, n - 1)]
    kin = np.asarray(model.link_poses, float)[reached]
    kin = measure.points(np.linalg.inv(kin[:, g:g + 1]) @ kin, corners)
    error = float(np.linalg.norm(sim - kin, axis=-1).max(initial=0.0))
    if run.diverged:  # the links are lost (inf; None in JSON)
        error = np.inf
    completed = bool(reached.all()) and error <= tol
    # closure: the two anchors as carried by both closure links
    c = tree.closure
    ends = [measure.points(poses[:, k], tree.anchors) for k in (c, (c + 1) % 6)]
    closure = float(np.linalg.norm(ends[0] - ends[1], axis=-1).max(initial=0.0))
    tilt, lift, slide, clearance, stands = 0.0, 0.0, 0.0, None, None
    if not anchored:
        tilt, lift, slide = measure.base_motion(model, run.root, settled)
        stands = tilt <= TILT_LIMIT_DEG and lift <= LIFT_LIMIT_MM
        clearance = measure.table_clearance(model, poses[np.round(times[reached] / dt).astype(int)])
    gaps = {p: _parts_gap(model, poses, p, r[4]) for p, r in run.contacts.items()}
    pairs = tuple({"bodies": list(p), "steps": r[0], "first_time_s": r[1] * dt,
                   "max_depth_mm": r[2], "parts_gap_mm": gaps[p]}
                  for p, r in sorted(run.contacts.items()))
    # the convex pieces contain the parts: only a contact of the parts themselves counts
    touching = np.zeros(n, bool)
    for p, r in run.contacts.items():
        if gaps[p] <= 0.0:
            touching[[k for k in r[4] if k < n]] = True
    contacts = int(touching.sum())
    curve_t = np.linspace(0.0, times[-1], CURVE_SAMPLES) if held is None else np.zeros(0)
    curve = np.interp(curve_t, np.arange(n) * dt, run.torque) if n else np.zeros(len(curve_t))
    ok = completed and contacts == 0 and (anchored or (bool(stands) and clearance >= 0.0))
    return PhysicsReport(
        ok=ok, completed=completed, max_pose_error_mm=error, pose_tolerance_mm=tol,
        max_motor_error_rad=float(np.abs(run.motor - target[:n]).max(initial=0.0)),
        max_closure_gap_mm=closure, non_adjacent_contacts=contacts, contact_pairs=pairs,
        unchecked_bodies=tuple(b.name for b in model.bodies if not b.convex),
        min_table_clearance_mm=clearance, stands=stands, base_tilt_deg_max=tilt,
        base_lift_mm_max=lift, base_slide_mm_max=slide,
        drive="motor" if held is None else "hand", hand_link=held,
        peak_torque_dynamic_nm=None if held is not None else
        float(np.abs(run.torque).max(initial=0.0)),
        peak_torque_quasi_static_nm=quasi_static, peak_torque_rigid_nm=rigid,
        torque_time_s=tuple(np.round(curve_t, 6).tolist()),
        torque_nm=tuple(float(f"{v:.6g}") for v in curve), motor_joint=model.motor_joint,
        grounded_link=g, closure_joint=c, anchored=anchored, timestep=dt, steps=n,
        sim_seconds=n * dt, wall_seconds=time.perf_counter() - wall,
        servo_kp=None if gains is None else float(gains[0]),
        servo_kv=None if gains is None else float(gains[1]), mujoco_warnings=tuple(messages),
        method=METHOD)


def _parts_gap(model: PhysicsModel, poses: np.ndarray, bodies: tuple[str, str],
               steps: list[int]) -> float:
    """Least gap (mm; 0: touching) between the two ``bodies``' meshes as simulated (``poses``
    ``(steps, 6, 4, 4)`` T_world_link, mm) at up to :data:`EXACT_STEPS` of the ``steps`` where
    their convex pieces touched, evenly spread (manifold3d ``min_gap``)."""
    by = {b.name: b for b in model.bodies}
    solids = []
    for name in bodies:
        b = by[name]
        solids.append((mesh_manifold(b.mesh.vertices, b.mesh.faces),
                       model.grounded_link if b.link < 0 else b.link))
    pick = np.unique(np.linspace(0, len(steps) - 1, min(EXACT_STEPS, len(steps))).astype(int))
    gap = np.inf
    for k in np.asarray(steps)[pick]:
        (sa, la), (sb, lb) = solids
        a = sa.transform(poses[k, la][:3].tolist())
        gap = min(gap, a.min_gap(sb.transform(poses[k, lb][:3].tolist()), 10.0))
        if gap <= 0.0:
            break
    return float(gap)


METHOD = ("MuJoCo forward simulation of the parts as rigid bodies (masses, inertia from the "
          "meshes at uniform density), hinges on the joint axes, the loop closed by two connect "
          "constraints on one hinge's axis, gravity -z, the base free on a table with friction "
          "1 (unless anchored), the motor hinge position- and velocity-servoed along the "
          "schedule (or, turned by hand, the base held and a link across the loop moved along "
          "its path by a welded mocap body); torque = the servo's force; pose error relative to "
          "the grounded link at the corners of each link's bounding box")
