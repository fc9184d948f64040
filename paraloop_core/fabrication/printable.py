"""Printable by default: the realization, size, parts, base and checks chosen by the program.

:func:`make` takes candidate realizations (lazily: each is a new, equally certified search,
made by the caller, which knows the design) and

1. sizes each (:mod:`choice`, :func:`sizing.plan`: the largest size whose parts fit the
   bed, the thickest bars the certificate allows, joints with real hardware) and keeps the
   best: the width and length/width aims met, then the largest size, then the thickest
   thinnest bar; the first candidate is the design's own loop, and it is kept when it is as
   good as any tried;
2. builds the links (:mod:`assembly`), each laid on a flat face for printing (:mod:`layout`),
   shrinking the size if a built part does not fit the bed;
3. grounds it (:mod:`base`): a rod and a plate on which it stands over the whole cycle, the
   grounded joint re-laid for the rod; where a link of it would print over supports (its bar
   too thin for a flat that keeps its bores' walls) or a bar is cut across its core at a
   joint, the next sized candidates are built too and the one with the fewest such defects
   is taken (a base first);
4. verifies the parts over the continuous cycle (:mod:`check`), measures walls, support,
   stiffness (:mod:`stiffness`) and the motor torque of the real masses.

The caller writes the files (:mod:`files`). Everything the program chose, and why, is in the
report (``choice``, ``sizing``, ``warnings``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from paraloop_core.design import DriveSettings
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import (
    assembly,
    base,
    bed,
    check,
    choice,
    drive_mass,
    flat,
    joints,
    keel,
    layout,
    parts,
    remedy,
    rows,
    sizing,
    stand,
    stiffness,
    thickness,
)
from paraloop_core.fabrication.assembly import Assembly
from paraloop_core.fabrication.profiles import Options
from paraloop_core.fabrication.progress import Progress
from paraloop_core.linkage.drive import peak_speed_ratios
from paraloop_core.realization.certified import Realization

#: Rebuilds with the keels that failed the verification a level lower (:func:`keel.in_the_way`:
#: wide, narrow, none).
KEEL_ROUNDS = 3
#: The report's ``drive.motor_chosen`` where the recommended motor's torque would bend two
#: links into the gap they keep and another joint's does not (:func:`make`).
MOTOR_KEEPS_GAPS = "keeps the gaps"
#: Sizes (factors) tried in turn when the built parts must shrink to fit the bed.
SMALLER = (1.0, 0.97, 0.94, 0.9)


@dataclass(frozen=True)
class Printed:
    """The printable loop: its ``assembly``, the ``realization`` (and ``effector``) it was
    built on, the design ``loop``, which ``candidate`` that was, the ``base`` and the
    ``report`` (JSON-ready)."""

    assembly: Assembly
    realization: Realization
    effector: object | None
    loop: int
    candidate: str
    base: base.Base | None
    report: dict


def stage(progress: Progress | None, lo: float, hi: float) -> Progress | None:
    """``progress`` mapped onto ``[lo, hi]`` of a larger task (None stays None)."""
    if progress is None:
        return None
    return lambda f, msg: progress(lo + (hi - lo) * f, msg)


def _cut_words(layouts: Iterable[joints.Joint]) -> str:
    """Which bars a joint cuts across their centre line (:func:`joints.cut_sides`), in words."""
    return "; ".join(f"the bar of link {(j.index + k) % 6} is cut across its core at joint "
                     f"{j.index} (it runs close along the axis into the room of the "
                     "neighbour's boss or of the joint's hardware)"
                     for j in layouts for k in (0, 1) if j.cut[k])


#: How far the end-effector link's bars reach past P's corners L and R towards its centroid
#: (a fraction of the way): inside P, not on its corner.
END_INSET = 1e-4


def _fit_and_build(real: Realization, ee: object | None, plan: sizing.Plan, opts: Options,
                   keel_levels: tuple[int, ...] = (keel.WIDE,) * 6
                   ) -> tuple[Assembly, sizing.Plan, str | None]:
    """The assembly of ``plan`` and how P became part of link 3 (:mod:`endlink`'s method;
    None without an end-effector); with an automatic size it shrinks while a built link does
    not fit the bed in its print orientation; ``keel_levels``: each link's keel."""
    end_bars, el = None, None
    if ee is not None:
        from paraloop_core.fabrication import endlink

        el = endlink.end_link(ee, real.points)
        # the bars S_3 L and R E_3 end on P's corners; ending exactly there left the union
        # pinched at that point (two vertices at one position: an open mesh for a slicer):
        # a hair (END_INSET of the way to P's centroid) inside P instead
        end_bars = np.array(ee.end_link()[[0, 1, 2, 3]], float).reshape(2, 2, 3)
        mid = np.asarray(ee.effector.vertices, float).mean(axis=0)
        end_bars[0, 1] += END_INSET * (mid - end_bars[0, 1])
        end_bars[1, 0] += END_INSET * (mid - end_bars[1, 0])
    for _ in range(4):
        extras = None
        if el is not None:  # P in mm at this plan's scale
            solid = endlink.solid_manifold(el, plan.scale)
            extras = {3: (solid, parts.principal_capsules(solid))}
        asm = assembly.assemble(plan, real.points, real.joint_factors, opts.printer,
                                plan.kind, end_bars=end_bars, extras=extras,
                                keel_levels=keel_levels)
        ext = np.array([layout.laid_extent(p.manifold.to_mesh().vert_properties[:, :3],
                                           p.down) for p in asm.links])
        grow = float(bed.laid_fit_factor(ext, opts.printer).min())  # on their print flats
        if grow >= 1.0 or opts.size_mm is not None:
            break
        plan = _smaller(real, ee, plan, opts, plan.size_mm * min(grow, 0.99))
    return asm, plan, None if el is None else el.method


