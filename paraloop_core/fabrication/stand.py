"""The loop on its stand: the grounded joint re-laid on a steel rod whose foot is held by the
base plate (:mod:`base`), the rod's printed cap keeping the moving link on (or, without the
cap, the floor of that link's blind bore past the rod's tip), the plate grown for the built
parts' centre of mass.

:func:`ground` ranks the rods :func:`base.ground` finds (best first), tries the stock rods
whose bore leaves both grounded links a print flat (:func:`rods`), and keeps the first whose
two links still build whole and lie flat; without the cap only where no rod and side holds
one (nor cuts a bar); the assembly unchanged, with :data:`NO_BASE`, where no rod clears the
moving links.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import (
    assembly,
    base,
    flat,
    joints,
    parts,
    profiles,
    sizing,
    stiffness,
)
from paraloop_core.fabrication.assembly import Assembly
from paraloop_core.fabrication.profiles import Options, Rod

#: Grounding rods tried (best first) until one leaves both its links flat on the bed.
GROUND_TRIES = 4


def ground(asm: Assembly, opts: Options) -> tuple[Assembly, base.Base | None, list[str]]:
    """The assembly standing on its base (module docstring of :mod:`base`), the grounded joint
    re-laid for the rod and its two links rebuilt: the best base whose two links still lie
    flat on the bed and hold together; unchanged with a warning where no rod clears the
    moving parts."""
    warnings = []
    ranked = base.ground(asm, opts.material.density_g_cm3, opts.printer.bed_mm, opts.rod,
                         opts.printer.clearance_mm)
    if not ranked:  # then a rod that keeps the least gap, though not the stiffness margin
        ranked = base.ground(asm, opts.material.density_g_cm3, opts.printer.bed_mm, opts.rod,
                             opts.printer.clearance_mm,
                             need=np.full((6, 6), stiffness.MIN_GAP_MM))
        if ranked:
            warnings.append(f"the grounding rod keeps {ranked[0].clearance_mm:.1f} mm from "
                            "the moving links: more than the least gap, less than three times "
                            "their predicted deflection")
    if opts.ground_link is not None and ranked:
        mine = [b for b in ranked if b.link == opts.ground_link]
        if not mine:
            warnings.append(f"no grounding rod on link {opts.ground_link} clears the moving "
                            f"links over the whole cycle: the rod holds link "
                            f"{ranked[0].link} instead")
        ranked = mine or ranked
    # best first: both links flat with the rod's cap, the cap on support, flat without the
    # cap (a blind bore's floor holds the turning link), neither; without the cap only where
    # no rod and side holds one; a rod whose cap's room cuts across a bar
    # (:func:`joints.cut_sides`) only where no other holds
    tries = [(b, rod) for b in ranked[:GROUND_TRIES] for rod in rods(asm, b, opts)]
    cut = None
    for cap in (True, False):
        fallback = None
        for b, rod in tries:
            try:
                grounded = on_rod(asm, replace(b, rod=rod), opts, cap)
            except FabricationError as exc:  # this rod or side leaves a link in pieces
                if exc.reason not in ("falls-apart", "bad-parameters", "not-watertight"):
                    raise
                continue
            if any(grounded[0].joints[b.joint].cut):
                cut = cut or grounded  # make() names the bar
                continue
            if all(flat.lies_flat(grounded[0].slack[i]) for i in (b.joint, (b.joint + 1) % 6)):
                return (*grounded, warnings)
            fallback = fallback or grounded  # make() names the links not flat
        if fallback is not None:
            return (*fallback, warnings)
    if cut is not None:
        return (*cut, warnings)
    return asm, None, warnings + [NO_BASE]


def rods(asm: Assembly, b: base.Base, opts: Options) -> list[Rod]:
    """Stock rods up to the maker's, thickest first, whose bore leaves both links of the
    grounded joint a print flat (:mod:`flat`, at most two); the maker's rod when none does
    (those links then print with supports)."""
    stock = sorted((rod for rod in profiles.RODS.values() if rod.d_mm <= opts.rod.d_mm),
                   key=lambda rod: (rod != opts.rod, -rod.d_mm))
    side = 0 if b.link == b.joint else 1
    fits = []
    for rod in stock:
        j = rod_joint(asm, b.joint, opts, rod, side, True)
        if all(flat.lies_flat(asm.plan.radii[i] * sizing.APOTHEM - flat.least_depth(
                (asm.bars[i][0][0], asm.bars[i][-1][1]),
                [(j if i == b.joint else asm.joints[i], False),
                 (j if (i - 1) % 6 == b.joint else asm.joints[(i - 1) % 6], True)],
                opts.printer.wall_mm)) for i in (b.joint, (b.joint + 1) % 6)):
            fits.append(rod)
    return fits[:2] or [opts.rod]


def rod_joint(asm: Assembly, joint: int, opts: Options, rod: Rod, side: int, cap: bool
               ) -> joints.Joint:
    """Joint ``joint`` of ``asm`` laid out anew as the grounded joint on ``rod``."""
    old = asm.joints[joint]
    r = asm.plan.radii
    return joints.layout(joint, old.origin, old.at(old.length), old.w,
                         assembly.bar_vectors(asm, joint), (r[joint], r[(joint + 1) % 6]),
                         old.boss_radius, "rod", opts.printer, eps=parts.EPS_MM, rod=rod,
                         rod_side=side, cap=cap)


#: How to hold a loop without a base, and why it has none.
HOLD = ("hold it by a link (clamp or screw the link's boss to a stand) or hang it by a link "
        "on a string")
NO_BASE = ("no grounding rod clears the moving links over the whole cycle: exported without a "
           "base; " + HOLD)
#: Plates built for one grounding: the first, then grown for the measured centre of mass.
PLATE_ROUNDS = 3


def on_rod(asm: Assembly, b: base.Base, opts: Options, cap: bool = True
            ) -> tuple[Assembly, base.Base]:
    """``asm`` with joint ``b.joint`` laid out for the rod, the plate and the rod added."""
    side = 0 if b.link == b.joint else 1
    new = rod_joint(asm, b.joint, opts, b.rod, side, cap)
    asm = assembly.relay(asm, b.joint, new)
    rod_piece = new.axle
    cap_end = new.at(rod_piece.s1 if side == 0 else rod_piece.s0)  # the rod's upper end
    b = replace(b, top=cap_end)
    bare = replace(asm, hardware=tuple(h for h in asm.hardware if h.role != "rod"))
    for n in range(PLATE_ROUNDS):
        asm = assembly.with_parts(bare, (base.plate_part(b, opts.printer.wall_mm),),
                                  (base.rod_hardware(b, cap_end),), b)
        b = base.final(asm, b, opts.material.density_g_cm3)
        if b.stands or n == PLATE_ROUNDS - 1:
            break
        # the plate was chosen with predicted masses: where the built parts' centre of mass
        # comes nearer its rim than the margin, a plate for the measured path (bed allowing)
        grown = base.refit(b, b.rod, opts.printer.wall_mm, opts.printer.bed_mm)
        if grown is None:
            break
        b = grown
    return replace(asm, base=b), b
