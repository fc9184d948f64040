"""STEP solids (issue 29, item 3): ``parts.step`` holds one valid closed solid per printed
part whose volume agrees with its STL within 1 %, ``assembly.step`` the parts and the
hardware; the solids and the meshes come from one :mod:`csg` tree per part. Read back with
OpenCascade's own reader, independently of the writer."""

from __future__ import annotations

import re
import types
from collections import Counter

import fab_fixtures as F
import numpy as np
import pytest
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.IFSelect import IFSelect_RetDone
from OCP.STEPControl import STEPControl_Reader
from OCP.TopAbs import TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS

from paraloop_core.fabrication import csg, export, parts, step, step_hull


def _read(data: bytes, tmp_path, name: str) -> list:
    """The solids of a STEP file, as OCP's STEPControl_Reader finds them."""
    path = tmp_path / name
    path.write_bytes(data)
    reader = STEPControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    reader.TransferRoots()
    out, ex = [], TopExp_Explorer(reader.OneShape(), TopAbs_SOLID)
    while ex.More():
        out.append(ex.Current())
        ex.Next()
    return out


def _props(solid) -> tuple[float, np.ndarray]:
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(solid, props)
    return props.Mass(), np.array(props.CentreOfMass().Coord())


def _surfaces(solid) -> Counter:
    """How many faces of each surface type (``"Plane"``, ``"Cylinder"``, ...)."""
    out, ex = Counter(), TopExp_Explorer(solid, TopAbs_FACE)
    while ex.More():
        out[BRepAdaptor_Surface(TopoDS.Face(ex.Current())).GetType().name[8:]] += 1
        ex.Next()
    return out


def _closed(solid) -> bool:
    ex = TopExp_Explorer(solid, TopAbs_SHELL)
    shells = []
    while ex.More():
        shells.append(BRep_Tool.IsClosed_s(TopoDS.Shell(ex.Current())))
        ex.Next()
    return len(shells) == 1 and shells[0]


@pytest.fixture(scope="module")
def written():
    """The fixture's printed loop (grounded on a rod and plate, M3 joints): its STEP files,
    report and STL meshes."""
    asm = F.printed().assembly
    report = {"parts": [{"name": p.name} for p in asm.parts]}
    files = dict(export.step_files(asm, report))
    return asm, files, report, export.part_meshes(asm)


def test_parts_step_has_one_valid_solid_per_part_agreeing_with_its_stl(written, tmp_path):
    asm, files, report, meshes = written
    solids = _read(files["parts.step"], tmp_path, "parts.step")
    assert len(solids) == len(asm.parts)
    props = [_props(s) for s in solids]
    unmatched = set(range(len(solids)))
    for p in asm.parts:
        mesh = meshes[p.name]
        # the solid whose centre of mass is the mesh's (the parts lie apart)
        k = min(unmatched, key=lambda i: np.linalg.norm(props[i][1] - mesh.center_mass))
        unmatched.remove(k)
        assert BRepCheck_Analyzer(solids[k]).IsValid() and _closed(solids[k]), p.name
        faces = _surfaces(solids[k])  # true round surfaces, not facets
        assert faces["Cylinder"] >= 1 and sum(faces.values()) < 150, (p.name, faces)
        if p.role == "link":  # the fillets' oblique cones: ruled (B-spline) faces
            assert faces["BSplineSurface"] >= 1, (p.name, faces)
        assert props[k][0] == pytest.approx(mesh.volume, rel=0.01), p.name
        assert np.linalg.norm(props[k][1] - mesh.center_mass) < 0.01 * mesh.scale, p.name
    assert {e["step"] for e in report["parts"]} == {"exact"}


