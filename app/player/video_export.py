"""A story as one MP4: the film a child takes home (default), or the rig's views.

Views (``view``):

* ``story`` (default) -- the story as the child made it (:class:`app.player.story_film.StoryFilm`):
  a title card, each scene's place with its characters large on their paths with their
  motions (pyrender, a virtual camera framing the cast), an ending card with the
  celebration's chime; 1280x720 at 30 fps unless told otherwise;
* ``camera`` -- what an audience sees on the table: the projector stage
  (:class:`app.player.stage.StageRenderer`) through the synthetic rig, its camera frame with
  the projected characters on the board;
* ``overhead`` -- the Play preview's view of the whole table from the child's side
  (:class:`app.player.preview.ScenePreviewRenderer`);
* ``projector`` -- the projector's own image (black = no light).

3-D frames need OpenGL (pyrender, EGL). The app runs the export in a child process
(:func:`export_in_subprocess`): a GL context of its own, beside the Kivy window's, and
the UI thread stays free. When 3-D rendering is unavailable (no pyrender, no GL, a
failing first frame) the export falls back to the top-down 2-D animation drawn with
Pillow (for ``story``: between the same title and ending cards) and says so in the
result (the teacher screen and the log show it). Encoding is imageio-ffmpeg; without
ffmpeg, :func:`available` says why.

Sound (issue 14, 29): when a scene has a voice and the caller says where the story's
assets are (``narration_dir``), :func:`story_audio` lays each scene's narration at the
first sample of that scene's first video frame on one 48 kHz mono track that is exactly
as long as the video (scene ``i`` spans ``round(duration_i * fps)`` frames, after
``lead`` frames of title card, so its audio spans the samples between the cumulative frame
boundaries times ``48000 / fps``, rounded -- boundaries never drift), resampled with a
polyphase filter (:func:`scipy.signal.resample_poly`); the story film adds the
celebration's chime (:func:`app.player.celebration.chime`) on the ending card; silence
elsewhere. ffmpeg (imageio-ffmpeg's binary) then muxes it as AAC beside the untouched
H.264 stream, so the audio stream's duration equals the video's.

By hand (and in the app's child process): ``storybeam export STORY.json OUT.mp4
[--view story|camera|overhead|projector|2d] [--fps N] [--size WxH]`` (:mod:`app.commands.export_cmd`).

This module stays light at import (numpy and the story model): the app imports it at
start-up, on Android too, where imageio, Pillow and pyrender are absent.
"""
from __future__ import annotations

import atexit
import importlib.util
import json
import logging
import math
import subprocess
import sys
import tempfile
import wave
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from app.paths import REPO_ROOT
from app.player.cards import CHARACTER_COLOURS, FILM_FPS, FILM_SIZE, PLACES, card_frames, with_cards
from app.player.celebration import chime
from app.story import TABLE_DEPTH_M, TABLE_WIDTH_M, NarrationError, Story, StoryError, read_audio
from retrieval.durable import durable_move, fsync_file, make_dirs
from retrieval.errors import StoryBeamError

VIEWS = ("story", "camera", "overhead", "projector", "2d")
#: the rig views' rate (they keep the rig's size); the film's is FILM_FPS
RIG_FPS = 15.0
log = logging.getLogger(__name__)


class VideoExportError(StoryBeamError):
    """A story video could not be written."""


@dataclass
class ExportResult:
    """Where the video went and how it was drawn (``mode``: the view, or ``2d``)."""

    path: Path
    mode: str
    frames: int
    note: str = ""  # why the 2-D fallback was used

    def __str__(self) -> str:
        return f"{self.path} ({self.mode}, {self.frames} frames{'; ' + self.note if self.note else ''})"


def available() -> str | None:
    """None when MP4 export works here, else the reason it does not."""
    try:
        import imageio.v2  # noqa: F401  # optional: imageio (absent on Android)
        import imageio_ffmpeg  # optional: imageio-ffmpeg (absent on Android)
        imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError) as exc:
        return f"no ffmpeg ({exc})"
    return None


