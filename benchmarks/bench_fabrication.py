"""Fabrication figures (prints, never asserts): carving six links at 128 voxels along each
design space, meshing, building and exporting the parts, verifying them over 720 samples.

Run: ``.venv/bin/python benchmarks/bench_fabrication.py [design.json] [--png docs/carved.png]``
(``--png`` also renders the carved spaces offscreen, a small numpy + PIL rasterizer).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from paraloop_core import design, pipeline
from paraloop_core.fabrication import carve, export, meshing, parts, voxelspace

COLORS = np.array([[150, 150, 150], [220, 60, 60], [60, 160, 70], [240, 140, 30],
                   [60, 110, 220], [170, 80, 200]], float)


def render(meshes: list[tuple[np.ndarray, np.ndarray]], colors: np.ndarray, path: str,
           size: int = 900) -> None:
    """Flat-shaded orthographic view (painter's algorithm) of coloured meshes to a PNG."""
    from PIL import Image, ImageDraw

    view = np.array([[0.8, -0.6, 0.0], [0.25, 0.33, 0.91], [-0.55, -0.73, 0.41]])
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    tris, cols = [], []
    for k, (v, f) in enumerate(meshes):
        tris.append((v @ view.T)[f])
        cols.append(np.repeat(colors[k][None], len(f), axis=0))
    tri, col = np.concatenate(tris), np.concatenate(cols)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
    keep = n[:, 2] > 0  # facing the viewer (+z towards the eye)
    tri, col, n = tri[keep], col[keep], n[keep]
    shade = 0.35 + 0.65 * np.clip(n @ np.array([0.3, 0.5, 0.81]), 0, 1)
    lo, hi = tri[..., :2].reshape(-1, 2).min(0), tri[..., :2].reshape(-1, 2).max(0)
    xy = (tri[..., :2] - lo) / (hi - lo).max() * (size - 40) + 20
    xy[..., 1] = size - xy[..., 1]
    img = Image.new("RGB", (size, size), "white")
    draw = ImageDraw.Draw(img)
    for i in np.argsort(tri[..., 2].mean(1)):  # far to near
        c = tuple(int(x) for x in col[i] * shade[i])
        draw.polygon([tuple(p) for p in xy[i]], fill=c)
    img.save(path)


def main(path: str = "assets/designs/sun-disc.json", png: str | None = None) -> None:
    real = pipeline.solve(design.load_design(path)).realization
    jf, pts, rho = real.joint_factors, real.points, real.radius
    space_r = float(np.median(real.design_space_radii))
    print(f"design {path}: bar radius {rho:.4g}, design-space radius {space_r:.4g}")

    spaces = voxelspace.default_spaces(pts, space_r, resolution=128)
    shapes = [sp.occupancy.shape for sp in spaces]
    print("grids:", shapes, f"({sum(int(np.prod(s)) for s in shapes) / 1e6:.2f} M voxels)")
    last = [0.0]

    def progress(f: float, msg: str) -> None:
        if f - last[0] >= 0.2 or f == 1.0:
            print(f"  [{100 * f:5.1f} %] {msg}")
            last[0] = f

    t = time.perf_counter()
    cv = carve.carve(jf, pts, spaces, keep_radius=rho, progress=progress)
    print(f"carving 6 links at 128: {time.perf_counter() - t:.2f} s, "
          f"max motion margin {cv.report['max_motion_margin']:.4g}, "
          f"bars kept {np.round(cv.report['bar_kept'], 3).tolist()}")

    t = time.perf_counter()
    bodies = [meshing.space_mesh(sp, stride=2) for sp in cv.spaces]
    print(f"meshing 6 carved spaces (stride 2): {time.perf_counter() - t:.2f} s, "
          f"{sum(len(f) for _, f in bodies)} triangles")

    if png is not None:
        t = time.perf_counter()
        bars = []  # the realized bars, dark, for context
        for i in range(6):
            m = parts.capsule(pts[2 * i], pts[2 * i + 1], rho, 16).to_mesh()
            bars.append((np.asarray(m.vert_properties[:, :3], float), np.asarray(m.tri_verts)))
        render(bodies + bars, np.concatenate([COLORS, 0.45 * COLORS]), png)
        print(f"rendered {png} in {time.perf_counter() - t:.2f} s")

    spec = parts.PartSpec(size_mm=500.0)
    t = time.perf_counter()
    asm = parts.build_assembly(jf, pts, rho, spec)
    res = export.export_assembly(asm, verify=False)
    print(f"export of all cylinder parts (build + STL/3MF/GLB): {time.perf_counter() - t:.2f} s, "
          f"{sum(len(b) for _, b in res.files) / 1e6:.2f} MB")

    t = time.perf_counter()
    ver = export.verify_assembly(asm, samples=720)
    print(f"verification at 720 samples: {time.perf_counter() - t:.2f} s, ok={ver['ok']}, "
          f"min gap {ver['min_gap_mm']:.3f} mm, continuous {ver['continuous_min_gap_mm']:.3f} mm")

    t = time.perf_counter()
    carved = parts.build_assembly(jf, pts, rho, spec, bodies)
    ver = export.verify_assembly(carved, samples=720)
    print(f"carved parts: build + verification {time.perf_counter() - t:.2f} s, ok={ver['ok']}, "
          f"min gap {ver['min_gap_mm']:.3f} mm, continuous {ver['continuous_min_gap_mm']:.3f} mm")


if __name__ == "__main__":
    args = sys.argv[1:]
    out = None
    if "--png" in args:
        out = args.pop(args.index("--png") + 1)
        args.remove("--png")
    main(*args, png=out)
