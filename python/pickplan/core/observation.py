"""What a depth camera gives the planner: depth images with intrinsics and poses, and the target.

File format (``.npz``, written by ``Observation.save``, read by ``Observation.load``):

=============== ================ =====================================================================
key             shape, dtype     meaning
=============== ================ =====================================================================
``depth``       (V, H, W) f4     metres along each camera's optical axis; 0 or NaN: no return
``K``           (V, 3, 3) f8     pinhole intrinsics [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]; pixel (r, c)
                                 covers [c, c + 1) x [r, r + 1)
``camera_pose`` (V, 4, 4) f8     camera -> world, OpenCV axes (z forward, x right, y down)
``target_mask`` (V, H, W) u1     nonzero where the target is (or ``target_pixel`` instead)
``target_pixel`` (V, 2) i4       (row, col) on the target in each view, -1 where it is not seen: grown
                                 to the connected surface segment (``grow_target``)
``rgb``         (V, H, W, 3) u1  optional colour
``format``      str              ``"pickplan.observation"``; ``version`` int: 1
=============== ================ =====================================================================
"""

from __future__ import annotations

import io
import math
import os
import struct
import tokenize
import zipfile
import zlib
from collections import deque
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pickplan.core.errors import InputError
from pickplan.core.fields import FieldReader
from pickplan.core.io import atomic_open

FORMAT = "pickplan.observation"
VERSION = 1
MIN_VALID_FRACTION = 0.1  # a view with fewer depth returns than this is refused
RIGID_TOL = 1e-5
# What a real depth camera gives: beyond these a value is corrupt, not a camera.
FIELD_OF_VIEW_DEG = (1.0, 170.0)  # per image axis, from the focal length and the image size
MAX_SKEW = 1e-3  # |s| / fx: pickplan's back-projection has no skew term
MAX_DEPTH = 100.0  # m
MAX_CAMERA_DISTANCE = 100.0  # m from the robot base
MAX_VIEWS, MAX_PIXELS = 64, 50_000_000  # per file, per view
MAX_FILE_BYTES = 8_000_000_000  # uncompressed, every array together

# What reading a truncated, bit-flipped or foreign archive raises (RuntimeError: an encrypted member;
# TokenError and SyntaxError: numpy parses a damaged array header as Python text).
CORRUPT_ARCHIVE = (
    zipfile.BadZipFile,
    zipfile.LargeZipFile,
    zlib.error,
    struct.error,
    ValueError,
    OSError,
    EOFError,
    NotImplementedError,
    KeyError,
    RuntimeError,
    tokenize.TokenError,
    SyntaxError,
)

#: The error an unusable observation raises (an ``InputError``: file and field named).
ObservationError = InputError


@dataclass(eq=False)
class Observation:
    depth: np.ndarray  # (V, H, W) float32
    K: np.ndarray  # (V, 3, 3)
    camera_pose: np.ndarray  # (V, 4, 4)
    target_mask: np.ndarray  # (V, H, W) bool
    rgb: Optional[np.ndarray] = None
    source: str = "<memory>"

    def __post_init__(self):
        self.depth, self.K, self.camera_pose, self.target_mask, self.rgb = _validated(
            self.depth, self.K, self.camera_pose, self.target_mask, self.rgb, self.source
        )

    @property
    def views(self) -> int:
        return int(self.depth.shape[0])

    def save(self, path) -> None:
        data = {
            "depth": self.depth,
            "K": self.K,
            "camera_pose": self.camera_pose,
            "target_mask": self.target_mask.astype(np.uint8),
            "format": np.array(FORMAT),
            "version": np.array(VERSION),
        }
        if self.rgb is not None:
            data["rgb"] = self.rgb
        buf = io.BytesIO()
        np.savez_compressed(buf, **data)
        with atomic_open(os.fspath(path), "wb") as f:
            f.write(buf.getvalue())

    @classmethod
    def load(cls, path) -> "Observation":
        path = os.fspath(path)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"observation file not found: {path}")
        data = read_npz(path)
        r = FieldReader(path)
        with r:
            fmt = r.key(data, "format")
            if fmt.shape != () or fmt.dtype.kind != "U" or str(fmt) != FORMAT:
                r.fail("format", f"expected {FORMAT!r}, got {str(fmt)[:60]!r}")
            version = r.key(data, "version")
            if version.shape != () or version.dtype.kind not in "iu" or int(version) != VERSION:
                r.fail("version", f"this pickplan reads observation version {VERSION}, got {str(version)[:40]}")
            for key in ("depth", "K", "camera_pose"):
                with r.part():
                    r.key(data, key)
            if "target_mask" not in data and "target_pixel" not in data:
                r.fail("target_mask", "missing (or target_pixel: the target must be given)")
        depth = data["depth"]
        mask = data["target_mask"] if "target_mask" in data else grow_target(depth, data["target_pixel"], path)
        return cls(depth, data["K"], data["camera_pose"], mask, data.get("rgb"), source=path)


