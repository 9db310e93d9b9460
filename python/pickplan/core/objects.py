"""Object models: watertight mesh, convex collision parts, mass properties, resting poses, grasps.

Two sources give the same ``ObjectModel`` record:

* the built-in set (``objects_builtin``): procedural shapes with the sizes and masses of the OMG
  paper's ten YCB objects, named like the YCB folders (``006_mustard_bottle``);
* a folder per object in the layout of ``../shared/data/ycb`` (``mesh.stl``, ``collision.obj``,
  ``grasps_*.npy``), loaded by ``load_ycb_object``.

>>> lib = library()                      # built-ins; library("/path/to/ycb") or $PICKPLAN_YCB_DIR
>>> can = lib.get("005_tomato_soup_can")
>>> can.resting_poses[0] @ [0, 0, 0, 1]  # object frame -> resting on z = 0, COM above the origin
"""

from __future__ import annotations

import glob
import math
import os
import warnings
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import trimesh

from pickplan.core import containers, objects_builtin, procedural, stability
from pickplan.core.caches import memo
from pickplan.core.io import content_file

YCB_ENV = "PICKPLAN_YCB_DIR"
BUILTIN_PREFIX = "builtin:"
DEFAULT_DENSITY = 400.0  # kg/m^3, for objects with no known mass (household packaging is mostly air)

# YCB masses (Calli et al., 2015) in kg, also used for real scans of these objects.
KNOWN_MASSES = {name: spec.mass for name, spec in objects_builtin.BUILTIN_SPECS.items()}


@dataclass(eq=False)
class ObjectModel:
    """One rigid object, everything in its own (mesh) frame, metres and kilograms."""

    name: str
    mesh: trimesh.Trimesh
    collision_parts: List[trimesh.Trimesh]
    mass: float
    com: np.ndarray  # (3,) centre of mass
    inertia: np.ndarray  # (3, 3) about the centre of mass, object axes
    resting_poses: List[np.ndarray]  # 4x4 object -> world transforms resting on z = 0, most stable first
    source: str  # "builtin:NAME" or the object's folder
    grasps: Dict[str, np.ndarray] = field(default_factory=dict)  # set name -> (N, 4, 4) gripper in object
    resting_barriers: List[float] = field(default_factory=list)  # COM rise (m) needed to tip each pose
    collision_file: Optional[str] = None  # OBJ with the parts as separate objects (PyBullet compound)
    friction: Optional[float] = None  # lateral friction; None: the scene's setting
    resting_probabilities: List[float] = field(default_factory=list)  # of each resting pose, dropped at random

    @property
    def extents(self) -> np.ndarray:
        return np.asarray(self.mesh.extents, dtype=float)

    def collision_obj_path(self) -> str:
        """An OBJ file holding the convex parts, one ``o`` per part (PyBullet makes a hull of each).

        Built-ins are written once to a per-user cache folder, named by content hash, so every
        process and PyBullet client reads the same bytes.
        """
        if self.collision_file is None:
            self.collision_file = _write_parts_obj(self.collision_parts)
        return self.collision_file


# --- mass properties and resting poses ------------------------------------------------------------
def mass_properties(
    mesh: trimesh.Trimesh, mass: Optional[float] = None, density: float = DEFAULT_DENSITY
) -> Tuple[float, np.ndarray, np.ndarray]:
    """(mass, com, inertia about com) of a uniform solid; ``mass`` overrides the density."""
    volume = float(mesh.volume)
    if not np.isfinite(volume) or volume <= 1e-12:
        raise ValueError(f"mesh encloses no volume ({volume:.3g} m^3): cannot compute mass properties")
    rho = density if mass is None else float(mass) / volume
    props = trimesh.triangles.mass_properties(mesh.triangles, density=rho)
    inertia = np.asarray(props["inertia"], dtype=float)
    return float(props["mass"]), np.asarray(props["center_mass"], dtype=float), 0.5 * (inertia + inertia.T)


