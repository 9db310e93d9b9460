"""Pictures through Pillow: PNG round-trips exactly; the GIF keeps every frame (held poses too),
its timing and looping, and decodes to the frames it was given; bad input is named."""

import numpy as np
import pytest
from PIL import Image, ImageSequence

from pickplan.sim import render


def _frames():
    out = []
    for k in range(4):
        f = np.full((40, 50, 3), 255, np.uint8)
        f[5:20, 5 + 5 * k : 20 + 5 * k] = (200, 30, 30)  # a moving red block
        f[25:35, :] = (30, 120, 200)
        out.append(f)
    return out + [out[-1].copy()]  # the last pose held: two identical frames


def test_png_round_trips(tmp_path):
    rgba = np.random.default_rng(0).integers(0, 256, (12, 17, 4), dtype=np.uint8)
    render.write_png(str(tmp_path / "a.png"), rgba)
    with Image.open(tmp_path / "a.png") as im:
        assert im.mode == "RGB" and im.size == (17, 12)
        assert np.array_equal(np.asarray(im), rgba[..., :3])


def test_gif_keeps_every_frame_and_its_timing(tmp_path):
    frames = _frames()
    render.write_gif(str(tmp_path / "a.gif"), frames, fps=5)
    with Image.open(tmp_path / "a.gif") as im:
        assert im.n_frames == len(frames) and im.info["loop"] == 0 and im.info["duration"] == 200
        decoded = [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(im)]
    for got, want in zip(decoded, frames):  # three colours fit the palette exactly
        assert np.array_equal(got, want)


def test_bad_pictures_are_named(tmp_path):
    with pytest.raises(ValueError, match="no frames"):
        render.write_gif(str(tmp_path / "a.gif"), [])
    with pytest.raises(ValueError, match="same size"):
        render.write_gif(str(tmp_path / "a.gif"), [np.zeros((4, 4, 3), np.uint8), np.zeros((5, 4, 3), np.uint8)])
    with pytest.raises(ValueError, match="fps"):
        render.write_gif(str(tmp_path / "a.gif"), _frames(), fps=0)
    with pytest.raises(ValueError, match=r"\(H, W, 3\|4\)"):
        render.write_png(str(tmp_path / "a.png"), np.zeros((4, 4)))
    assert not list(tmp_path.iterdir())  # nothing half-written