def default_fps(view: str) -> float:
    return FILM_FPS if view == "story" else RIG_FPS


def frame_count(story: Story, fps: float, view: str = "camera") -> int:
    """Frames of the video: every scene's, and for the story film its two cards."""
    cards = sum(card_frames(fps)) if view == "story" else 0
    return cards + sum(max(1, int(round(scene.duration * fps))) for scene in story.scenes)


#: Sample rate of an exported video's sound track (Hz).
AUDIO_RATE = 48000


def has_narration(story: Story) -> bool:
    return any(scene.narration is not None for scene in story.scenes)


def story_audio(story: Story, fps: float, narration_dir: str | Path | None,
                rate: int = AUDIO_RATE, film: bool = False) -> tuple[np.ndarray, list[str]]:
    """The story's sound track as int16 mono samples at ``rate`` -- exactly
    ``frame_count(story, fps, view) / fps`` seconds (rounded to a sample) -- and a list of
    problems (a narration file missing or damaged: that scene stays silent).

    Scene ``i`` starts at sample ``round(F_i * rate / fps)``, ``F_i`` the number of video
    frames before it (for the story film, ``film=True``, the title card's included), so
    every narration starts on its scene's first frame; the film's ending card carries the
    celebration's chime. ``narration_dir`` None: no voices."""
    from scipy.signal import resample_poly  # deferred: scipy only when a narrated story is exported

    lead, tail = card_frames(fps) if film else (0, 0)
    counts = [lead] + [max(1, int(round(scene.duration * fps))) for scene in story.scenes] + [tail]
    bounds = [int(round(f * rate / fps)) for f in np.concatenate([[0], np.cumsum(counts)])]
    track = np.zeros(bounds[-1], np.int16)
    problems: list[str] = []
    if film:
        ring = chime(rate)[: bounds[-1] - bounds[-2]]
        track[bounds[-2]:bounds[-2] + len(ring)] = ring
    for i, scene in enumerate(story.scenes):
        if scene.narration is None or narration_dir is None:
            continue
        try:
            audio = read_audio(Path(narration_dir) / scene.narration.asset)
        except NarrationError as exc:
            problems.append(f"scene {i + 1} is silent: {exc}")
            continue
        samples = audio.samples.astype(np.float64)
        if audio.rate != rate:
            g = math.gcd(audio.rate, rate)
            samples = resample_poly(samples, rate // g, audio.rate // g)
        a, b = bounds[i + 1], bounds[i + 2]  # bounds[0:2] span the title card (empty without one)
        part = np.clip(np.round(samples[: b - a]), -32768, 32767).astype(np.int16)
        track[a:a + len(part)] = part
    return track, problems


def _write_wav(path: Path, samples: np.ndarray, rate: int) -> None:
    with wave.open(str(path), "wb") as wf:
        wf.setnchannels(1)
        wf.setsampwidth(2)
        wf.setframerate(rate)
        wf.writeframes(samples.astype("<i2").tobytes())


def mux_audio(video: Path, samples: np.ndarray, out: Path, rate: int = AUDIO_RATE) -> None:
    """Write ``out``: ``video``'s H.264 stream copied and ``samples`` as an AAC stream
    (imageio-ffmpeg's ffmpeg binary). Raises :class:`VideoExportError`."""
    import imageio_ffmpeg  # optional: imageio-ffmpeg (absent on Android; available() said it is here)

    wav = out.with_name(f".{out.stem}.audio.wav")
    try:
        _write_wav(wav, samples, rate)
        cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-y", "-v", "error", "-i", str(video), "-i", str(wav),
               "-map", "0:v:0", "-map", "1:a:0", "-c:v", "copy", "-c:a", "aac", "-b:a", "128k", "-ar", str(rate),
               "-ac", "1", "-f", "mp4", str(out)]
        done = subprocess.run(cmd, capture_output=True, text=True, errors="replace")
        if done.returncode != 0:
            last = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
            raise VideoExportError(f"{out}: adding the narration failed ({last})")
    finally:
        wav.unlink(missing_ok=True)