def _smaller(real: Realization, ee: object | None, plan: sizing.Plan, opts: Options,
             size_mm: float) -> sizing.Plan:
    """The plan of ``plan``'s joints at ``size_mm``, or a little smaller where the room
    there is not enough (the hardware's stock lengths make the room uneven in the size);
    raises :class:`sizing.NoRoomError` where none of :data:`SMALLER` has room."""
    for f in SMALLER:
        try:
            return sizing.plan(real, opts.printer, opts.material, plan.kind, opts.rod,
                               size_mm=size_mm * f, ee=ee)
        except sizing.NoRoomError as exc:
            error = exc
    raise error


def make(candidates: Iterable[choice.Candidate], opts: Options | None = None,
         drive: DriveSettings | None = None, progress: Progress | None = None,
         on_parts: Callable[[Assembly], None] | None = None) -> Printed:
    """The printable loop (module docstring); ``on_parts(assembly)`` is called with the parts
    before their verification (the export starts its STEP solids then), with None as soon as
    that verification takes a keel off (those parts are not the ones kept), and again with
    the final parts."""
    opts = opts or Options()
    ranked, tried, roomless = choice.choose(candidates, opts, stage(progress, 0.0, 0.25))
    if progress is not None:
        progress(0.25, "building the parts")
    # the best candidate that builds and stands on its base, no bar cut and its links
    # all flat on the bed; else the built one on a base with the fewest defects, standing
    # first (_built_score)
    built, error, handed = [], None, []

    def hand(asm: Assembly | None) -> None:  # the parts to the STEP helper, again where they
        # changed; None: the parts handed are rebuilt (their solids are not wanted)
        if on_parts is not None and (not handed or handed[-1] is not asm):
            handed.append(asm)
            on_parts(asm)

    thin = sizing.LEVELS.index("thin bars")
    for cand, real, ee, plan in ranked:
        sized_level = plan.level
        try:
            asm, plan, ee_method = _fit_and_build(real, ee, plan, opts)
        except FabricationError as exc:  # a link cut through or pinched, or no room at the
            # size its built parts fit the bed: the next one
            if not _unbuilt(exc):
                raise
            tried.append(f"{cand.label}: not built ({exc})")
            error = exc
            continue
        asm, b, warnings = _grounded(asm, opts, progress, cand.label)
        x = _Built(cand, real, ee, plan, asm, ee_method, b, warnings)
        # built parts that fit the bed only smaller than sized, where the bars fall below
        # the floors: the next candidate sized within them is built too (_built_score)
        shrunk = plan.level >= thin > sized_level
        if _keeled(asm) and _accepted(asm, b, opts) and not shrunk:
            # its keels verified before it is taken: one taken off leaves its link over
            # supports, and the next candidate may lie flat
            hand(asm)
            settled = _settled_or_why(x, opts, progress, tried, lambda: hand(None))
            if isinstance(settled, FabricationError):  # the next candidate may print
                error = settled
                continue
            x = settled
            asm, b = x.asm, x.base
        built.append(x)
        if _accepted(asm, b, opts) and not shrunk:
            break
        if shrunk:
            tried.append(f"{cand.label}: its parts fit the bed only at {plan.size_mm:.0f} mm, "
                         "where its bars are thinner than the floors")
        lifted = _lifted(asm)
        if b is None and opts.ground:
            tried.append(f"{cand.label}: no grounding rod clears its moving links")
        elif b is not None and not b.stands:
            tried.append(f"{cand.label}: its plate does not keep the centre of mass inside")
        if lifted:
            tried.append(f"{cand.label}: link{'s' * (len(lifted) > 1)} "
                         f"{', '.join(map(str, lifted))} would print over supports")
        if choice.cut(asm.joints):
            tried.append(f"{cand.label}: {_cut_words(asm.joints)}")
    # the best built (the earlier of equals), verified; where its keels come off and a link
    # then falls apart, the next best
    for x in sorted(built, key=lambda x: _built_score(x, opts.ground), reverse=True):
        hand(x.asm)  # the STEP solids start before the verification (again if a keel comes off)
        settled = x if x.ver is not None else \
            _settled_or_why(x, opts, progress, tried, lambda: hand(None))
        if not isinstance(settled, FabricationError):
            x = settled
            break
        error = settled
    else:
        raise error
    cand, real, ee, plan, asm, ee_method, b, warnings, ver = x
    hand(asm)
    lifted = _lifted(asm)
    if lifted:
        warnings.append(f"link{'s' if len(lifted) > 1 else ''} "
                        f"{', '.join(map(str, lifted))} cannot lie on the bar's face without "
                        "breaking into a bore: printed standing on the bosses' cut faces, the "
                        "bar over supports")
    if choice.cut(asm.joints):
        warnings.append(f"{_cut_words(asm.joints)}: a crescent is left of it there (no "
                        "realization tried avoids this)")
    if cand.near_singular and drive is not None and drive.motor is not None:
        warnings.append(f"loop {cand.loop}'s cycle passes close to a singular configuration "
                        "(no realization of a loop farther from one was sized): there the "
                        f"design's motor on joint {drive.motor} can let it switch to another "
                        "branch of its motion or jam; turn it slowly near its tightest pose")
    sized = sizing.to_dict(plan, opts.printer, rows.bounds_of(real))
    level = sizing.level_warnings(plan)
    if plan.level >= thin:  # thinner than the floors: whether a larger bed brings them
        # within (the printed realization first, then the others sized, then those without
        # room here)
        others = [(c.label, r, e) for c, r, e, _ in ranked if c is not cand]
        larger = remedy.stronger_print([(cand.label, real, ee), *others, *roomless], opts,
                                       choice.plan_of)
        if larger:  # nothing where the maker fixed the size
            sized["larger_print"] = larger
            level = [f"{level[0]}; {larger['sentence']}"]
    report = {
        "choice": {"realization": cand.label, "loop": cand.loop, "tried": tried,
                   "radius": real.radius, "separation": real.separation},
        "sizing": sized,
        "joints": [joints.to_dict(j) for j in asm.joints],
        "verification": ver, "warnings": warnings + level,
        "print_flat_slack_mm": asm.slack.tolist(),
        "keels_mm": [p.keel_mm for p in asm.links]}
    # how the loop is held where no base stands on its own (None: it stands)
    if b is not None:
        report["base"] = base.to_dict(b, opts.printer.bed_mm)
        report["mount"] = None if b.stands else b.mount
    else:
        report["mount"] = stand.NO_BASE if opts.ground else \
            "exported without a base: " + stand.HOLD
    if ee_method is not None:  # how P became part of link 3 (closed, hull or thickened)
        report["end_effector"] = {"link": 3, "method": ee_method}
    masses, centers = base.link_masses(asm, opts.material.density_g_cm3)
    resting = b.link if b is not None else 0
    up = b.up if b is not None else np.array([0.0, 0.0, 1.0])
    report["drive"] = drive_mass.entry(asm.joint_factors, asm.scale, masses, centers, resting,
                                       drive, opts.material, up)
    if cand.near_singular and (drive is None or drive.motor is None):
        report["drive"]["near_singular"] = True  # a motor may switch its branch: by hand
    # turned by hand, no motor bends a bar: self-weight only (a motor's torque there, 1e3 -
    # 1e8 times a smooth loop's, would read as metres of bending)
    tq = None if drive_mass.by_hand(report["drive"]) else \
        report["drive"].get("peak_torque_n_m", plan.torque_nm)
    across = stiffness.across_gravity(asm.joint_factors, list(asm.bars), resting, up)

    def bent(torque: float | None) -> stiffness.Deflection:
        return stiffness.deflections(plan.deflection.lengths, plan.radii, across,
                                     opts.material.modulus_gpa, opts.material.density_g_cm3,
                                     torque or 0.0)

    defl = bent(tq)
    # the sizing planned the torque of its own resting link; where the base rests another
    # and the recommended motor's torque would bend links into each other, another joint
    # that holds the loop and keeps the gaps takes the motor, else none (by hand)
    closed = None if tq is None else stiffness.gap_closed(defl.total, ver["pairs"])
    if closed is not None and (drive is None or drive.motor is None):
        other = _motor_keeping_gaps(
            lambda m: drive_mass.entry(asm.joint_factors, asm.scale, masses, centers, resting,
                                       replace(drive or DriveSettings(), motor=m),
                                       opts.material, up),
            peak_speed_ratios(asm.joint_factors).max(axis=1), report["drive"]["motor"],
            lambda torque: stiffness.gap_closed(bent(torque).total, ver["pairs"]) is None)
        if other is not None:
            report["drive"] = {**other, "motor_bends_at": {"motor": report["drive"]["motor"],
                                                           **closed}}
            tq, closed = other["peak_torque_n_m"], None
            defl = bent(tq)
            was = report["drive"]["motor_bends_at"]
            report["warnings"].append(
                f"the motor is on joint {other['motor']}: on joint {was['motor']} (the "
                f"smoothest) its torque would bend links {was['links'][0]} and "
                f"{was['links'][1]} closer than 3 times their deflections")
    if closed is not None:
        report["drive"]["motor_bends"] = closed
        tq, defl = None, bent(None)
    why = drive_mass.hand_reason(report["drive"])
    if why is not None:
        report["warnings"].append(
            f"{why}: turn it by hand, holding the base and a link across the loop (the physics "
            "check does so)" + (", or design a smoother motion (the smooth-drive criterion)"
                               if drive_mass.too_slow(report["drive"]) else ""))
    report["stiffness"] = stiffness.to_dict(defl, opts.material.modulus_gpa, tq)
    report["walls"] = thickness.walls({p.name: check.part_trimesh(p.manifold)
                                       for p in asm.parts}, opts.printer.wall_mm)
    if progress is not None:
        progress(1.0, "parts verified")
    return Printed(asm, real, ee, cand.loop, cand.label, b, report)


