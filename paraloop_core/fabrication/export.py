"""Export (STL per link, 3MF with named bodies, GLB assembly, JSON report) and verification.

**Verification** (:func:`verify_assembly`), after every export: each part must be a valid
manifold and watertight (trimesh); for every pair of parts and each of ``samples`` evenly
spaced parameters ``u_k = k / samples`` the moving part is placed by the relative link pose
(scaled to mm) and

* a broad phase bounds the gap from below by the parts' bounding capsules (each part lies in
  the union of its capsules); only where that bound is below ``search_mm`` does manifold3d
  compute the exact gap (``min_gap``) and, on contact, the intersection volume;
* adjacent parts (joint J): the intended contacts are excluded explicitly with the joint zone
  ``W_J`` (:func:`parts.zone_solid`). Inside it each part lies in a solid of revolution about
  the shared axis (:func:`parts.zone_hulls`: boss region, pin, head), and the relative motion
  is a rotation about that axis, so (i) the hardware of the two parts keeps its designed gap
  (pin in bore, boss ends; measured once at home: ``joint_clearance_mm``), (ii) the gap
  between one part's hull and the other part outside ``W_J`` is the same at every angle
  (measured once, minus the polygon error: ``joint_zone_gap_mm``), and (iii) the parts outside
  ``W_J`` are checked at every sample like any other pair;
* continuity: the gap at any parameter between samples is at least the gap at the nearest
  sample minus a displacement bound (points of the moving part within its bounding sphere,
  mm): the smaller of :func:`motion_bound.displacement_bounds` (speed) and
  :func:`motion_bound.chain_displacement_bounds` (joint angles; finite near a singular
  pose, alone where no speed bound exists). ``continuous_min_gap_mm > 0`` for every pair
  certifies the parts collision-free over the whole continuous cycle.
"""

from __future__ import annotations

import itertools
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING

import manifold3d as m3d
import numpy as np
import trimesh

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import carve, endlink, grounding, guide, meshing, parts, voxelspace
from paraloop_core.fabrication.parts import (
    Assembly,
    Part,
    PartSpec,
    design_scale,
    resolve_spec,
    zone_hulls,
    zone_solid,
)
from paraloop_core.linkage import loops
from paraloop_core.realization.clearance import segment_distance
from paraloop_core.realization.motion_bound import sound_displacement_bounds, try_motion_bound

if TYPE_CHECKING:
    from paraloop_core.realization.ee_certificate import EndEffectorRealization
    from paraloop_core.realization.endeffector import EndEffector

Progress = Callable[[float, str], None]
#: Exact (manifold3d) gap checks one pair may spend refining between samples; beyond it the
#: pair's continuous bound stays as far as proven (``ok`` false if that is not > 0).
MAX_EXACT_CHECKS = 3000
#: RGB of links 0..5 in the exported assembly (and the animated glTF).
LINK_COLORS = np.array([[150, 150, 150], [220, 60, 60], [60, 160, 70], [240, 140, 30],
                        [60, 110, 220], [170, 80, 200]], np.uint8)


def part_trimesh(part: Part) -> trimesh.Trimesh:
    """The part as a merged trimesh (mm, home frame)."""
    mesh = part.manifold.to_mesh()
    return trimesh.Trimesh(np.asarray(mesh.vert_properties[:, :3], float),
                           np.asarray(mesh.tri_verts, np.int64), process=True)


def _mm_poses(asm: Assembly, u: np.ndarray) -> np.ndarray:
    """Link poses ``(T, 6, 4, 4)`` with translations in mm."""
    mats = dq.to_matrix(loops.link_poses(asm.joint_factors, poly.param_to_t(u)))
    mats[..., :3, 3] *= asm.scale
    return mats


def _capsule_gap(ca: tuple, cb: tuple, rel: np.ndarray) -> np.ndarray:
    """Lower bound ``(T,)`` of the gap between capsule sets ``(segments, radii)``, b moved."""
    seg_b = np.einsum("tij,nkj->tnki", rel[:, :3, :3], cb[0]) + rel[:, None, None, :3, 3]
    d = segment_distance(ca[0][None, :, None, 0], ca[0][None, :, None, 1],
                         seg_b[:, None, :, 0], seg_b[:, None, :, 1])
    return (d - ca[1][None, :, None] - cb[1][None, None, :]).min(axis=(1, 2))