def test_assembly_step_has_the_parts_and_the_hardware(written, tmp_path):
    asm, files, _, _ = written
    solids = _read(files["assembly.step"], tmp_path, "assembly.step")
    assert len(solids) == len(asm.parts) + len(asm.hardware)
    assert all(BRepCheck_Analyzer(s).IsValid() for s in solids)
    text = files["assembly.step"].decode(errors="replace")
    for p in asm.parts:
        assert f"'{p.name}'" in text  # each part a named product
    parts_volume = sum(m.volume for m in written[3].values())
    hardware_volume = sum(h.solid.volume() for h in asm.hardware)
    total = sum(_props(s)[0] for s in solids)
    assert total == pytest.approx(parts_volume + hardware_volume, rel=0.01)


def test_the_tree_is_the_mesh(written):
    """Each part's manifold is its csg tree's evaluation (one description, no drift)."""
    asm = written[0]
    for p in (*asm.parts, *asm.hardware):
        man = p.manifold if hasattr(p, "manifold") else p.solid
        again = csg.manifold(p.csg)
        assert again.volume() == pytest.approx(man.volume(), rel=1e-9)
        assert again.num_vert() == man.num_vert()


def test_exact_round_solids_and_faceted_meshes():
    """A cylinder of many sides is written as a true cylinder (its exact volume, not the
    polygon's); a tree holding a mesh is written as that mesh's faceted solid."""
    cyl = csg.prism(np.zeros(3), np.array([0.0, 0.0, 10.0]), 5.0, 48)
    solid, kind = step.part_solid(types.SimpleNamespace(csg=cyl, manifold=csg.manifold(cyl)))
    assert kind == "exact" and _props(solid)[0] == pytest.approx(np.pi * 25 * 10, rel=1e-9)
    hexa = csg.prism(np.zeros(3), np.array([0.0, 0.0, 10.0]), 5.0, 6)
    solid, _ = step.part_solid(types.SimpleNamespace(csg=hexa, manifold=csg.manifold(hexa)))
    assert _props(solid)[0] == pytest.approx(1.5 * np.sqrt(3) * 25 * 10, rel=1e-9)
    tree = csg.Union((csg.Mesh(csg.manifold(hexa)), cyl))
    man = csg.manifold(tree)
    solid, kind = step.part_solid(types.SimpleNamespace(csg=tree, manifold=man))
    assert kind == "faceted" and BRepCheck_Analyzer(solid).IsValid()
    assert _props(solid)[0] == pytest.approx(man.volume(), rel=1e-6)


def test_printed_pins_and_caps_are_exact():
    pieces = parts.piece_parts(F.plan("printed-pin").layouts)
    assert {p.role for p in pieces} >= {"pin", "cap"}
    for p in pieces:
        solid, kind = step.part_solid(p)
        assert kind == "exact" and BRepCheck_Analyzer(solid).IsValid(), p.name
        assert _props(solid)[0] == pytest.approx(p.manifold.volume(), rel=0.01), p.name


def test_exact_hull_known_answers():
    """A cylinder's hull with a small prism inside it is the cylinder; with a tiny prism on
    its axis beyond an end, the cylinder and a right cone (exact volumes, where a sampled hull
    falls short by 0.3 % at 48 sides)."""
    z = np.array([0.0, 0.0, 1.0])
    boss = csg.prism(7 * z, 10 * z, 5.0, 48)
    inside = csg.prism(8 * z, 9 * z, 2.0, 6)
    solid = step_hull.exact_hull((boss, inside))
    assert solid is not None and BRepCheck_Analyzer(solid).IsValid()
    assert _props(solid)[0] == pytest.approx(np.pi * 25 * 3, rel=1e-9)
    assert _surfaces(solid) == Counter({"Cylinder": 1, "Plane": 2})
    tip = csg.prism(16 * z, 16.001 * z, 1e-4, 6)
    solid = step_hull.exact_hull((boss, tip))
    assert solid is not None and BRepCheck_Analyzer(solid).IsValid()
    assert _props(solid)[0] == pytest.approx(np.pi * 25 * (3 + 6 / 3), rel=1e-4)