def _motor_keeping_gaps(entry: Callable[[int], dict], worst: np.ndarray, tried: int,
                        keeps: Callable[[float], bool]) -> dict | None:
    """The drive entry (``entry(motor)``) of the smoothest motor joint (``worst`` ``(6,)``
    speed ratio per motor) other than ``tried`` that holds the loop and whose peak torque
    ``keeps`` the gaps, marked :data:`MOTOR_KEEPS_GAPS`; None where no joint does."""
    for m in np.argsort(worst, kind="stable"):
        if int(m) == tried:
            continue
        e = entry(int(m))
        if "error" not in e and not drive_mass.by_hand(e) and keeps(e["peak_torque_n_m"]):
            return {**e, "motor_chosen": MOTOR_KEEPS_GAPS}
    return None


def _unbuilt(exc: FabricationError) -> bool:
    """Whether ``exc`` says a candidate's parts do not build (a link cut through or pinched,
    no room at the size they fit the bed): the next candidate is built instead."""
    return exc.reason in ("falls-apart", "not-watertight") or isinstance(exc, sizing.NoRoomError)


def _accepted(asm: Assembly, b: base.Base | None, opts: Options) -> bool:
    """Whether a built candidate is taken at once: standing on its base (or no grounding
    asked for), no link over supports, no bar cut across its core."""
    return bool((b is not None and b.stands or not opts.ground) and not _lifted(asm)
                and not choice.cut(asm.joints))