def story_frames(story: Story, fps: float = RIG_FPS, size: tuple[int, int] = (640, 426)):
    """Yield top-down 2-D RGB frames (H, W, 3 uint8) of the whole story, scene after
    scene: the fallback when 3-D rendering is unavailable."""
    from PIL import Image, ImageDraw  # optional: Pillow (absent on Android, where there is no export)

    w, h = size

    def px(x: float, y: float) -> tuple[float, float]:
        return x / TABLE_WIDTH_M * w, h - y / TABLE_DEPTH_M * h

    for scene in story.scenes:
        n = max(1, int(round(scene.duration * fps)))
        base = Image.new("RGB", size, PLACES[scene.background].ground if scene.background in PLACES else (0, 0, 0))
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
                d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=CHARACTER_COLOURS.get(c.kind, (200, 200, 200)),
                          outline=(30, 30, 30), width=2)
            yield np.asarray(frame)


def story_frames_3d(story: Story, fps: float = RIG_FPS, view: str = "camera",
                    size: tuple[int, int] = FILM_SIZE) -> Iterator[np.ndarray]:
    """Yield 3-D RGB frames of the whole story (see the module docstring for views;
    ``size`` is the story film's).

    Creates the GL renderer on the calling thread and closes it at the end."""
    if view == "story":
        from app.player.story_film import StoryFilm  # optional: the 3-D scene layer (the caller falls back to 2-D)
        film = StoryFilm(story, fps, size)
        try:
            film.check()  # no GL here: raise before the first card, so the caller falls back
            yield from film.frames()
        finally:
            film.close()
        return
    if view == "overhead":
        from app.player.preview import ScenePreviewRenderer  # optional: pyrender (the caller falls back to 2-D)
        renderer = ScenePreviewRenderer(fps=30.0)
        try:
            for scene in story.scenes:
                for i in range(max(1, int(round(scene.duration * fps)))):
                    yield renderer.render(scene, i / fps)
        finally:
            renderer.close()
        return
    from app.player.stage import StageRenderer  # optional: pyrender (the caller falls back to 2-D)
    from ar.rig import SyntheticRig  # optional: as above (OpenCV), with the stage

    # the synthetic hand moves at the video's frame rate; the rig is never a live camera here
    stage = StageRenderer(rig=SyntheticRig(fps=fps), fps=30.0, rig_fps=fps)
    try:
        for scene in story.scenes:
            for i in range(max(1, int(round(scene.duration * fps)))):
                yield stage.render(scene, i / fps, view).rgb
    finally:
        stage.close()