def _caps(part: Part, drop_joint: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    keep = part.joint != drop_joint if drop_joint is not None else np.ones(len(part.radii), bool)
    return part.capsules[keep], part.radii[keep]


def _affine(m: np.ndarray) -> list:
    return [list(map(float, row)) for row in m[:3, :4]]


def _pair_gaps(asm: Assembly, a: int, b: int, ma: m3d.Manifold, mb: m3d.Manifold, caps: tuple,
               u: np.ndarray, search: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Gap (capped at ``search``; capsule bound where that is larger), intersection volume
    ``(T,)`` of solids ``ma`` (part a) and ``mb`` (part b moved) at parameters ``u``, and the
    number of exact (manifold3d) checks."""
    poses = _mm_poses(asm, u)
    rel = np.linalg.inv(poses[:, a]) @ poses[:, b]  # part b in part a's home frame, mm
    lb = _capsule_gap(caps[0], caps[1], rel)
    gap = np.maximum(lb, search)
    vol = np.zeros(len(u))
    for s in np.nonzero(lb < search)[0]:
        moved = mb.transform(_affine(rel[s]))
        gap[s] = ma.min_gap(moved, search)
        if gap[s] <= 0.0:
            vol[s] = (asm.parts[a].manifold ^ asm.parts[b].manifold.transform(
                _affine(rel[s]))).volume()
    return gap, vol, int(np.sum(lb < search))


def _subsamples(u: np.ndarray, idx: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """``counts[i]`` (at most 64) new parameters spread over the cell of sample ``u[idx[i]]``
    (halfway to its cyclic neighbours)."""
    nxt = np.append(u[1:], u[0] + 1.0)
    prv = np.insert(u[:-1], 0, u[-1] - 1.0)
    n = np.clip(counts, 1, 64).astype(int)
    cell = np.repeat(np.asarray(idx), n)  # cell of each new parameter
    k = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)  # its index within the cell
    lo, hi = (u[cell] + prv[cell]) / 2, (u[cell] + nxt[cell]) / 2
    return np.unique((lo + (hi - lo) * (k + 0.5) / np.repeat(n, n)) % 1.0)


def _step_motion(asm: Assembly, a: int, b: int, center: np.ndarray, bound, reach: float,
                 u: np.ndarray) -> np.ndarray:
    """How far (mm) part b's points within ``reach`` of ``center`` (design units) move,
    relative to part a, about each sample ``u`` (:func:`sound_displacement_bounds`)."""
    return asm.scale * sound_displacement_bounds(asm.joint_factors, a, b, center,
                                                 reach / asm.scale, u, bound)


def verify_assembly(asm: Assembly, samples: int = 720, search_mm: float | None = None,
                    progress: Progress | None = None) -> dict:
    """Check watertightness and pairwise clearance over the cycle (module docstring); returns
    the JSON-ready report (``ok``, ``min_gap_mm``, ``continuous_min_gap_mm``, per pair)."""
    if samples < 8:
        raise FabricationError("verification needs at least 8 samples", "bad-parameters")
    t0 = time.perf_counter()
    search = max(2.0, 4.0 * asm.spec.clearance_mm) if search_mm is None else float(search_mm)
    parts = asm.parts
    part_info = []
    for p in parts:
        tm = part_trimesh(p)
        part_info.append({"name": p.name, "watertight": bool(tm.is_watertight),
                          "pieces": len(p.manifold.decompose()),
                          "manifold_status": str(p.manifold.status()),
                          "volume_mm3": float(p.manifold.volume()),
                          "triangles": int(p.manifold.num_tri())})
    # uniform in u plus uniform in each norm factor's rotation angle: a fast turn (the
    # motion near a singular pose) gets its share of samples instead of endless refinement
    jf = asm.joint_factors
    fast = poly.t_to_param(poly.cycle_parameters(
        jf[:3, 0], np.linalg.norm(jf[:3, 1:4], axis=-1), max(samples // 3, 8))) % 1.0
    u0 = np.unique(np.concatenate([np.arange(samples) / samples, fast]))
    pairs_out, joint_gaps = [], []
    for k, (a, b) in enumerate(itertools.combinations(range(6), 2)):
        if progress is not None:
            progress(k / 15, f"verifying links {a} and {b}")
        pa, pb = parts[a], parts[b]
        joint = a if b == a + 1 else (5 if (a, b) == (0, 5) else None)
        const = np.inf  # time-independent part of the gap (adjacent parts)
        ma, mb = pa.manifold, pb.manifold
        if joint is not None:
            z = asm.zones[joint]
            w = zone_solid(z, asm.spec.segments)
            ma, mb = ma - w, mb - w
            hull_lo, hull_up = zone_hulls(z, asm.spec)
            lo, up = (pa, pb) if joint == a else (pb, pa)
            # Each side's part inside W lies in its hull, a solid of revolution about the
            # shared axis: its gap to the other part outside W is the same for every angle
            # (up to the polygon error of the hull).
            poly_err = (z.radius + z.eps) * (1.0 - np.cos(np.pi / asm.spec.segments))
            raw = min(hull_lo.min_gap(up.manifold - w, search),
                      hull_up.min_gap(lo.manifold - w, search))
            const = raw - poly_err if raw < search else np.inf
            joint_gaps.append(lo.manifold.min_gap(up.manifold, search))
        caps = (_caps(pa, joint), _caps(pb, joint))
        # Continuity: bounding sphere of the moving part (mm -> design units for the bound).
        ends = pb.capsules.reshape(-1, 3)
        center = 0.5 * (ends.min(0) + ends.max(0))
        reach = float(np.max(np.linalg.norm(ends - center, axis=1)) + pb.radii.max())
        bound = try_motion_bound(asm.joint_factors, a, b, center / asm.scale)

        gap, vol, n_exact = _pair_gaps(asm, a, b, ma, mb, caps, u0, search)
        u = u0
        for _ in range(4):  # refine cells whose motion bound exceeds their gap
            delta = _step_motion(asm, a, b, center / asm.scale, bound, reach, u)
            bad = np.nonzero((gap - delta <= 0) & (gap > 0))[0]
            if not len(bad) or np.any(vol > 1e-9):  # certified, or a collision anyway
                break
            new = _subsamples(u, bad, np.ceil(2 * delta[bad] / gap[bad]))
            if n_exact + len(new) > MAX_EXACT_CHECKS:  # unproven: the report says so
                break
            g_new, v_new, n_new = _pair_gaps(asm, a, b, ma, mb, caps, new, search)
            n_exact += n_new
            order = np.argsort(np.concatenate([u, new]))
            u = np.concatenate([u, new])[order]
            gap, vol = np.concatenate([gap, g_new])[order], np.concatenate([vol, v_new])[order]
        else:  # all rounds refined: the bound of the final samples
            delta = _step_motion(asm, a, b, center / asm.scale, bound, reach, u)
        i_min = int(np.argmin(gap))
        pairs_out.append({
            "links": [a, b], "adjacent": joint is not None,
            "min_gap_mm": float(min(gap[i_min], const)), "at_u": float(u[i_min]),
            "continuous_min_gap_mm": float(min(np.min(gap - delta), const)),
            "joint_zone_gap_mm": float(min(const, search)) if joint is not None else None,
            "max_step_motion_mm": float(delta.max()),
            "samples": int(len(u)),
            "exact_checks": n_exact,
            "colliding_samples": int(np.sum(vol > 1e-9)),
            "max_intersection_mm3": float(vol.max()),
        })
    watertight = all(p["watertight"] and p["manifold_status"] == "Error.NoError"
                     and p["pieces"] == 1 for p in part_info)
    collisions = sum(p["colliding_samples"] for p in pairs_out)
    cont = min(p["continuous_min_gap_mm"] for p in pairs_out)
    report = {
        "ok": bool(watertight and collisions == 0 and cont > 0),
        # a gap under half the clearance may fuse in printing
        "printable": bool(min(p["min_gap_mm"] for p in pairs_out)
                          >= 0.5 * asm.spec.clearance_mm),
        "watertight": watertight,
        "samples": samples,
        "max_pair_samples": max(p["samples"] for p in pairs_out),
        "search_mm": search,
        "min_gap_mm": min(p["min_gap_mm"] for p in pairs_out),
        "continuous_min_gap_mm": cont,
        "max_step_motion_mm": max(p["max_step_motion_mm"] for p in pairs_out),
        "joint_clearance_mm": float(min(joint_gaps)),
        "collisions": int(collisions),
        "method": "gaps at evenly spaced u by manifold3d min_gap (capsule broad phase), "
                  "intersection volume on contact; continuous bound = gap - max motion of "
                  "the moving part between samples (the smaller of the Bernstein speed bound "
                  "and the joint-angle bound); adjacent parts "
                  "exclude the joint zone, whose hardware is a solid of revolution",
        "parts": part_info,
        "pairs": pairs_out,
        "seconds": time.perf_counter() - t0,
    }
    if progress is not None:
        progress(1.0, "verification done")
    return report


@dataclass(frozen=True)
class ExportResult:
    """Files ``(name, bytes)``, the JSON-ready report (also among the files) and the
    ``assembly`` they were made of."""

    files: list[tuple[str, bytes]]
    report: dict
    assembly: Assembly | None = None


#: Build volume (mm) the plates are laid out for unless a printer is given (``sizing``).
DEFAULT_BED_MM = (250.0, 210.0, 210.0)


def export_assembly(asm: Assembly, *, verify: bool = True, samples: int = 720,
                    extra_report: dict | None = None, bed_mm: tuple = DEFAULT_BED_MM,
                    with_guide: bool = True, rhino: bool = False,
                    progress: Progress | None = None) -> ExportResult:
    """STL per part (home pose), ``paraloop.3mf`` (named parts laid out on the bed
    ``bed_mm`` in print orientation; more plates as ``paraloop_plate<k>.3mf``),
    ``assembly.glb`` (home pose, coloured), with ``with_guide`` the assembly guide
    (:mod:`guide`), with ``rhino`` ``paraloop.3dm`` (:mod:`rhino`), and ``report.json``.
    Raises :class:`FabricationError` (``not-watertight``) if a part is not watertight."""
    meshes = {}
    files: list[tuple[str, bytes]] = []
    for p in asm.parts:
        tm = part_trimesh(p)
        if not tm.is_watertight:
            raise FabricationError(f"{p.name} is not watertight", "not-watertight")
        meshes[p.name] = tm
        files.append((f"{p.name}.stl", tm.export(file_type="stl")))
    layout = guide.bed_layout(meshes, bed_mm, asm.spec.print_in_place)
    files += guide.plate_files(meshes, layout)
    if with_guide:
        files += guide.guide_pages(asm, meshes, layout, bed_mm)
    glb = trimesh.Scene()
    for p in asm.parts:
        tm = meshes[p.name].copy()
        tm.visual.face_colors = np.append(LINK_COLORS[p.link], 255)
        glb.add_geometry(tm, node_name=p.name, geom_name=p.name)
    files.append(("assembly.glb", glb.export(file_type="glb")))
    if rhino:
        from paraloop_core.fabrication import rhino as rhino_mod  # optional dependency

        files.append(("paraloop.3dm", rhino_mod.assembly_3dm(
            meshes, {p.name: LINK_COLORS[p.link] for p in asm.parts})))
    report = {"scale_mm_per_unit": asm.scale, "spec": asdict(asm.spec),
              "parts": [{"name": name, "obb_extents_mm":  # for bed fit and the part list
                         np.sort(tm.bounding_box_oriented.primitive.extents).tolist()}
                        for name, tm in meshes.items()],
              "print_layout": guide.layout_entry(layout, bed_mm), **(extra_report or {})}
    if verify:
        report["verification"] = verify_assembly(asm, samples, progress=progress)
    files.append(("report.json", report_json(report)))
    return ExportResult(files, report, asm)


def report_json(report: dict) -> bytes:
    """``report.json``'s bytes, strict JSON (a non-finite number, e.g. an unbounded gap,
    is written as null)."""
    def finite(x):
        if isinstance(x, dict):
            return {k: finite(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [finite(v) for v in x]
        return None if isinstance(x, float) and not np.isfinite(x) else x

    return json.dumps(finite(report), indent=2, allow_nan=False).encode()


def stage(progress: Progress | None, lo: float, hi: float) -> Progress | None:
    """Map a sub-task's progress in [0, 1] onto [lo, hi] of the caller's."""
    if progress is None:
        return None
    return lambda f, msg: progress(lo + (hi - lo) * f, msg)


#: Extra polygon segments tried when a part is not watertight as a slicer reads it: a boolean
#: can pinch two vertices onto one point (random design 49: a valid manifold3d mesh with two
#: vertices at the same float32 position), which another tessellation does not.
RETESSELLATE = (0, 2, 6)


def export_parts(joint_factors: np.ndarray, points: np.ndarray, radius: float, *,
                 spec: PartSpec | None = None, ground: bool = True, ground_axis: int | None = None,
                 ground_link: int | None = None,
                 ground_z: float | None = None,
                 space_radius: float | Sequence[float] | None = None,
                 resolution: int | None = None,
                 order: Sequence[tuple[int, int]] = carve.DEFAULT_ORDER, samples: int = 720,
                 effector: EndEffector | EndEffectorRealization | None = None,
                 progress: Progress | None = None, verify: bool = True,
                 bed_mm: tuple = DEFAULT_BED_MM, with_guide: bool = True,
                 rhino: bool = False) -> ExportResult:
    """Parts of a realized loop (``joint_factors`` ``(6, 8)``, ``points`` ``(12, 3)``, bar
    ``radius``, design units) at ``spec.size_mm``, with a grounding column (``ground``; on
    ``ground_link`` along ``ground_axis``, default the best, see :mod:`grounding`;
    ``ground_z`` in design units) and, if ``space_radius`` is given (one value:
    base link twice; or six, e.g. ``Realization.design_space_radii``), carved design spaces as
    link bodies (:func:`carve_design_spaces`); exported and verified. ``effector``: the
    end-effector (``Solution.end_effector`` or its ``EndEffector``; None: none): link 3 is then
    the bars ``S_3 L``, ``R E_3`` and P's solid (:mod:`endlink`), not the bar ``S_3 E_3``.
    ``bed_mm``, ``with_guide``, ``rhino``: as :func:`export_assembly`."""
    pts = np.asarray(points, float)
    spec = spec or PartSpec()
    scale = design_scale(pts, spec.size_mm)
    rs = resolve_spec(spec, float(radius), scale)
    report: dict = {}
    el = None if effector is None else endlink.end_link(effector, pts)
    solid = None if el is None else endlink.solid_manifold(el, scale)
    bodies = None
    if space_radius is not None:
        cv, bodies = carve_design_spaces(joint_factors, pts, radius, space_radius, spec=spec,
                                         resolution=resolution, order=order, effector=effector,
                                         progress=stage(progress, 0.0, 0.4))
        report["carving"] = {**cv.report, "meshed": [b is not None for b in bodies]}
    extras = None
    if ground:
        gz = _zones_extent(rs)
        bars = [pts[[2 * i, 2 * i + 1]][None] * scale for i in range(6)]
        if el is not None:
            bars[3] = el.bars * scale
        zones = parts.joint_zones(joint_factors, pts * scale, rs, bars)
        splits = [z.split / z.length if z.length > 0 else 0.5 for z in zones]
        end_caps = None if el is None else \
            [(p0, p1, rs.rho_mm / scale) for p0, p1 in el.bars] + \
            [(c[0] / scale, c[1] / scale, c[2] / scale) for c in parts.principal_capsules(solid)]
        g = grounding.ground_column(
            joint_factors, pts, bar_radius=rs.rho_mm / scale, hub_radius=gz[0] / scale,
            hub_extent=gz[1] / scale, link=ground_link, axis=ground_axis,
            pin_heads=rs.print_in_place,
            ground_z=ground_z, end_link=end_caps, splits=splits)
        top, bottom = g.top * scale, g.bottom * scale
        # start 1 mm (at most half its length) inside the base link's boss: no touching faces
        z = zones[g.axis]  # link g holds the lower boss of joint g, the upper one of joint g-1
        boss = z.split - z.gap / 2 if g.axis == g.link else z.length - z.split - z.gap / 2
        top = top + (top - bottom) / np.linalg.norm(top - bottom) * min(1.0, 0.5 * boss)
        foot0 = np.array([bottom[0], bottom[1], g.ground_z * scale])
        foot1 = foot0 + [0.0, 0.0, g.foot_height * scale]
        r, rf = g.radius * scale, g.foot_radius * scale
        extras = {g.link: [
            (parts.cylinder(top, bottom, r, rs.segments), np.stack([top, bottom]), r),
            (parts.cylinder(foot0, foot1, rf, rs.segments), np.stack([foot0, foot1]), rf)]}
        report["grounding"] = {"link": g.link, "axis": g.axis, "ground_z_mm": g.ground_z * scale,
                               "column_radius_mm": r, "certified_clearance_mm":
                                   g.clearance * scale,
                               "sampled_clearance_mm": g.sampled_clearance * scale}
    if progress is not None:
        progress(0.45, "building parts")
    for more in RETESSELLATE:
        asm = parts.build_assembly(joint_factors, pts, radius,
                                   replace(spec, segments=spec.segments + more), bodies, extras,
                                   None if el is None else (el.bars, solid))
        if el is not None:  # P is cut only where it would enter a joint's hardware zone
            report["end_effector"] = {"method": el.method, "volume_mm3": solid.volume(),
                                      "kept_mm3": (asm.parts[3].manifold ^ solid).volume()}
        try:
            return export_assembly(asm, verify=verify, samples=samples, extra_report=report,
                                   bed_mm=bed_mm, with_guide=with_guide, rhino=rhino,
                                   progress=stage(progress, 0.5, 1.0))
        except FabricationError as exc:
            if exc.reason != "not-watertight" or more == RETESSELLATE[-1]:
                raise


def carve_design_spaces(joint_factors: np.ndarray, points: np.ndarray, radius: float,
                        space_radius: float | Sequence[float], *, spec: PartSpec | None = None,
                        resolution: int | None = None,
                        order: Sequence[tuple[int, int]] = carve.DEFAULT_ORDER,
                        effector: EndEffector | EndEffectorRealization | None = None,
                        progress: Progress | None = None,
                        ) -> tuple[carve.Carving, list[tuple[np.ndarray, np.ndarray] | None]]:
    """Carve capsule design spaces of ``space_radius`` (design units; see
    :func:`voxelspace.default_spaces`) in ``order`` with joint zones sized for the hardware of
    ``spec``, and mesh them (None where a space is too thin to mesh). Meshes in home frames.
    ``resolution``: voxels along a space (None: :func:`voxelspace.auto_resolution`).
    With an ``effector`` (as in :func:`export_parts`) link 3's space covers its bars ``S_3 L``,
    ``R E_3`` and P (:func:`endlink.link_space`), and P, fixed in link 3, is removed with its
    sweep from every other space before the pairwise differences."""
    pts = np.asarray(points, float)
    spec = spec or PartSpec()
    scale = design_scale(pts, spec.size_mm)
    rs = resolve_spec(spec, float(radius), scale)
    resolution = resolution or voxelspace.auto_resolution(pts, space_radius)
    spaces = voxelspace.default_spaces(pts, space_radius, resolution=resolution)
    bars, fixed = None, []
    if effector is not None:
        el = endlink.end_link(effector, pts)
        r3 = float(np.ravel(space_radius)[3 if np.ndim(space_radius) else 0])
        spaces[3] = endlink.link_space(el, r3, scale, resolution)
        bars = [el.bars if i == 3 else None for i in range(6)]
        fixed = [(3, endlink.solid_space(el, spaces[3].pitch, scale))]
    cv = carve.carve(joint_factors, pts, spaces, keep_radius=float(radius),
                     joint_radius=rs.boss_radius_mm / scale * 1.1, order=order, bars=bars,
                     fixed=fixed, progress=stage(progress, 0.0, 0.9))
    cv.report["resolution"] = resolution  # the automatic choice is worth reporting
    bodies = [_carved_body(sp) for sp in cv.spaces]
    if progress is not None:
        progress(1.0, "carved spaces meshed")
    return cv, bodies


def _carved_body(space: voxelspace.VoxelSpace) -> tuple[np.ndarray, np.ndarray] | None:
    """Mesh of a carved space (coarse first, then fine); None where it is too thin to mesh
    (the part then keeps just its bar)."""
    for stride in (2, 1):
        try:
            return meshing.space_mesh(space, stride=stride)
        except FabricationError:
            continue
    return None


def _zones_extent(spec: PartSpec) -> tuple[float, float]:
    """Hub radius and reach beyond the joint point (mm) of the joint hardware."""
    reach = spec.boss_length_mm * (2 if spec.print_in_place else 1) + \
        (spec.clearance_mm if spec.print_in_place else 0.0)
    return spec.boss_radius_mm + 0.1, reach


def export_design_parts(joint_factors: np.ndarray, points: np.ndarray, radius: float,
                        **options) -> list[tuple[str, bytes]]:
    """Files ``(name, bytes)`` for the studio's export button (options of
    :func:`export_parts`)."""
    return export_parts(joint_factors, points, radius, **options).files