def _rotation_to_down(n: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector n to -z (so an upright object keeps its yaw)."""
    target = np.array([0.0, 0.0, -1.0])
    v, c = np.cross(n, target), float(np.dot(n, target))
    if c < -1 + 1e-12:  # n = +z: turn over about x
        return np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def _polygon_edge_distances(poly: np.ndarray, p: np.ndarray) -> Optional[np.ndarray]:
    """Distances from p to the edges of a counter-clockwise convex polygon; None if p is outside."""
    a, b = poly, np.roll(poly, -1, axis=0)
    e = b - a
    lengths = np.linalg.norm(e, axis=1)
    keep = lengths > 1e-12
    a, e, lengths = a[keep], e[keep], lengths[keep]
    cross = (e[:, 0] * (p[1] - a[:, 1]) - e[:, 1] * (p[0] - a[:, 0])) / lengths
    return cross if np.all(cross > 0) else None


def compute_resting_poses(
    mesh: trimesh.Trimesh, com: np.ndarray, max_poses: int = 10, angle_tol_deg: float = 3.0, contact_tol: float = 1e-3
) -> Tuple[List[np.ndarray], List[float]]:
    """Stable resting poses on the plane z = 0, most stable first, and their tipping barriers.

    A candidate is a cluster of convex-hull faces with nearly the same normal; the support polygon is
    the hull vertices within ``contact_tol`` of that plane. The pose is stable when the centre of mass
    projects strictly inside it; its barrier is how far the COM must rise to tip over the nearest
    edge (sqrt(h^2 + d^2) - h). Deterministic: no sampling. The pose puts the lowest mesh point at
    z = 0 and the COM above the origin.
    """
    from scipy.spatial import ConvexHull

    hull = mesh.convex_hull
    verts = np.asarray(hull.vertices)
    normals, areas = np.asarray(hull.face_normals), np.asarray(hull.area_faces)
    order = np.lexsort((np.arange(len(areas)), -areas))  # biggest faces first, ties by index
    cos_tol = np.cos(np.radians(angle_tol_deg))
    clusters = np.zeros((len(order), 3))
    k = 0
    for f in order:  # greedy clustering of normals, deterministic order
        if k == 0 or np.max(clusters[:k] @ normals[f]) < cos_tol:
            clusters[k] = normals[f]
            k += 1
    clusters = clusters[:k]
    # Quick filter: the ray from the COM along a cluster normal must leave the hull through a face of
    # that cluster, otherwise the COM is not above that support face.
    plane = np.einsum("ij,ij->i", normals, np.asarray(hull.triangles_center)) - normals @ com
    along = clusters @ normals.T  # (C, F)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_exit = np.where(along > 1e-9, plane[None, :] / along, np.inf)
    exit_face = np.argmin(t_exit, axis=1)
    clusters = clusters[np.einsum("ij,ij->i", clusters, normals[exit_face]) >= cos_tol - 1e-9]
    candidates = []
    for n in clusters:
        offsets = verts @ n
        top = offsets.max()
        contact = verts[offsets >= top - contact_tol]
        if len(contact) < 3:
            continue
        R = _rotation_to_down(n)
        flat = contact @ R.T
        try:
            ring = flat[ConvexHull(flat[:, :2]).vertices, :2]  # counter-clockwise in 2D
        except Exception:  # collinear contacts: an edge, not a face to rest on
            continue
        c = R @ com
        dist = _polygon_edge_distances(ring, c[:2])
        if dist is None:
            continue
        height = float(top - np.dot(com, n))
        barrier = float(np.min(np.sqrt(height**2 + dist**2) - height))
        T = np.eye(4)
        T[:3, :3] = R
        lowest = float((np.asarray(mesh.vertices) @ R.T)[:, 2].min())
        T[:3, 3] = [-c[0], -c[1], -lowest]
        candidates.append((barrier, T))
    if not candidates:
        raise ValueError("no stable resting pose found (the centre of mass lies outside every support face)")
    candidates.sort(key=lambda bt: -bt[0])  # stable sort: ties keep the deterministic cluster order
    candidates = candidates[:max_poses]
    return [T for _, T in candidates], [b for b, _ in candidates]


# --- building records ----------------------------------------------------------------------------
def _check_mesh(mesh: trimesh.Trimesh, what: str) -> trimesh.Trimesh:
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"{what}: empty mesh (no triangles)")
    if not np.all(np.isfinite(mesh.vertices)):
        raise ValueError(f"{what}: mesh has non-finite vertices")
    if np.min(mesh.extents) <= 1e-6:
        raise ValueError(f"{what}: degenerate mesh (extents {np.round(mesh.extents, 6).tolist()} m)")
    return mesh


def make_object(
    name: str,
    mesh: trimesh.Trimesh,
    collision_parts: Sequence[trimesh.Trimesh],
    source: str,
    mass: Optional[float] = None,
    density: float = DEFAULT_DENSITY,
    grasps: Optional[Dict[str, np.ndarray]] = None,
    collision_file: Optional[str] = None,
    friction: Optional[float] = None,
) -> ObjectModel:
    """Build a record from a mesh: mass properties and resting poses are computed here.

    A mesh that is not watertight still works (with a warning): mass properties and resting poses
    then come from its convex hull, whose volume is well defined.
    """
    _check_mesh(mesh, name)
    solid = mesh
    if not mesh.is_watertight:
        warnings.warn(
            f"{name}: mesh is not watertight; mass properties and resting poses use its convex hull", stacklevel=3
        )
        solid = mesh.convex_hull
    elif mesh.volume < 0:  # inside-out winding
        mesh = mesh.copy()
        mesh.invert()
        solid = mesh
    m, com, inertia = mass_properties(solid, mass=mass, density=density)
    poses, barriers = compute_resting_poses(solid, com)
    probabilities = stability.resting_probabilities(solid, com, poses)
    parts = list(collision_parts) if collision_parts else [mesh.convex_hull]
    return ObjectModel(
        name=name,
        mesh=mesh,
        collision_parts=parts,
        mass=m,
        com=com,
        inertia=inertia,
        resting_poses=poses,
        source=source,
        grasps=dict(grasps or {}),
        resting_barriers=barriers,
        collision_file=collision_file,
        friction=friction,
        resting_probabilities=probabilities,
    )


def procedural_object(name: str) -> ObjectModel:
    """An object of the procedural families (see ``procedural.FAMILIES``), e.g. ``"scissors_01"``."""
    mesh, parts, gen = procedural.generate(name)
    return make_object(
        name, mesh, parts, source=procedural.PROCEDURAL_PREFIX + name, mass=gen.mass, friction=gen.friction
    )


def builtin_object(name: str) -> ObjectModel:
    """A procedural stand-in for a YCB object (see ``objects_builtin.BUILTIN_SPECS``)."""
    mesh, parts, spec = objects_builtin.build(name)
    return make_object(name, mesh, parts, source=BUILTIN_PREFIX + name, mass=spec.mass)


def read_obj_parts(path: str) -> List[trimesh.Trimesh]:
    """Split an OBJ with several objects/groups (``o``/``g`` lines) into one mesh per part.

    Face indices in OBJ are global across the file (1-based, negative = relative), so they are
    resolved against all vertices read so far.
    """
    verts: List[List[float]] = []
    parts: List[List[List[int]]] = [[]]
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        for lineno, line in enumerate(f, 1):
            tok = line.split()
            if not tok:
                continue
            try:
                if tok[0] == "v":
                    v = [float(x) for x in tok[1:4]]
                    if len(v) != 3 or not all(math.isfinite(x) for x in v):
                        raise ValueError("expected 3 finite coordinates")
                    verts.append(v)
                elif tok[0] in ("o", "g"):
                    if parts[-1]:
                        parts.append([])
                elif tok[0] == "f":
                    idx = [int(t.split("/")[0]) for t in tok[1:]]
                    idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                    parts[-1] += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
            except (ValueError, IndexError) as exc:
                raise ValueError(f"{path}:{lineno}: malformed OBJ line {line.strip()!r}") from exc
    V = np.asarray(verts, dtype=float).reshape(-1, 3)
    meshes = []
    for faces in parts:
        if not faces:
            continue
        F = np.asarray(faces, dtype=np.int64)
        if F.min() < 0 or F.max() >= len(V):
            raise ValueError(f"{path}: face refers to a vertex that does not exist")
        used, inverse = np.unique(F, return_inverse=True)
        meshes.append(trimesh.Trimesh(V[used], inverse.reshape(-1, 3), process=True))
    return meshes


def read_grasp_array(path: str) -> np.ndarray:
    """A stored grasp array (``.npy``, float (N, 4, 4)); ValueError naming the file when it is damaged
    or of the wrong kind (rigidity is checked where grasp sets are made: ``omg.grasps.check_grasps``)."""
    try:
        arr = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise
    except Exception as exc:  # noqa: BLE001 - numpy reports a damaged file as ValueError, EOFError,
        # OSError, or (a broken header) SyntaxError / tokenize.TokenError: each means "damaged"
        raise ValueError(f"{path}: not a readable .npy grasp array ({type(exc).__name__}: {exc})") from None
    if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "fiu":
        raise ValueError(f"{path}: expected a float array of grasps, got dtype {getattr(arr, 'dtype', type(arr))}")
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise ValueError(f"{path}: expected an (N, 4, 4) array of grasps, got shape {arr.shape}")
    return np.asarray(arr, dtype=float)


def load_ycb_object(folder: Union[str, os.PathLike], density: float = DEFAULT_DENSITY) -> ObjectModel:
    """Load one object folder: ``mesh.stl`` (required), ``collision.obj``, ``grasps_*.npy``.

    The mass is the YCB mass when the folder name is a known YCB object, else ``density`` x volume.
    Without ``collision.obj`` the mesh's convex hull is the single collision part.
    """
    folder = os.path.abspath(os.fspath(folder))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"object folder not found: {folder}")
    name = os.path.basename(folder.rstrip(os.sep))
    mesh_path = os.path.join(folder, "mesh.stl")
    if not os.path.isfile(mesh_path):
        raise FileNotFoundError(f"object mesh not found: {mesh_path}")
    try:
        loaded = trimesh.load(mesh_path, force="mesh")
    except Exception as exc:
        raise ValueError(f"{mesh_path}: cannot read mesh ({exc})") from exc
    if not isinstance(loaded, trimesh.Trimesh):  # an empty file loads as an empty Scene
        raise ValueError(f"{mesh_path}: empty mesh (no triangles)")
    _check_mesh(loaded, mesh_path)
    coll_path = os.path.join(folder, "collision.obj")
    parts, coll_file = [], None
    if os.path.isfile(coll_path):
        parts, coll_file = read_obj_parts(coll_path), coll_path
    grasps = {}
    for path in sorted(glob.glob(os.path.join(folder, "grasps_*.npy"))):
        key = os.path.basename(path)[len("grasps_") : -len(".npy")]
        grasps[key] = read_grasp_array(path)
    return make_object(
        name,
        loaded,
        parts,
        source=folder,
        mass=KNOWN_MASSES.get(name),
        density=density,
        grasps=grasps,
        collision_file=coll_file,
    )


def _write_parts_obj(parts: Sequence[trimesh.Trimesh]) -> str:
    lines, offset = [], 1
    for i, p in enumerate(parts):
        lines.append(f"o part_{i}")
        lines += ["v %.9f %.9f %.9f" % tuple(v) for v in np.asarray(p.vertices, dtype=float)]
        lines += ["f %d %d %d" % tuple(t) for t in (np.asarray(p.faces) + offset)]
        offset += len(p.vertices)
    return content_file("\n".join(lines) + "\n", "collision", ".obj")


# --- libraries -----------------------------------------------------------------------------------
class ObjectLibrary:
    """A named set of objects, loaded lazily on first ``get`` and kept."""

    def __init__(self, names: Sequence[str], root: Optional[str] = None, kind: str = ""):
        self.root = root  # None for the built-in sets, else the folder holding one folder per object
        self.kind = kind or ("builtin" if root is None else "folder")
        self._names = list(names)
        self._models: Dict[str, ObjectModel] = {}

    @property
    def names(self) -> List[str]:
        return list(self._names)

    @property
    def source(self) -> str:
        return self.kind if self.root is None else self.root

    def get(self, name: str) -> ObjectModel:
        if name not in self._names:
            raise KeyError(f"object {name!r} not in library {self.source}; expected one of {self._names}")
        if name not in self._models:
            if self.root is not None:
                self._models[name] = load_ycb_object(os.path.join(self.root, name))
            elif self.kind == "procedural":
                self._models[name] = procedural_object(name)
            else:
                self._models[name] = builtin_object(name)
        return self._models[name]

    def __contains__(self, name: str) -> bool:
        return name in self._names

    def __len__(self) -> int:
        return len(self._names)

    def __repr__(self) -> str:
        return f"ObjectLibrary({self.source!r}, {len(self)} objects)"


def library(source: Optional[Union[str, os.PathLike]] = None) -> ObjectLibrary:
    """The built-in set (``source`` None/"builtin" and no $PICKPLAN_YCB_DIR), the procedural families
    (``"procedural"``), or a YCB-layout folder.

    A folder qualifies an object when its sub-folder holds ``mesh.stl``.
    """
    if source is None:
        source = os.environ.get(YCB_ENV) or "builtin"
    source = os.fspath(source)
    return _library(source if source in ("builtin", "procedural") else os.path.abspath(source))


@memo(8)  # a library keeps the meshes and hulls it has built: costly to rebuild
def _library(key: str) -> ObjectLibrary:
    if key == "builtin":
        lib = ObjectLibrary(sorted(objects_builtin.BUILTIN_SPECS))
    elif key == "procedural":
        lib = ObjectLibrary(procedural.names(), kind="procedural")
    else:
        if not os.path.isdir(key):
            raise FileNotFoundError(f"object library folder not found: {key}")
        names = sorted(d for d in os.listdir(key) if os.path.isfile(os.path.join(key, d, "mesh.stl")))
        if not names:
            raise ValueError(f"object library folder {key} has no object folders with a mesh.stl")
        lib = ObjectLibrary(names, root=key)
    return lib


@memo(16)
def container_object(source: str) -> ObjectModel:
    """A container a scene names by its size (``core.containers``: ``bin:<x>x<y>x<height>``)."""
    mesh, parts = containers.bin_geometry(source)
    return make_object(source.replace(":", "_"), mesh, parts, source=source, mass=containers.BIN_MASS)


def model_from_source(name: str, source: str) -> ObjectModel:
    """The model a scene refers to: ``builtin:NAME``, ``procedural:NAME``, a container (``bin:...``) or an
    object folder (through the cached libraries)."""
    if source.startswith(containers.BIN_PREFIX):
        return container_object(source)
    if source.startswith(BUILTIN_PREFIX):
        return library("builtin").get(source[len(BUILTIN_PREFIX) :])
    if source.startswith(procedural.PROCEDURAL_PREFIX):
        return library("procedural").get(source[len(procedural.PROCEDURAL_PREFIX) :])
    folder = os.path.abspath(source)
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"object folder not found: {folder} (object {name!r})")
    return library(os.path.dirname(folder)).get(os.path.basename(folder))