class _Built(NamedTuple):
    """A candidate of :func:`make` built and grounded (``base`` None: no grounding), and its
    verification once made (:func:`_settled`)."""

    cand: choice.Candidate
    real: Realization
    ee: object | None
    plan: sizing.Plan
    asm: Assembly
    ee_method: str | None
    base: base.Base | None
    warnings: list[str]
    ver: dict | None = None


def _grounded(asm: Assembly, opts: Options, progress: Progress | None, label: str
              ) -> tuple[Assembly, base.Base | None, list[str]]:
    """``asm`` on its grounding rod and base plate (:func:`stand.ground`), unless the options
    ask for none: ``(assembly, base or None, warnings)``."""
    if not opts.ground:
        return asm, None, []
    if progress is not None:
        progress(0.4, f"grounding {label}: rod and base plate")
    return stand.ground(asm, opts)


def _settled(x: _Built, opts: Options, progress: Progress | None, tried: list[str],
             drop: Callable[[], None] | None = None) -> _Built:
    """A built candidate ``x`` with its verification, after narrowing or taking off the keels
    it fails (:func:`keel.in_the_way`; the candidate rebuilt so, grounded and verified again;
    at most :data:`KEEL_ROUNDS` times): a link without its keel then prints over supports.
    ``drop()`` is called when the first keel comes off (the parts handed for their STEP
    solids are not kept)."""
    cand, real, ee, plan, asm, ee_method, b, warnings, _ = x
    # while a round is left, a keel that fails ends the verification (check.verify's keels):
    # the parts are built again without it; the parts kept get the whole verification
    ver = check.verify(asm, opts.samples, progress=stage(progress, 0.45, 0.95),
                       keels=[p.keel_mm for p in asm.links])
    for n in range(KEEL_ROUNDS):
        blocked = keel.in_the_way([p.keel_mm for p in asm.links], ver["pairs"])
        if not blocked:
            break
        if drop is not None and n == 0:
            drop()
        levels = tuple(max(k - 1, keel.NONE) if i in blocked else k
                       for i, k in enumerate(asm.keel_levels))
        tried.append(f"{cand.label}: the keel of link{'s' * (len(blocked) > 1)} "
                     f"{', '.join(map(str, blocked))} comes too close to another link: "
                     + ", ".join(f"link {i} {'narrowed' if levels[i] else 'without'}"
                                 for i in sorted(blocked)))
        asm, plan, ee_method = _fit_and_build(real, ee, plan, opts, levels)
        asm, b, warnings = _grounded(asm, opts, progress, cand.label)
        ver = check.verify(asm, opts.samples, progress=stage(progress, 0.45, 0.95),
                           keels=None if n == KEEL_ROUNDS - 1 else
                           [p.keel_mm for p in asm.links])
    return _Built(cand, real, ee, plan, asm, ee_method, b, warnings, ver)