def export_story_mp4(story: Story, path: str | Path, fps: float | None = None,
                     progress: Callable[[int], None] | None = None, view: str = "story",
                     narration_dir: str | Path | None = None, size: tuple[int, int] | None = None) -> ExportResult:
    """Write ``story`` as an H.264 MP4 at ``path``.

    ``view`` is ``story`` (the film, the default), ``camera``, ``overhead``, ``projector``
    (3-D) or ``2d``; ``fps`` defaults to 30 for the film and 15 for the others, ``size``
    (the film's only) to 1280x720. A 3-D view that cannot render (no pyrender or GL) falls
    back to ``2d`` (the film keeps its cards); the result's ``note`` says why.
    ``progress(i)`` is called after frame ``i`` is written. With ``narration_dir`` (the
    folder of the story's assets) and a narrated scene, the video gets its voices (see the
    module docstring); a narration that cannot be read leaves its scene silent and is
    named in the note. The film always has its sound track (the ending's chime)."""
    if view not in VIEWS:
        raise VideoExportError(f"{path}: unknown view {view!r}; choose one of {', '.join(VIEWS)}")
    fps = float(fps) if fps else default_fps(view)
    film = view == "story"
    size = tuple(size) if size else FILM_SIZE
    if film and (size[0] < 64 or size[1] < 48 or size[0] % 2 or size[1] % 2):
        raise VideoExportError(f"{path}: the video size must be even and at least 64x48 (got {size[0]}x{size[1]})")
    if not 1.0 <= fps <= 60.0:
        raise VideoExportError(f"{path}: frames per second must be between 1 and 60 (got {fps:g})")
    why = available()
    if why:
        raise VideoExportError(f"{path}: cannot export video: {why}")
    import imageio.v2 as imageio  # optional: imageio (absent on Android; available() said it is here)

    def flat() -> Iterator[np.ndarray]:
        return with_cards(story, fps, size, story_frames(story, fps, size)) if film else story_frames(story, fps)

    path = Path(path)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    mode, note, written = view, "", 0
    frames: Iterator[np.ndarray] = flat() if view == "2d" else story_frames_3d(story, fps, view, size)
    try:
        make_dirs(path.parent)
        if view != "2d":
            try:
                first = next(frames)
            except StopIteration:
                first = None
            except Exception as exc:  # noqa: BLE001 - no pyrender / no GL / a broken driver: fall back
                note = f"3-D rendering unavailable ({type(exc).__name__}: {exc}); top-down 2-D video instead"
                log.warning("%s: %s", path, note)
                mode, first = "2d", None
                frames = flat()
            if first is not None:
                frames = _chain(first, frames)
        with imageio.get_writer(tmp, fps=fps, codec="libx264", macro_block_size=2, quality=6,
                                pixelformat="yuv420p") as writer:
            for i, frame in enumerate(frames):
                writer.append_data(frame)
                written += 1
                if progress:
                    progress(i)
        if film or (narration_dir is not None and has_narration(story)):
            samples, problems = story_audio(story, fps, narration_dir, film=film)
            if problems:
                note = "; ".join([note] + problems if note else problems)
                log.warning("%s: %s", path, "; ".join(problems))
            muxed = path.with_name(f".{path.stem}.tmp-audio{path.suffix}")
            try:
                mux_audio(tmp, samples, muxed)
                muxed.replace(tmp)
            finally:
                muxed.unlink(missing_ok=True)
        fsync_file(tmp)  # durable (retrieval.durable): the video reaches the disk before its name
        durable_move(tmp, path)
    except (OSError, RuntimeError, ValueError, VideoExportError) as exc:
        try:
            tmp.unlink(missing_ok=True)
        except (OSError, ValueError):
            pass
        if isinstance(exc, VideoExportError):
            raise
        raise VideoExportError(f"{path}: video export failed ({exc})") from None
    finally:
        close = getattr(frames, "close", None)
        if close:
            close()
    return ExportResult(path, mode, written, note)


def _chain(first, rest):
    yield first
    yield from rest


# ---------------------------------------------------------------------------- child process
_children: set = set()


@atexit.register
def _stop_children() -> None:
    """An export must not outlive the app that asked for it (it would keep a core busy)."""
    for proc in list(_children):
        if proc.poll() is None:
            proc.terminate()


