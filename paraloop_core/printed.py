"""From a solved design to the printed loop: the realization to print, the parts, the files.

The design's own realization is certified for the paper's thin bars (offset ``d`` 1 % of the
polyline): its joints are millimetres long at any printable size. :func:`candidates` offers
roomier realizations instead: the design's loop first, then the other eight, each with the
joint offset that gives pins of :data:`PIN_FRACTIONS` of the loop's extent and bars of
:data:`RHO_FRACTIONS` of it, each a new search with the same certificate. Between them come
the roomy realizations of every loop (:mod:`realization.roomy`: polylines drawn for room per
extent rather than shortness, certified the same way), which many generic designs need: their
shortest polylines pass so close that no offset leaves room for real joints.
:func:`fabrication.printable.make` picks among them and builds the parts; :func:`export`
writes the export folder, whose ``result.json`` is the printed loop's result (the format of
``paraloop solve``), so anyone can check the parts against the motion they will make, and whose
report says what was chosen instead of the design's realization.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import replace

import numpy as np

from paraloop_core import pipeline
from paraloop_core.design import DriveSettings
from paraloop_core.errors import RealizationError
from paraloop_core.fabrication import animate, bed, check, drive_mass, guide, printable
from paraloop_core.fabrication import export as export_files
from paraloop_core.fabrication.choice import Candidate
from paraloop_core.fabrication.printable import Options, Printed
from paraloop_core.fabrication.progress import Progress
from paraloop_core.fabrication.step_job import StepJob
from paraloop_core.linkage import drive_plan, singularity
from paraloop_core.pipeline import Solution
from paraloop_core.realization import polyline, realize, roomy
from paraloop_core.result import json_text, result_to_dict

#: Pin lengths (the offset d) of the candidates as shares of the loop's extent, best first:
#: about 20 mm at a desk size, room for the screw's head and nut recesses and two diameters
#: of hold in each boss.
PIN_FRACTIONS = (0.075, 0.095, 0.06, 0.045)
#: Bar radius of the realization search as a share of the offset d: the certified gaps.
RHO_FRACTIONS = (0.5, 0.35)
#: The design's own loop's candidates tried before the roomy ones (its others come after).
FIRST_OWN = 2
#: Pin length (the offset d) of a roomy candidate (:mod:`roomy`), a share of its polyline's
#: extent.
ROOMY_PIN = 0.06
#: Work budget of each candidate search (:meth:`realize.Search.work`; about 0.3 ms a unit):
#: more for the design's own loop, the one worth printing.
WORK, WORK_OWN = 10_000, 25_000


def expected_size(sol: Solution, printer: printable.Printer) -> tuple[float, float, float]:
    """``(size mm, polyline length l, extent)`` of the design's loop: the size at which its
    links' skeletons would fill the bed, and the initial polyline's length and box side (design
    units), to turn pin lengths in mm into offset fractions of l."""
    real = sol.realization
    if real is not None:
        pts, length = np.asarray(real.points, float), real.length
    else:
        _, pts6 = polyline.shortest_polyline(sol.loop.joint_factors)
        pts, length = np.repeat(pts6, 2, axis=0), polyline.polyline_length(pts6)
    return bed_size(pts, printer), float(length), float(np.max(np.ptp(pts, axis=0)))


def bed_size(points: np.ndarray, printer: printable.Printer) -> float:
    """Size (mm, longest side) at which a loop's polyline ``points`` ``(N, 3)`` would fill
    the bed, less a fifth for the bosses and the base: what an automatic export aims at."""
    pts = np.asarray(points, float)
    return bed.bed_scale(pts, printer) * float(np.max(np.ptp(pts, axis=0))) * 0.8


def realize_variant(sol: Solution, loop: int, d_fraction: float, rho_fraction: float,
                    budget: int | None = None) -> Solution:
    """``sol`` realized anew on ``loop`` with offset ``d_fraction`` of the polyline and bars
    ``rho_fraction`` of it (the design's ``p``, fixed vertices and end-effector); raises
    :class:`RealizationError` when the search finds none."""
    rs = replace(sol.design.realization, d=None, rho=None, d_fraction=d_fraction,
                 rho_fraction=rho_fraction)
    attempt = replace(sol, design=replace(sol.design, loop=loop, realization=rs))
    jf, in_unit = sol.search_factors(loop)
    budget = budget or (WORK_OWN if loop == sol.design.loop else WORK)
    params = dict(p=rs.p, d_fraction=d_fraction, rho_fraction=rho_fraction,
                  fixed=dict(rs.fixed), max_k=rs.max_k, in_unit=in_unit, budget=budget)
    if sol.design.end_effector is None:
        real = None
        if loop == sol.design.loop and sol.realization is not None:
            # the design's own pattern (shifts, offsets) with the roomier offset and bars
            # first: one certificate instead of a search, where it holds
            real = realize.Search(jf, dict(rs.fixed), in_unit).run_hint(
                sol.realization.shifts, sol.realization.offsets, p=rs.p, rho=None, d=None,
                d_fraction=d_fraction, rho_fraction=rho_fraction, max_k=rs.max_k)
        real, ee = (real if real is not None else realize.realize(jf, **params)), None
    else:
        from paraloop_core.realization import realize_ee

        ee = realize_ee.realize_with_effector(jf, pipeline.attach_end_effector(attempt),
                                              **params,
                                              ee_clearance=sol.design.end_effector.clearance)
        real = ee.realization
    return replace(attempt, realization=real, end_effector=ee, realization_report={
        "status": "found", "attempts": [], "fallback": None})


def roomy_variant(sol: Solution, loop: int, pin: float,
                  draws: roomy.Draws | None = None) -> Solution:
    """``sol`` realized anew on ``loop`` by :func:`roomy.realize_roomy` (pins ``pin`` of the
    polyline's extent; the design's fixed vertices, no end-effector; ``draws`` the loop's
    :func:`roomy.draw` when already made); raises :class:`RealizationError` when none of
    its polylines is certified."""
    rs = sol.design.realization
    real = roomy.realize_roomy(draws or _draws(sol, loop), pin=pin)
    rs = replace(rs, p=float(roomy.FINE_P), d=real.separation, rho=real.radius)
    return replace(sol, design=replace(sol.design, loop=loop, realization=rs),
                   realization=real, end_effector=None, realization_report={
                       "status": "found", "attempts": [], "fallback": None})


def _draws(sol: Solution, loop: int, close: bool = False) -> roomy.Draws:
    """:func:`roomy.draw` of ``loop``; ``close``: round the collision-free polyline the
    design realized (its shifts, steps of ``l / p``, as steps of ``l / FINE_P``)."""
    jf, in_unit = sol.search_factors(loop)
    center = None
    if close:
        center = np.rint(np.asarray(sol.realization.shifts, float) * roomy.FINE_P
                         / sol.design.realization.p).astype(int)
    return roomy.draw(jf, dict(sol.design.realization.fixed), in_unit, center=center)


def _roomy_candidates(sol: Solution, made: list[Solution]) -> Iterator[Candidate]:
    """Roomy realizations (:mod:`roomy`) of every loop, the most promising loop first (the
    near-singular ones last); then the design's loop drawn round its own polyline (last: it
    adds a chance where the others found too little, and takes none of their turns)."""
    draws = {i: _draws(sol, i) for i in range(len(sol.loops))}
    near = _near_singular(sol)

    def candidate(loop: int, what: str, get: Callable[[], roomy.Draws]) -> Candidate:
        def run() -> tuple:
            s = roomy_variant(sol, loop, ROOMY_PIN, get())
            made.append(s)
            return s.realization, None

        return Candidate(f"loop {loop}, roomy polyline{what}, offset d = {ROOMY_PIN:g} of its "
                         "extent", loop, run, near[loop])

    for loop in sorted(draws, key=lambda i: (near[i], -draws[i].promise)):
        yield candidate(loop, "", lambda loop=loop: draws[loop])
    if sol.realization is not None:
        mine = sol.design.loop
        yield candidate(mine, " near the design's", lambda: _draws(sol, mine, close=True))


def _near_singular(sol: Solution) -> list[bool]:
    """Per loop: whether it is (near) singular (:func:`singularity.loop_status`)."""
    return [s != "ok" for s in singularity.loop_status(sol.singularity)]


def candidates(sol: Solution, printer: printable.Printer, made: list[Solution]
               ) -> Iterator[Candidate]:
    """Lazy candidates (module docstring), best first: the design's loop (roomiest first;
    after :data:`FIRST_OWN` of them, or after the first where it found none, without an
    end-effector, every loop's roomy realization), then every other loop;
    each solution a candidate realizes is appended to ``made`` (the chosen one's result is
    written)."""
    _, length, ext = expected_size(sol, printer)
    mine, near = sol.design.loop, _near_singular(sol)
    # the design's loop first; the other loops from the farthest from a singular pose
    others = sorted((i for i in range(len(sol.loops)) if i != mine),
                    key=lambda i: -float(sol.singularity[i]))
    order = [(mine, PIN_FRACTIONS[0], RHO_FRACTIONS[0]), (mine, PIN_FRACTIONS[0],
                                                           RHO_FRACTIONS[1]),
             (mine, PIN_FRACTIONS[1], RHO_FRACTIONS[1]), (mine, PIN_FRACTIONS[2],
                                                           RHO_FRACTIONS[1]),
             (mine, PIN_FRACTIONS[3], RHO_FRACTIONS[0])]
    later = [(i, PIN_FRACTIONS[0], RHO_FRACTIONS[1]) for i in others]
    start, roomy_left = len(made), sol.design.end_effector is None
    for n, (loop, pin, rf) in enumerate(order + later):
        # the roomy ones after FIRST_OWN, or at once where the first search found none
        # (the second repeats its search with thinner bars: rarely found, costly when not)
        if roomy_left and (n == FIRST_OWN or n == 1 and len(made) == start):
            roomy_left = False
            yield from _roomy_candidates(sol, made)
        d_fraction = pin * ext / length

        def run(loop=loop, d_fraction=d_fraction, rf=rf) -> tuple:
            s = realize_variant(sol, loop, d_fraction, rf)
            made.append(s)
            return s.realization, s.end_effector

        yield Candidate(f"loop {loop}, offset d = {d_fraction:.3g} l, bars {rf:g} d", loop,
                        run, near[loop])


def note(sol: Solution, printed: Printed) -> str:
    """What was printed instead of the design's realization, in words."""
    loop = sol.design.loop
    what = f"loop {printed.loop}" + ("" if printed.loop == loop else
                                    f" (the design's is loop {loop})")
    return (f"printed: {what}, realized again with joint offsets and bars for real joints "
            f"({printed.candidate}); the design's own realization keeps the paper's thin bars, "
            "whose joints are a few millimetres long at a printable size")