def read_npz(path: str) -> dict:
    """Every array of an ``.npz`` archive, read without unpickling and without allocating more than
    the archive holds; InputError naming the file for anything that is not such an archive (a
    ``.npy`` renamed, a truncated or corrupted file)."""

    def fail(message):
        raise InputError(message, path=path)

    with open(path, "rb") as f:
        magic = f.read(6)
    if magic.startswith(b"\x93NUMPY"):
        fail("a single .npy array, not an .npz archive of named arrays (Observation.save writes one)")
    try:
        with zipfile.ZipFile(path) as z:
            infos = z.infolist()
            if sum(i.file_size for i in infos) > MAX_FILE_BYTES:
                fail(f"its arrays hold more than {MAX_FILE_BYTES} bytes")
            return {i.filename[:-4]: _npy(z, i, path) for i in infos if i.filename.endswith(".npy")}
    except CORRUPT_ARCHIVE as exc:
        fail(f"not a readable .npz observation ({type(exc).__name__}: {str(exc)[:200]})")


def _npy(z: zipfile.ZipFile, info: zipfile.ZipInfo, path: str) -> np.ndarray:
    with z.open(info) as f:
        version = np.lib.format.read_magic(f)
        header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, fortran, dtype = header(f)
        if dtype.hasobject:
            raise InputError("holds Python objects (pickled data is never read)", path=path, field=info.filename[:-4])
        size = math.prod(shape) * dtype.itemsize
        if size > info.file_size:
            raise InputError(f"declares {size} bytes but holds {info.file_size}", path=path, field=info.filename[:-4])
        data = f.read(size)
        if len(data) != size:
            raise InputError("truncated array data", path=path, field=info.filename[:-4])
        return np.frombuffer(data, dtype=dtype).reshape(shape, order="F" if fortran else "C").copy()


def _validated(depth, K, pose, mask, rgb, source):
    r = FieldReader(None if source == "<memory>" else source)
    with r:
        depth = _depth(r, depth)
        V, H, W = depth.shape
        K = r.attempt(_intrinsics, r, K, (V, H, W))
        pose = r.attempt(_poses, r, pose, V)
        mask = r.attempt(_mask, r, mask, depth)
        if rgb is not None:
            rgb = r.attempt(_rgb, r, rgb, (V, H, W))
    return depth, K, pose, mask, rgb


def _numeric(r: FieldReader, value, where: str, kinds: str = "fiu") -> np.ndarray:
    a = np.asarray(value)
    if a.dtype.kind not in kinds:
        r.fail(where, f"expected numbers, got an array of {a.dtype}")
    return a


def _depth(r: FieldReader, depth) -> np.ndarray:
    depth = _numeric(r, depth, "depth", "f")
    depth = depth[None] if depth.ndim == 2 else depth
    if depth.ndim != 3 or depth.shape[0] < 1 or min(depth.shape[1:]) < 2:
        r.fail("depth", f"expected shape (V, H, W), got {depth.shape}")
    if depth.shape[0] > MAX_VIEWS or depth.shape[1] * depth.shape[2] > MAX_PIXELS:
        r.fail("depth", f"{depth.shape}: more than {MAX_VIEWS} views or {MAX_PIXELS} pixels a view")
    depth = depth.astype(np.float32)
    if np.any(np.isinf(depth)) or np.any(depth < 0):
        r.fail("depth", "negative or infinite values (use 0 or NaN for pixels without a return)")
    if np.nanmax(depth, initial=0.0) > MAX_DEPTH:
        r.fail("depth", f"values up to {np.nanmax(depth):.3g} m: more than a depth camera's {MAX_DEPTH:g} m")
    valid = np.isfinite(depth) & (depth > 0)
    for v in range(depth.shape[0]):
        if valid[v].mean() < MIN_VALID_FRACTION:
            r.fail(
                "depth",
                f"view {v} has depth in only {100 * valid[v].mean():.1f} % of its pixels "
                f"(need {100 * MIN_VALID_FRACTION:.0f} %): zero, NaN or missing depth",
            )
    return depth


def _views(r: FieldReader, value, name: str, shape: tuple) -> np.ndarray:
    a = _numeric(r, value, name).astype(float)
    a = a[None] if a.ndim == len(shape) - 1 else a
    if a.shape != shape:
        r.fail(name, f"expected shape {shape}, got {np.asarray(value).shape}")
    if not np.all(np.isfinite(a)):
        r.fail(name, "not finite")
    return a