def _settled_or_why(x: _Built, opts: Options, progress: Progress | None, tried: list[str],
                    drop: Callable[[], None]) -> _Built | FabricationError:
    """:func:`_settled`, or why the candidate does not print: without a keel in the way a
    link falls apart (:func:`_unbuilt`; ``tried`` says so), the next candidate may print."""
    try:
        return _settled(x, opts, progress, tried, drop)
    except FabricationError as exc:
        if not _unbuilt(exc):
            raise
        tried.append(f"{x.cand.label}: not built without its keel ({exc})")
        return exc


def _built_score(x: _Built, ground: bool) -> tuple:
    """Rank of a built candidate of :func:`make` (larger is better; ``max`` keeps the earlier,
    better sized, of equals): on a base (when grounding is asked for), then the fewest
    defects a maker would meet: links printed over supports, bars thinner than the floors
    (:data:`sizing.LEVELS`' last level), a bar cut across its core at a joint
    (:func:`joints.cut_sides`); then standing on its plate (else screwed down: the report's
    ``mount``). A grounding rod without its cap is none: it ends in a blind bore."""
    plan, asm, b = x.plan, x.asm, x.base
    defects = int(bool(_lifted(asm))) + int(plan.level >= 3) + int(choice.cut(asm.joints))
    return (b is not None or not ground, -defects, b is not None and b.stands)


def _lifted(asm: Assembly) -> list[int]:
    """The links that cannot lie on their bar's face and have no keel: printed on their
    bosses' cut faces, the bar over supports (:func:`flat.lift`)."""
    return [i for i in range(6) if not flat.lies_flat(asm.slack[i]) and not asm.links[i].keel_mm]


def _keeled(asm: Assembly) -> list[int]:
    """The links lying on a keel (:func:`parts.keeled`)."""
    return [i for i in range(6) if asm.links[i].keel_mm]
