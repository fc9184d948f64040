"""Guide renderer figures (prints, never asserts): a 1000 x 750 picture of ~50 000 triangles
(six capsules in a ring), plain and with 12 labels, a dashed axis and an arrow; and, with
``--design``, the demo pictures and ``assembly.html`` of a design's exported parts.

Run: ``.venv/bin/python benchmarks/bench_render.py [--design assets/designs/sun-disc.json]
[--out /tmp/render_demo/guide]``. Times are the best of 5 runs, wall clock and this process's
CPU time (the machine may be shared).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import trimesh

from paraloop_core.fabrication import guide_html, guide_pictures, raster, render
from paraloop_core.fabrication.export import LINK_COLORS
from paraloop_core.fabrication.render import Arrow3, Item, Label, Line3, View


def best_of(f, n: int = 5) -> tuple[float, float]:
    """Best wall and CPU seconds of ``n`` calls of ``f``."""
    wall, cpu = np.inf, np.inf
    for _ in range(n):
        w0, c0 = time.perf_counter(), time.process_time()
        f()
        wall, cpu = min(wall, time.perf_counter() - w0), min(cpu, time.process_time() - c0)
    return wall, cpu


def ring_scene() -> tuple[list[Item], list[Label], list]:
    items, labels = [], []
    for k in range(6):
        a = 2 * np.pi * k / 6
        m = trimesh.creation.capsule(height=60.0, radius=8.0, count=[64, 64])
        m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
        m.apply_transform(trimesh.transformations.rotation_matrix(a, [0, 0, 1]))
        m.apply_translation([60 * np.cos(a), 60 * np.sin(a), 10 * (k % 2)])
        color = tuple(int(c) for c in LINK_COLORS[k])
        items.append(Item(m, color))
        labels += [Label(f"link {k}", m.centroid, color, item=k),
                   Label(f"joint {k}", m.vertices[np.argmax(m.vertices[:, 2])], (30, 30, 30))]
    lines = [Line3((0, 0, -40), (0, 0, 60), dashed=True), Arrow3((90, 90, 40), (40, 40, 20))]
    return items, labels, lines


def synthetic() -> None:
    items, labels, lines = ring_scene()
    n = sum(len(it.mesh.faces) for it in items)
    view = View()
    print(f"synthetic ring: {n} triangles, {view.size[0]} x {view.size[1]} px, "
          f"supersample {view.supersample}")
    render.render(items, view=view)  # warm (font, caches)
    for name, f in (("picture, no labels", lambda: render.render_image(items, view=view)),
                    ("picture + 12 labels, axis, arrow",
                     lambda: render.render_image(items, labels, lines, view)),
                    ("PNG bytes + labels", lambda: render.render(items, labels, lines, view)),
                    ("coverage 200 x 150 (view choice)",
                     lambda: render.Coverage(items).seen(View(size=(200, 150), supersample=1)))):
        wall, cpu = best_of(f)
        print(f"  {name:34s} {wall * 1e3:7.1f} ms wall {cpu * 1e3:7.1f} ms cpu")
    cam = render.camera(view, np.concatenate([it.mesh.vertices for it in items]))
    layers = [render._layer(it, cam, 0.77) for it in items]
    xy = np.concatenate([la.xy for la in layers])
    z = np.concatenate([la.depth for la in layers])
    wall, cpu = best_of(lambda: raster.rasterize(xy, z, cam.shape))
    print(f"  {'z-buffer alone (front faces)':34s} {wall * 1e3:7.1f} ms wall {cpu * 1e3:7.1f} "
          f"ms cpu ({len(xy)} front faces)")


def demo_guide(asm, report: dict) -> guide_html.Guide:
    """A demo page over today's parts (the lead's guide replaces it)."""
    sz = report.get("sizing", {})
    spec = asm.spec
    layout = {p["name"]: p for p in report["print_layout"]["parts"]}
    steps = [guide_html.Step(
        f"joint {j}" + (": close the loop" if j == 5 else ""),
        f"Slide the bore of link {(j + 1) % 6} (blue) onto the pin of link {j} (yellow), "
        "along the dashed axis, the way the red arrow points.",
        (guide_html.Picture(f"assembly_where_{j}.png", f"where joint {j} is"),
         guide_html.Picture(f"assembly_joint_{j}.png", f"joint {j} pulled apart")))
        for j in range(6)]
    return guide_html.Guide(
        title="paraloop: assembly guide (demo)",
        summary="Six printed links form a closed 6R loop that turns inside out.",
        warnings=("The pins are not retained: they slide in their bores.",),
        facts=(guide_html.Fact("size", f"{spec.size_mm:.0f} mm"),
               guide_html.Fact("pins", f"radius {spec.pin_radius_mm:.2f} mm, bores "
                               f"{spec.pin_radius_mm + spec.clearance_mm:.2f} mm"),
               guide_html.Fact("printer", str(sz.get("printer", "generic")))),
        overview=(guide_html.Picture("assembly_loop.png", "the assembled loop",
                                     "The assembled loop: links and joints."),),
        profiles=(guide_html.PrintProfile("PLA", (
            guide_html.Fact("layer height", f"<= {min(0.2, spec.clearance_mm / 1.5):.2f} mm"),
            guide_html.Fact("supports", "on"))),),
        parts=tuple(guide_html.PartRow(f"{p.name}.stl", str(layout[p.name]["plate"]),
                                       f"on its flattest face ({layout[p.name]['contact_mm2']:.0f}"
                                       " mm² contact)") for p in asm.parts),
        steps=tuple(steps))


def demo(design: str, out: Path) -> None:
    from paraloop_core import design as design_mod
    from paraloop_core import pipeline
    from paraloop_core.fabrication import printable

    d = design_mod.load_design(design)
    sol = pipeline.solve(d)
    result = printable.export_printable(sol.realization, samples=60, effector=sol.end_effector,
                                        fixed=dict(d.realization.fixed),
                                        alternatives=sol.other_loops())
    asm = result.assembly
    out.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    scenes = guide_pictures.assembly_scenes(asm)
    compose = time.perf_counter() - t
    print(f"{design}: {sum(len(p.manifold.to_mesh().tri_verts) for p in asm.parts)} triangles; "
          f"composition (view choice) {compose:.2f} s")
    for name, scene in scenes:
        t = time.perf_counter()
        (out / name).write_bytes(scene.png())
        print(f"  {name:24s} {(time.perf_counter() - t) * 1e3:6.0f} ms")
    (out / "assembly.html").write_bytes(guide_html.guide_html(demo_guide(asm, result.report)))
    print(f"  wrote {out}/assembly.html")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--design")
    parser.add_argument("--out", default="/tmp/render_demo/guide")
    args = parser.parse_args()
    synthetic()
    if args.design:
        demo(args.design, Path(args.out))
