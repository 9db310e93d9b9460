"""Mesh helpers shared by robots and objects (trimesh)."""
from __future__ import annotations

import numpy as np


def geometry_to_trimesh(geom: dict):
    """A URDF collision geometry record (from the native Robot) as a trimesh in the link frame."""
    import trimesh

    kind = geom["kind"]
    if kind == "mesh":
        loaded = trimesh.load(geom["mesh_path"], force="mesh", process=False)
        mesh = loaded.copy()
        mesh.apply_scale(np.asarray(geom["scale"], dtype=float))
    elif kind == "box":
        mesh = trimesh.creation.box(extents=geom["size"])
    elif kind == "cylinder":
        mesh = trimesh.creation.cylinder(radius=geom["size"][0], height=geom["size"][1], sections=32)
    elif kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=geom["size"][0])
    else:  # pragma: no cover - the native side only produces the kinds above
        raise ValueError(f"unknown collision geometry kind {kind!r}")
    mesh.apply_transform(np.asarray(geom["origin"], dtype=float))
    return mesh