def _intrinsics(r: FieldReader, K, image: tuple) -> np.ndarray:
    V, H, W = image
    K = _views(r, K, "K", (V, 3, 3))
    lo, hi = (math.radians(a) for a in FIELD_OF_VIEW_DEG)
    for v, k in enumerate(K):
        if not (np.array_equal(k[2], [0, 0, 1]) and k[1, 0] == 0):
            r.fail("K", f"view {v}: expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got {np.round(k, 6).tolist()}")
        for axis, f, size in (("fx", k[0, 0], W), ("fy", k[1, 1], H)):
            if not size / (2 * math.tan(hi / 2)) <= f <= size / (2 * math.tan(lo / 2)):
                r.fail(
                    "K",
                    f"view {v}: {axis} = {f:.4g} px gives a field of view outside {FIELD_OF_VIEW_DEG} degrees "
                    f"over {size} px: not a camera's focal length",
                )
        if abs(k[0, 1]) > MAX_SKEW * k[0, 0]:
            r.fail("K", f"view {v}: skew {k[0, 1]:.4g} px; pickplan models none (at most {MAX_SKEW:g} fx)")
        if not (0 <= k[0, 2] <= W and 0 <= k[1, 2] <= H):
            r.fail("K", f"view {v}: principal point ({k[0, 2]:.4g}, {k[1, 2]:.4g}) outside the {W} x {H} image")
    return K


def _poses(r: FieldReader, pose, V: int) -> np.ndarray:
    pose = _views(r, pose, "camera_pose", (V, 4, 4))
    for v in range(V):
        R = pose[v, :3, :3]
        if (
            np.abs(R @ R.T - np.eye(3)).max() > RIGID_TOL
            or np.linalg.det(R) < 0
            or np.abs(pose[v, 3] - [0, 0, 0, 1]).max() > RIGID_TOL
        ):
            r.fail("camera_pose", f"view {v} is not a rigid transform")
        if np.linalg.norm(pose[v, :3, 3]) > MAX_CAMERA_DISTANCE:
            r.fail(
                "camera_pose",
                f"view {v} is {np.linalg.norm(pose[v, :3, 3]):.3g} m from the robot base "
                f"(at most {MAX_CAMERA_DISTANCE:g} m)",
            )
    return pose


def _mask(r: FieldReader, mask, depth: np.ndarray) -> np.ndarray:
    mask = np.asarray(mask)
    mask = mask[None] if mask.ndim == 2 else mask
    if mask.dtype.kind not in "biu":
        r.fail("target_mask", f"expected booleans or 0/1 integers, got an array of {mask.dtype}")
    if mask.shape != depth.shape:
        r.fail("target_mask", f"expected shape {depth.shape} like depth, got {mask.shape}")
    if mask.dtype.kind != "b" and mask.size and (mask.min() < 0 or mask.max() > 1):
        r.fail("target_mask", f"expected 0 or 1, got values {mask.min()}..{mask.max()}")
    mask = mask.astype(bool)
    if not np.any(mask & np.isfinite(depth) & (depth > 0)):
        r.fail("target_mask", "the target has no pixel with depth in any view")
    return mask


def _rgb(r: FieldReader, rgb, image: tuple) -> np.ndarray:
    rgb = _numeric(r, rgb, "rgb")
    if rgb.shape != (*image, 3):
        r.fail("rgb", f"expected shape {(*image, 3)}, got {rgb.shape}")
    if rgb.size and not (np.all(np.isfinite(rgb)) and rgb.min() >= 0 and rgb.max() <= 255):
        r.fail("rgb", "expected colours in 0..255 (NaN or values outside)")
    return rgb.astype(np.uint8)


def grow_target(depth: np.ndarray, pixels, source: str = "<memory>", max_step: float = 0.01) -> np.ndarray:
    """A target mask from one (row, col) per view: the 4-connected pixels reachable through depth
    steps below ``max_step`` m (one surface segment; -1 marks a view that does not see the target)."""
    r = FieldReader(None if source == "<memory>" else source)
    with r:
        V, H, W = _depth(r, depth).shape
        given = _numeric(r, pixels, "target_pixel", "iu")
        pixels = given[None] if given.ndim == 1 else given
        if pixels.shape != (V, 2):
            r.fail("target_pixel", f"expected one (row, col) pair per view: shape ({V}, 2), got {given.shape}")
    depth = np.asarray(depth, float)
    depth = depth[None] if depth.ndim == 2 else depth
    mask = np.zeros(depth.shape, dtype=bool)
    for v, (row, col) in enumerate(pixels.tolist()):
        if row < 0 or col < 0:
            continue
        if row >= H or col >= W or not np.isfinite(depth[v, row, col]) or depth[v, row, col] <= 0:
            raise InputError(
                f"view {v} pixel {(row, col)} has no depth or is outside the {H} x {W} image",
                path=r.path,
                field="target_pixel",
            )
        queue = deque([(row, col)])
        mask[v, row, col] = True
        while queue:
            i, j = queue.popleft()
            for a, b in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
                if (
                    0 <= a < H
                    and 0 <= b < W
                    and not mask[v, a, b]
                    and np.isfinite(depth[v, a, b])
                    and depth[v, a, b] > 0
                    and abs(depth[v, a, b] - depth[v, i, j]) < max_step
                ):
                    mask[v, a, b] = True
                    queue.append((a, b))
    return mask