def make(sol: Solution, opts: Options | None = None, progress: Progress | None = None,
         on_parts: Callable | None = None) -> tuple[Printed, Solution]:
    """The printed loop of a solved design and the solution it was built on
    (``on_parts``: :func:`printable.make`'s)."""
    opts = opts or Options()
    if not sol.design.realization.enabled:
        raise RealizationError("the design has no realization (enable it in the design "
                               "file: realization.enabled)", "bad-parameters")
    made: list[Solution] = []
    printed = printable.make(candidates(sol, opts.printer, made), opts, sol.design.drive,
                             progress, on_parts)
    chosen = next(s for s in made if s.realization is printed.realization)
    chosen = replace(chosen, design=replace(chosen.design, drive=drive_of(
        printed, chosen.design.drive)), realization_report={
        **chosen.realization_report, "printed": note(sol, printed)})
    return printed, chosen


def drive_of(printed: Printed, settings: DriveSettings) -> DriveSettings:
    """The drive ``settings`` with the motor the printed loop is turned by: where the export
    moved the motor to a joint whose torque keeps the gaps (report ``drive.motor_chosen``,
    :func:`printable.make`), that joint."""
    d = printed.report.get("drive", {})
    return replace(settings, motor=d["motor"]) if d.get("motor_chosen") == \
        printable.MOTOR_KEEPS_GAPS else settings


