"""Headless pictures: PyBullet's TinyRenderer into PNG files (no display, no extra packages)."""
from __future__ import annotations

import struct
import zlib
from typing import Sequence

import numpy as np

from pickplan.core.io import atomic_open


def write_png(path: str, rgb: np.ndarray) -> None:
    """Write an (H, W, 3|4) uint8 image as PNG (atomic)."""
    img = np.ascontiguousarray(rgb[..., :3], dtype=np.uint8)
    h, w = img.shape[:2]
    raw = b"".join(b"\x00" + img[y].tobytes() for y in range(h))

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    with atomic_open(path, "wb") as f:
        f.write(png)


def render(client: int, width: int = 640, height: int = 480, target: Sequence[float] = (0.45, 0.0, 0.35),
           distance: float = 1.6, yaw: float = 50.0, pitch: float = -30.0) -> np.ndarray:
    """An RGB image of the current PyBullet scene from an orbit camera (TinyRenderer)."""
    import pybullet as pb

    view = pb.computeViewMatrixFromYawPitchRoll(target, distance, yaw, pitch, 0.0, 2, physicsClientId=client)
    proj = pb.computeProjectionMatrixFOV(50.0, width / height, 0.02, 10.0, physicsClientId=client)
    _, _, rgba, _, _ = pb.getCameraImage(width, height, view, proj, renderer=pb.ER_TINY_RENDERER,
                                         physicsClientId=client)
    return np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[..., :3]


def tile(images: Sequence[np.ndarray], columns: int) -> np.ndarray:
    """Images of equal size laid out in a grid."""
    h, w = images[0].shape[:2]
    rows = -(-len(images) // columns)
    out = np.full((rows * h, columns * w, 3), 255, dtype=np.uint8)
    for i, im in enumerate(images):
        r, c = divmod(i, columns)
        out[r * h:(r + 1) * h, c * w:(c + 1) * w] = im[..., :3]
    return out
