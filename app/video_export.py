"""Teacher export: one MP4 per story, drawn top-down like the tablet's preview.

Frames are drawn with Pillow (no OpenGL, so it runs on a worker thread beside the Kivy
window) and encoded with imageio-ffmpeg. This is the fallback used when no 3-D video
renderer is connected; on a device without ffmpeg, :func:`available` says why and the
teacher screen shows it instead of failing.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from app.story import TABLE_DEPTH_M, TABLE_WIDTH_M, Story
from retrieval.errors import StoryBeamError

# RGB 0..255, mirrors app/ui/art.py (kept separate: that module needs Kivy)
_BACKGROUNDS = {"sky": (158, 214, 250), "grass": (140, 204, 107), "night": (26, 33, 82), "sea": (51, 128, 204),
                "castle": (237, 219, 184), "forest": (77, 140, 77), "space": (15, 10, 36), "sand": (245, 214, 140)}
_CHARACTERS = {"robot": (115, 140, 191), "animal": (242, 153, 64), "child": (242, 128, 166)}


class VideoExportError(StoryBeamError):
    """A story video could not be written."""


def available() -> str | None:
    """None when MP4 export works here, else the reason it does not."""
    try:
        import imageio.v2  # noqa: F401
        import imageio_ffmpeg
        imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError) as exc:
        return f"no ffmpeg ({exc})"
    return None


def story_frames(story: Story, fps: float = 15.0, size: tuple[int, int] = (640, 426)):
    """Yield RGB frames (H, W, 3 uint8) of the whole story, scene after scene."""
    from PIL import Image, ImageDraw

    w, h = size

    def px(x: float, y: float) -> tuple[float, float]:
        return x / TABLE_WIDTH_M * w, h - y / TABLE_DEPTH_M * h

    for scene in story.scenes:
        n = max(1, int(round(scene.duration * fps)))
        base = Image.new("RGB", size, _BACKGROUNDS.get(scene.background, (0, 0, 0)))
        draw = ImageDraw.Draw(base)
        for c in scene.characters:
            if len(c.path) >= 2:
                draw.line([px(p[0], p[1]) for p in c.path], fill=(255, 255, 255), width=3)
        for i in range(n):
            frame = base.copy()
            d = ImageDraw.Draw(frame)
            for c in scene.characters:
                pos = c.position_at(i / fps)
                if pos is None:
                    continue
                cx, cy = px(*pos)
                r = 0.03 * w
                d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=_CHARACTERS.get(c.kind, (200, 200, 200)),
                          outline=(30, 30, 30), width=2)
            yield np.asarray(frame)


def export_story_mp4(story: Story, path: str | Path, fps: float = 15.0,
                     progress: Callable[[int], None] | None = None) -> Path:
    """Write ``story`` as an H.264 MP4 at ``path``; returns the path."""
    why = available()
    if why:
        raise VideoExportError(f"{path}: cannot export video: {why}")
    import imageio.v2 as imageio

    path = Path(path)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with imageio.get_writer(tmp, fps=fps, codec="libx264", macro_block_size=2, quality=6) as writer:
            for i, frame in enumerate(story_frames(story, fps)):
                writer.append_data(frame)
                if progress:
                    progress(i)
        tmp.replace(path)
    except (OSError, RuntimeError, ValueError) as exc:
        try:
            tmp.unlink(missing_ok=True)
        except (OSError, ValueError):
            pass
        raise VideoExportError(f"{path}: video export failed ({exc})") from None
    return path