def export(sol: Solution, opts: Options | None = None, *, rhino: bool = False,
           simulate: bool = False, progress: Progress | None = None
           ) -> tuple[list[tuple[str, bytes]], dict, Solution]:
    """The export folder's files (``paraloop export``, the studio's *Export all*), the report
    and the printed loop's solution; ``simulate``: with the physics check
    (:func:`physics_check`: report ``physics``, the MJCF and its meshes)."""
    opts = opts or Options()
    # the STEP solids are made on the second core while the parts are verified and the
    # meshes and guide written (:mod:`step_job`)
    with StepJob() as job:
        return _export(sol, opts, rhino, simulate, progress, job)


def _export(sol: Solution, opts: Options, rhino: bool, simulate: bool,
            progress: Progress | None, job: StepJob
            ) -> tuple[list[tuple[str, bytes]], dict, Solution]:
    def submit(asm) -> None:  # the parts built: their STEP solids start on the helper
        if asm is None:  # those handed are rebuilt: the helper stops its work on them
            job.withdraw()
        else:
            job.submit(asm, export_files.step_colors(asm), export_files.STEEL)

    printed, chosen = make(sol, opts, printable.stage(progress, 0.0, 0.85), submit)
    if progress is not None:
        progress(0.86, "writing the parts, the guide and its pictures")
    report = printed.report
    report["choice"]["note"] = note(sol, printed)
    report["choice"]["design_loop"] = sol.design.loop
    files, meshes, placements = export_files.files(printed.assembly, report, opts.material,
                                                   rhino=rhino)
    files += guide.pages(printed, meshes, placements, opts, report)
    glb, how = animation(printed, sol.design.drive)
    files.append(("animation.glb", glb))
    report["animation"] = f"animation.glb: the printed parts through one cycle, {how}"
    if simulate:
        if progress is not None:
            progress(0.9, "physics check (MuJoCo)")
        report["physics"], more = physics_check(printed, opts, sol.design.drive)
        files += more
    if progress is not None:
        progress(0.97, "STEP solids")
    files += export_files.step_files(printed.assembly, report, job)  # last: the slowest
    result = json_text(result_to_dict(chosen))
    files.append(("result.json", result.encode()))
    files.append(("report.json", export_files.report_json(report)))
    return files, report, chosen