def export_in_subprocess(story: Story, path: str | Path, fps: float | None = None, view: str = "story",
                         progress: Callable[[int, int], None] | None = None,
                         narration_dir: str | Path | None = None,
                         size: tuple[int, int] | None = None) -> ExportResult:
    """Run :func:`export_story_mp4` in a child Python process (its own GL context, away
    from the Kivy window's); ``progress(done, total)`` follows its frame count. Blocks:
    call it from a worker thread."""
    path = Path(path)
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False, encoding="utf-8") as fh:
        json.dump(story.to_dict(), fh)
        story_json = fh.name
    # the child is `storybeam export` (app.commands.export_cmd), run from the checkout
    cmd = ([sys.executable, "-m", "app.cli", "export", story_json, str(path), "--view", view, "--progress-lines"]
           + (["--fps", str(fps)] if fps else []) + (["--size", f"{size[0]}x{size[1]}"] if size else [])
           + (["--narration-dir", str(narration_dir)] if narration_dir is not None else []))
    root = str(REPO_ROOT)
    proc = None
    # stderr goes to a file: a chatty child must never block on a full pipe nobody reads
    with tempfile.TemporaryFile("w+", encoding="utf-8", errors="replace") as err_file:
        try:
            proc = subprocess.Popen(cmd, cwd=root, stdout=subprocess.PIPE, stderr=err_file, text=True)
            _children.add(proc)
            result_line = ""
            for line in proc.stdout:
                if line.startswith("progress ") and progress:
                    done, total = (int(v) for v in line.split()[1:3])
                    progress(done, total)
                elif line.startswith("result "):
                    result_line = line[len("result "):]
            proc.wait()
        except OSError as exc:
            raise VideoExportError(f"{path}: cannot start the video export ({exc})") from None
        finally:
            if proc is not None:
                _children.discard(proc)
            Path(story_json).unlink(missing_ok=True)
        err_file.seek(0)
        err = err_file.read()
    if proc.returncode != 0 or not result_line:
        last = [ln for ln in err.strip().splitlines() if ln.strip()][-1:] or [f"exit status {proc.returncode}"]
        raise VideoExportError(f"{path}: video export failed ({last[0]})")
    data = json.loads(result_line)
    return ExportResult(Path(data["path"]), data["mode"], data["frames"], data["note"])


def app_exporter(view: str = "story", fps: float | None = None,
                 narration_dirs: Callable[[Story], Path] | None = None, size: tuple[int, int] | None = None):
    """The exporter the app calls from a worker thread: ``export(story, path,
    progress(done, total)) -> ExportResult``. 3-D in a child process when pyrender is
    installed; otherwise (a slim install) the 2-D video in the calling thread (the film
    keeps its cards and sound), with the reason in the result's ``note`` and the log.
    ``narration_dirs(story)``: the folder of a story's assets, for its voices; ``size``:
    the film's (default 1280x720)."""
    def voices(story: Story) -> Path | None:
        return narration_dirs(story) if narration_dirs is not None and has_narration(story) else None

    if view != "2d" and importlib.util.find_spec("pyrender") is not None:
        def export(story: Story, path: str | Path, progress=None) -> ExportResult:
            return export_in_subprocess(story, path, fps, view, progress, voices(story), size)
        return export

    flat = "story" if view == "story" else "2d"

    def export_2d(story: Story, path: str | Path, progress=None) -> ExportResult:
        total = frame_count(story, fps or default_fps(flat), flat)
        result = export_story_mp4(story, path, fps, (lambda i: progress(i + 1, total)) if progress else None, flat,
                                  voices(story), size)
        if view != "2d" and not result.note:
            result.mode = "2d"
            result.note = "3-D rendering unavailable (pyrender is not installed); top-down 2-D video instead"
            log.warning("%s: %s", path, result.note)
        return result
    return export_2d


def read_story(path: str | Path) -> Story:
    """A story from its JSON file (``Story.to_dict`` form), or :class:`VideoExportError`
    naming the file."""
    try:
        return Story.from_dict(json.loads(Path(path).read_text(encoding="utf-8")))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, StoryError) as exc:
        # the story model's own errors name the field ("story.scenes[0]: ..."), not the file
        raise VideoExportError(f"{path}: cannot read the story ({exc})") from None


__all__ = ["VIEWS", "FILM_SIZE", "FILM_FPS", "RIG_FPS", "default_fps", "VideoExportError", "ExportResult", "available",
           "frame_count", "AUDIO_RATE", "has_narration",
           "story_audio", "mux_audio", "story_frames",
           "story_frames_3d", "export_story_mp4", "export_in_subprocess", "app_exporter", "read_story"]
