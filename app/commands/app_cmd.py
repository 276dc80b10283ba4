"""``storybeam app``: launch the tablet app, or draw one frame to a PNG and exit.

    storybeam app [--lang ja|en] [--db PATH] [--story ID | --demo-story]
                  [--screenshot PATH [--screen editor|home|play|projector|pin] [--size WxH]]
                  [--preview auto|3d|2d] [--renderer kivy-gl|pyrender] [--camera SOURCE] [--act-camera SOURCE]

A screenshot also writes ``PATH.json``: ``{"renderer": "kivy-gl" | "pyrender" | "2d",
"screen": ..., "clipped_widgets": [...]}`` -- which renderer drew the frame (play and
projector wait, up to ``SCREENSHOT_WAIT_S``, for their first 3-D frame) and the widgets
the window cuts off or another widget covers (:mod:`app.ui.layout_check`; empty when the
layout holds at this ``--size`` and ``--density``).

Cold start (process start to the first frame on screen) is measured and printed on every
launch, because it is what a teacher waits for in front of a class.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from retrieval.errors import StoryBeamError

SCREENS = ("editor", "home", "play", "projector", "pin", "teacher")
#: the longest a --screenshot of play / projector waits for its first 3-D frame
SCREENSHOT_WAIT_S = 90.0


def process_age_s() -> float | None:
    """Seconds since this process started (Linux /proc; None elsewhere)."""
    try:
        with open("/proc/self/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
        start_ticks = int(fields[19])  # field 22 overall: starttime, in clock ticks since boot
        with open("/proc/uptime") as fh:
            uptime = float(fh.read().split()[0])
        return uptime - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


_T_IMPORT = time.perf_counter()
_AGE_AT_IMPORT = process_age_s()


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("app", help="launch the StoryBeam tablet app (or save one screenshot)",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--lang", choices=("ja", "en"), help="interface language (default: last used, else ja)")
    p.add_argument("--db", metavar="PATH", help="profile database (default: $STORYBEAM_HOME/profile.db, "
                                                "~/.storybeam/profile.db)")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--story", metavar="ID", help="open this saved story in the scene editor")
    which.add_argument("--demo-story", action="store_true", help="open the bundled demo story")
    p.add_argument("--screenshot", metavar="PATH", help="draw one frame, save it as PNG and exit "
                                                        "(opens the demo story unless --story is given)")
    p.add_argument("--screen", choices=SCREENS, default=None, help="with --screenshot: which screen (default editor)")
    p.add_argument("--size", default="1280x800", help="window size WxH (default 1280x800)")
    p.add_argument("--density", type=_density, default=None,
                   help="screen density (Kivy's dp scale: 1, 1.33, 2, 3; default: the device's), to see "
                        "a tablet's layout on a desktop")
    p.add_argument("--camera", metavar="SOURCE",
                   help="the rig's camera: a device number (0), the Kivy camera (kivy, kivy:1: Android's "
                        "camera), a video file (session.mp4) or a folder of "
                        "images (frames/); a recording plays looped at its frame rate in place of the camera. "
                        "Calibration: camera.json + projector.json in the profile folder, else beside the "
                        "recording (default: the teacher's setting, else 0)")
    p.add_argument("--act-camera", metavar="SOURCE",
                   help="the camera \"Act it out\" films the child with: the Kivy camera (kivy:1, the "
                        "tablet's front camera: the default on Android), a device number (default 0 "
                        "elsewhere), or a video file / folder of images played looped in its place")
    p.add_argument("--preview", choices=("auto", "3d", "2d"), default="auto",
                   help="Play preview and projector screen: 3-D characters (the projector through the "
                        "tracked rig) or the 2-D top-down animation; auto = 3-D, except for a --screenshot "
                        "of another screen than play or projector")
    p.add_argument("--renderer", choices=("kivy-gl", "pyrender"), default="kivy-gl",
                   help="who draws the 3-D frames: Kivy's OpenGL ES 2 on the UI thread (default, every "
                        "device) or pyrender on the render thread (desktop, the reference renderer)")
    p.set_defaults(func=run)


def _density(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number such as 1, 1.33 or 2, got {text!r}") from None
    if not 0.5 <= value <= 4.0:
        raise argparse.ArgumentTypeError(f"{value} out of range (0.5 to 4)")
    return value


def _parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise StoryBeamError(f"--size: expected WIDTHxHEIGHT, got {text!r}") from None
    if not (320 <= w <= 4096 and 240 <= h <= 4096):
        raise StoryBeamError(f"--size: {w}x{h} out of range (320x240 to 4096x4096)")
    return w, h


def _camera_choice(option: str | None, db: Path) -> str:
    """``--camera``, else the teacher's saved choice, else device 0. A recording given with
    ``--camera`` is checked here (a missing or unreadable file is one clear error before any
    window opens); a saved choice that no longer opens falls back to device 0 with a warning.
    ``kivy`` / ``kivy:N`` (the Kivy camera) is opened by the app on its main thread."""
    from app.player.app_renderer import DEFAULT_CAMERA, check_camera_choice, saved_camera_choice  # deferred: app start-up only

    if option is not None:
        return check_camera_choice(option)  # raises CameraSourceError naming the problem
    return saved_camera_choice(db, DEFAULT_CAMERA)


def run(args: argparse.Namespace) -> int:
    # deferred: the story store (sqlite, numpy) loads only when the app launches, not for `storybeam --help`
    from app.story.storage import ProfileStore, StorageError, default_profile_path

    width, height = _parse_size(args.size)
    db = Path(args.db) if args.db else default_profile_path()
    if args.story:
        with ProfileStore(db) as store:  # fail here, plainly, before a window opens
            if not store.has_story(args.story):
                raise StorageError(f"{db}: no story with id '{args.story}'")
    camera = _camera_choice(args.camera, db)
    from app.player.app_renderer import check_camera_choice  # deferred: app start-up only
    act_camera = check_camera_choice(args.act_camera) if args.act_camera is not None else None  # before any window
    screenshot = Path(args.screenshot) if args.screenshot else None
    demo = args.demo_story or (screenshot is not None and not args.story)
    screen = args.screen or ("editor" if (args.story or demo) else None)

    from app.ui.env import prepare_kivy_env  # deferred: the UI layer loads only when the app launches
    if args.density is not None:  # read by kivy.metrics when Kivy is first imported
        os.environ["KIVY_METRICS_DENSITY"] = str(args.density)
    if screen == "teacher" and screenshot is None:
        raise StoryBeamError("--screen teacher goes with --screenshot (the app itself asks for the PIN)")
    prepare_kivy_env(headless=screenshot is not None, width=width, height=height)
    # deferred: Kivy reads its environment at import, so it comes after prepare_kivy_env()
    from kivy.clock import Clock
    from kivy.core.window import Window  # deferred: after prepare_kivy_env() (opens the window)

    from app.ui.app import StoryBeamApp  # deferred: imports Kivy, so after prepare_kivy_env()

    result = {"first_frame_s": None, "error": None}

    class _LaunchedApp(StoryBeamApp):
        def build(self):
            root = super().build()
            if screen == "teacher":  # a screenshot of the teacher's screen (--screenshot only, checked above)
                self.teacher_unlocked = True
                self.sm.current = "teacher"
            return root

        def on_start(self):
            Window.bind(on_flip=self._first_flip)

        def _first_flip(self, *_):
            Window.unbind(on_flip=self._first_flip)
            since = (_AGE_AT_IMPORT or 0.0) + (time.perf_counter() - _T_IMPORT)
            result["first_frame_s"] = since
            print(f"cold start: {since:.2f} s from process start to first drawn frame "
                  f"({'measured from /proc' if _AGE_AT_IMPORT is not None else 'from command start'})", flush=True)
            if screenshot is not None:
                Clock.schedule_once(self._capture, 0)

        def _capture(self, _dt):
            if use_3d and screen in ("play", "projector") and self.renderer is not None:
                drawn = getattr(self._shown_screen(), "drawn_by", None) or getattr(
                    getattr(self._shown_screen(), "player", None), "drawn_by", None)
                waited = time.perf_counter() - result.setdefault("capture_wait_t0", time.perf_counter())
                if drawn is None and self.renderer.alive and waited < SCREENSHOT_WAIT_S:
                    Clock.schedule_once(self._capture, 0.1)  # wait for the first 3-D frame
                    return
            try:
                screenshot.parent.mkdir(parents=True, exist_ok=True)
                with tempfile.TemporaryDirectory() as tmp:
                    Window.dispatch("on_draw")  # redraw into the back buffer (undefined after a flip)
                    written = Window.screenshot(name=os.path.join(tmp, "frame.png"))
                    shutil.move(written, screenshot)
                info = self._screenshot_info()
                Path(f"{screenshot}.json").write_text(json.dumps(info, indent=2))
                print(f"screenshot: {screenshot} (drawn by {info['renderer']})")
            except OSError as exc:
                result["error"] = f"{screenshot}: cannot save screenshot ({exc})"
            self.stop()

        def _shown_screen(self):
            return self.sm.current_screen

        def _screenshot_info(self) -> dict:
            """What drew the screenshot: ``renderer`` is "kivy-gl" or "pyrender" when the
            screen shows a 3-D frame, "2d" when it shows the 2-D drawing."""
            shown = self._shown_screen()
            drawn = getattr(shown, "drawn_by", None) or getattr(getattr(shown, "player", None), "drawn_by", None)
            if shown.name not in ("play", "projector") or (shown.name == "projector" and not shown.use_stage):
                drawn = None
            from kivy.metrics import Metrics  # deferred: Kivy, after the window

            from app.ui.layout_check import clipped_widgets  # deferred: Kivy, after the window
            info = {"renderer": drawn or "2d", "screen": shown.name, "size": list(Window.size),
                    "density": Metrics.density,
                    "clipped_widgets": clipped_widgets(list(reversed(Window.children)), Window.size),
                    "renderer_requested": args.renderer if use_3d else "2d",
                    "render_error": self.renderer.error if self.renderer is not None else None}
            frame = getattr(shown, "last_stage_frame", None)
            if frame is not None:
                info.update(view=frame.view, tracking=frame.state, live_rig=frame.live)
            if self.rig_camera is not None:
                info["rig_camera"] = self.rig_camera.name
            if self.projector_window is not None:  # the light also on the second display
                info["projector_window"] = list(self.projector_window.display)
            return info

    use_3d = args.preview == "3d" or (args.preview == "auto" and (screenshot is None or screen in ("play", "projector")))
    if use_3d and args.renderer == "pyrender" and importlib.util.find_spec("pyrender") is None:
        raise StoryBeamError("--renderer pyrender: pyrender is not installed (use --renderer kivy-gl)")
    factory = None
    if use_3d:  # the Play preview and the projector stage, on one render thread
        from app.player.app_renderer import app_renderer_factory  # deferred: the render thread's modules load on its first job
        factory = app_renderer_factory(db.parent, camera=camera, renderer=args.renderer)
    app = _LaunchedApp(db, lang=args.lang, story_id=args.story, demo=demo, start_screen=screen,
                       renderer_factory=factory, act_camera=act_camera)
    app.run()
    if result["error"]:
        raise StoryBeamError(result["error"])
    if screenshot is not None and not screenshot.is_file():
        raise StoryBeamError(f"{screenshot}: no frame was drawn")
    return 0