def animation(printed: Printed, settings: DriveSettings, frames: int = 240,
              seconds: float | None = None) -> tuple[bytes, str]:
    """``(.glb bytes, how it is driven)``: the printed parts (and hardware) moving through one
    cycle on their base, as the design's drive turns them (:func:`drive_plan.plan_drive` with
    the grounded link resting: its motor with the speed schedule, or at constant speed)."""
    asm = printed.assembly
    g = printed.base.link if printed.base is not None else 0
    jf = asm.joint_factors
    plan = drive_plan.plan_drive(jf, drive_of(printed, settings), resting_link=g)
    if plan.schedule is not None:
        t = animate.scheduled_parameters(jf, plan.schedule, frames)
        how = f"motor joint {plan.motor} with its speed schedule"
    else:
        theta = np.linspace(0.0, 2 * np.pi, frames)
        t = animate.motor_parameters(jf, plan.motor, theta)
        how = f"motor joint {plan.motor} at constant speed (no schedule meets the limits)"
    jf_mm = np.array(jf, float)
    jf_mm[:, 4:] *= asm.scale  # the same motion with lengths in mm
    meshes: list[list] = [[] for _ in range(6)]
    for p in asm.parts:
        rgb = export_files.color_of(-1 if p.role == "base" else p.link)
        meshes[p.link].append((check.part_trimesh(p.manifold), rgb))
    for h in asm.hardware:
        meshes[h.link].append((check.part_trimesh(h.solid), export_files.STEEL))
    world = printed.base.world_from_home() if printed.base is not None else None
    glb = animate.animated_glb(jf_mm, printed.realization.points * asm.scale, 1.0,
                               frames=frames, seconds=seconds or plan.cycle_time_s, t=t,
                               meshes=meshes, resting=g, world=world, unit="millimetres")
    return glb, how


def physics_check(printed: Printed, opts: Options, settings: DriveSettings,
                  hand: bool | None = None) -> tuple[dict, list[tuple[str, bytes]]]:
    """``(report, files)``: one cycle of the printed parts in MuJoCo
    (:mod:`fabrication.physics`): standing free on a table when there is a base (anchored
    otherwise), the design's drive, the quasi-static torque beside the dynamic one. ``hand``:
    turned by hand, the base held (None: where the drive report says that one motor cannot
    hold the loop, ``drive.HOLD_RATIO``; there the motor's run would only show that). The files
    are ``paraloop.xml`` (MJCF) and the bodies' meshes ``physics_<body>.stl`` (standing world
    frame, mm) it refers to."""
    from paraloop_core.fabrication import physics, physics_assembly  # MuJoCo loads here

    model = physics_assembly.model_from_assembly(printed.assembly, opts.material,
                                                 drive_of(printed, settings))
    anchored = printed.base is None
    quasi = printed.report["drive"].get("peak_torque_n_m")
    if hand is None:  # a motor where one can hold the loop, else a hand
        hand = drive_mass.by_hand(printed.report["drive"])
    rep = physics.simulate(model, quasi_static_peak_nm=quasi, anchored=anchored, hand=hand)
    names = {b.name: f"physics_{b.name}.stl" for b in model.bodies}
    xml = physics.mjcf(model, names, timestep=rep.timestep, anchored=rep.anchored,
                       servo=(rep.servo_kp, rep.servo_kv),
                       hand=rep.hand_link)
    files = [("paraloop.xml", xml.encode())]
    files += [(names[b.name], b.mesh.export(file_type="stl")) for b in model.bodies]
    return rep.to_dict(), files