def test_a_fillet_that_does_not_close_is_polyhedral(written, monkeypatch):
    """Where the exact hull is refused, the part stays exact but its webs are the sampled
    hull's facets, and says so; the volume still agrees with the mesh."""
    link = written[0].parts[0]
    monkeypatch.setattr(step_hull, "exact_hull", lambda items: None)
    solid, kind = step.part_solid(link)
    assert kind == "exact, polyhedral fillet" and BRepCheck_Analyzer(solid).IsValid()
    assert _props(solid)[0] == pytest.approx(link.manifold.volume(), rel=0.01)


def _geometry(data: bytes) -> list[str]:
    """A STEP file's statements up to its colours (whose order follows memory addresses);
    assembly usages without their serial number (counted per process by the writer)."""
    out = []
    for s in data.decode().split(";"):
        s = re.sub(r"USAGE_OCCURRENCE\('\d+'", "USAGE_OCCURRENCE('n'", "".join(s.split()))
        if "STYLE" in s or "COLOUR" in s:
            break
        if not s.startswith("FILE_NAME") and "PRESENTATION" not in s:  # time stamp, colours
            out.append(s)
    return out


_NUMBER = re.compile(r"[-+]?\d+\.\d*(?:E[-+]?\d+)?")


def _same_geometry(a: bytes, b: bytes) -> bool:
    """The same statements (:func:`_geometry`), their reals within 1e-9 of each other (the
    helper's solids come through a forked copy and a binary BRep: a zero may come back as
    -3e-18 instead of -7e-18)."""
    ga, gb = _geometry(a), _geometry(b)
    if len(ga) != len(gb):
        return False
    for sa, sb in zip(ga, gb, strict=True):
        if _NUMBER.sub("#", sa) != _NUMBER.sub("#", sb):
            return False
        xa, xb = (np.array(_NUMBER.findall(x), float) for x in (sa, sb))
        if not np.allclose(xa, xb, rtol=1e-9, atol=1e-9):
            return False
    return True


def test_the_helper_process_writes_the_same_solids(written):
    """The export's helper process (:mod:`step_job`) writes the same geometry, statement
    for statement, and the same kinds of solid as the solids made in this process."""
    from paraloop_core.fabrication import step_job

    asm, files, report, _ = written
    colors = export.step_colors(asm)
    with step_job.StepJob(spawn=True) as job:
        assert job._proc is not None
        job.submit(asm, colors, export.STEEL)
        out, kinds = job.result(asm, colors, export.STEEL)
        assert job._proc.returncode == 0  # made by the helper, not here
    assert kinds == {e["name"]: e["step"] for e in report["parts"]}
    assert [n for n, _ in out] == ["parts.step", "assembly.step"]
    for name, data in out:
        assert len(_geometry(data)) > 1000
        assert _same_geometry(data, files[name]), name


def test_a_helper_that_dies_leaves_the_solids_to_this_process(written):
    from paraloop_core.fabrication import step_job

    asm, files, report, _ = written
    colors = export.step_colors(asm)
    with step_job.StepJob(spawn=True) as job:
        job._proc.kill()
        job.submit(asm, colors, export.STEEL)
        out, kinds = job.result(asm, colors, export.STEEL)
    assert kinds == {e["name"]: e["step"] for e in report["parts"]}
    assert _same_geometry(dict(out)["parts.step"], files["parts.step"])


def test_parts_handed_again_are_the_ones_written(written):
    """The export hands the parts again where a keel came off after its verification: the
    first helper is stopped and the files are the second parts' (made by a new helper)."""
    from dataclasses import replace

    from paraloop_core.fabrication import step_job

    asm, files, report, _ = written
    colors = export.step_colors(asm)
    with step_job.StepJob(spawn=True) as job:
        first = job._proc
        job.submit(replace(asm, parts=asm.parts[:2], hardware=()), colors, export.STEEL)
        job.submit(asm, colors, export.STEEL)
        assert job._proc is not first and first.poll() is not None  # stopped
        out, kinds = job.result(asm, colors, export.STEEL)
        assert job._proc.returncode == 0  # made by the new helper
    assert kinds == {e["name"]: e["step"] for e in report["parts"]}
    assert _same_geometry(dict(out)["parts.step"], files["parts.step"])
