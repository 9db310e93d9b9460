"""Headless pictures: PyBullet's TinyRenderer (no display) into PNG files and animated GIFs (Pillow)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np
from PIL import GifImagePlugin, Image

from pickplan.core.io import atomic_open


@dataclass(frozen=True)
class RecordSettings:
    """Frames rendered headless (TinyRenderer) every ``every`` simulation steps, first and last included."""

    every: int = 24  # steps between frames (0.1 s at 240 Hz)
    width: int = 320
    height: int = 240
    max_frames: int = 300  # later frames are dropped (the last one is always kept)
    target: Tuple[float, float, float] = (0.4, 0.0, 0.3)  # orbit camera (``render``)
    distance: float = 1.5
    yaw: float = 45.0
    pitch: float = -25.0
    colorize: bool = True  # paint the objects (target red); visuals only, physics unchanged

    def __post_init__(self):
        if self.every < 1 or self.width < 8 or self.height < 8 or self.max_frames < 2:
            raise ValueError("RecordSettings: need every >= 1, width/height >= 8, max_frames >= 2")


def _rgb_image(rgb: np.ndarray) -> Image.Image:
    img = np.asarray(rgb)
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        raise ValueError(f"expected an (H, W, 3|4) image, got shape {img.shape}")
    return Image.fromarray(np.ascontiguousarray(img[..., :3], dtype=np.uint8), "RGB")


def write_png(path: str, rgb: np.ndarray) -> None:
    """Write an (H, W, 3|4) uint8 image as PNG (atomic)."""
    image = _rgb_image(rgb)
    with atomic_open(path, "wb") as f:
        image.save(f, format="PNG")


def write_gif(path: str, frames: Sequence[np.ndarray], fps: float = 10.0) -> None:
    """Write equal-size (H, W, 3|4) frames as a looping animated GIF (atomic), one GIF frame per
    frame, all sharing one 256-colour palette fitted to the whole animation (Pillow's median cut).

    Frames go through Pillow's per-frame GIF encoder (``getheader`` / ``getdata``): ``save_all``
    would merge identical consecutive frames, and a held pose would drop out of the frame count.
    """
    if not frames:
        raise ValueError("write_gif: no frames to write")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    images = [_rgb_image(f) for f in frames]
    w, h = images[0].size
    if any(im.size != (w, h) for im in images):
        raise ValueError("write_gif: frames must all have the same size")
    sheet = Image.new("RGB", (w, h * len(images)))
    for i, im in enumerate(images):
        sheet.paste(im, (0, i * h))
    palette = sheet.quantize(256, dither=Image.Dither.NONE)
    indexed = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    header, _ = GifImagePlugin.getheader(indexed[0], info={"loop": 0})
    delay_ms = max(10, int(round(1000.0 / fps)))
    with atomic_open(path, "wb") as f:
        f.writelines(header)
        for im in indexed:
            f.writelines(GifImagePlugin.getdata(im, duration=delay_ms))
        f.write(b";")  # the GIF trailer


def render(
    client: int,
    width: int = 640,
    height: int = 480,
    target: Sequence[float] = (0.45, 0.0, 0.35),
    distance: float = 1.6,
    yaw: float = 50.0,
    pitch: float = -30.0,
) -> np.ndarray:
    """An RGB image of the current PyBullet scene from an orbit camera (TinyRenderer)."""
    from pickplan.sim.bullet import pb

    view = pb.computeViewMatrixFromYawPitchRoll(target, distance, yaw, pitch, 0.0, 2, physicsClientId=client)
    proj = pb.computeProjectionMatrixFOV(50.0, width / height, 0.02, 10.0, physicsClientId=client)
    _, _, rgba, _, _ = pb.getCameraImage(
        width, height, view, proj, renderer=pb.ER_TINY_RENDERER, physicsClientId=client
    )
    return np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[..., :3]


def tile(images: Sequence[np.ndarray], columns: int) -> np.ndarray:
    """Images of equal size laid out in a grid."""
    h, w = images[0].shape[:2]
    rows = -(-len(images) // columns)
    out = np.full((rows * h, columns * w, 3), 255, dtype=np.uint8)
    for i, im in enumerate(images):
        r, c = divmod(i, columns)
        out[r * h : (r + 1) * h, c * w : (c + 1) * w] = im[..., :3]
    return out


_PALETTE = (
    (0.20, 0.45, 0.80),
    (0.25, 0.65, 0.35),
    (0.85, 0.65, 0.15),
    (0.55, 0.35, 0.70),
    (0.20, 0.65, 0.70),
    (0.60, 0.60, 0.60),
    (0.80, 0.45, 0.60),
)


def colorize(client: int, bodies: dict, target: str) -> None:
    """Paint the bodies (name -> body id) of a PyBullet scene, the target red (visuals only)."""
    from pickplan.sim.bullet import pb

    for i, name in enumerate(sorted(bodies)):
        rgb = (0.85, 0.15, 0.10) if name == target else _PALETTE[i % len(_PALETTE)]
        pb.changeVisualShape(bodies[name], -1, rgbaColor=[*rgb, 1.0], physicsClientId=client)


def save_frames(frames: Sequence[np.ndarray], path_png: str, columns: int = 4) -> None:
    """Write ``frames`` as one contact-sheet PNG (a grid, ``columns`` wide)."""
    if not frames:
        raise ValueError("save_frames: no frames to write")
    if columns < 1:
        raise ValueError(f"columns must be >= 1, got {columns}")
    write_png(path_png, tile(list(frames), columns))


def save_gif(frames: Sequence[np.ndarray], path: str, fps: float = 10.0) -> None:
    """Write ``frames`` as a looping animated GIF (Pillow)."""
    write_gif(path, frames, fps)
