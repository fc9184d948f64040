"""Rhino ``.3dm`` of the assembly, for architects who work in Rhino (optional dependency:
``rhino3dm``, ``pip install 'paraloop[rhino]'``).

One layer and one named mesh object per part (``link_<i>``), in the assembled home pose (base
frame), model unit millimetres: the same geometry as the ``link_<i>.stl`` files.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
import trimesh

from paraloop_core.errors import FabricationError


def require() -> None:
    """Raise :class:`FabricationError` (``bad-parameters``) unless rhino3dm is installed."""
    try:
        import rhino3dm  # noqa: F401
    except ImportError as exc:
        raise FabricationError("a .3dm export needs the rhino3dm package: pip install "
                               "'paraloop[rhino]' (or pip install rhino3dm)",
                               "bad-parameters") from exc


def assembly_3dm(meshes: dict[str, trimesh.Trimesh], colours: dict[str, np.ndarray]) -> bytes:
    """The parts ``meshes`` (mm, home pose) as a Rhino 8 file; ``colours`` RGB ``(3,)`` uint8
    per part name (the layer colour)."""
    require()
    import rhino3dm

    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = rhino3dm.UnitSystem.Millimeters
    for name, tm in meshes.items():
        layer = rhino3dm.Layer()
        layer.Name = name
        layer.Color = (*(int(c) for c in colours[name]), 255)
        index = model.Layers.Add(layer)
        mesh = rhino3dm.Mesh()
        for x, y, z in tm.vertices.tolist():
            mesh.Vertices.Add(x, y, z)
        for a, b, c in tm.faces.tolist():
            mesh.Faces.AddFace(a, b, c)
        mesh.Normals.ComputeNormals()
        attributes = rhino3dm.ObjectAttributes()
        attributes.Name, attributes.LayerIndex = name, index
        model.Objects.AddMesh(mesh, attributes)
    with tempfile.TemporaryDirectory() as tmp:  # rhino3dm writes files, not bytes
        path = os.path.join(tmp, "paraloop.3dm")
        if not model.Write(path, 8):
            raise FabricationError("rhino3dm could not write the .3dm file", "bad-parameters")
        with open(path, "rb") as f:
            return f.read()
