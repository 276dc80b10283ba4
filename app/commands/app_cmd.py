"""``storybeam app``: launch the tablet app, or draw one frame to a PNG and exit.

    storybeam app [--lang ja|en] [--db PATH] [--story ID | --demo-story]
                  [--screenshot PATH [--screen editor|home|play|projector|pin] [--size WxH]]

Cold start (process start to the first frame on screen) is measured and printed on every
launch, because it is what a teacher waits for in front of a class.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import tempfile
import time
from pathlib import Path

from retrieval.errors import StoryBeamError

SCREENS = ("editor", "home", "play", "projector", "pin")


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
    p.add_argument("--preview", choices=("auto", "3d", "2d"), default="auto",
                   help="Play preview and projector screen: 3-D characters (pyrender, on its own thread; "
                        "the projector through the tracked rig) or the 2-D top-down animation; "
                        "auto = 3-D when pyrender is installed, except with --screenshot")
    p.set_defaults(func=run)


def _parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise StoryBeamError(f"--size: expected WIDTHxHEIGHT, got {text!r}") from None
    if not (320 <= w <= 4096 and 240 <= h <= 4096):
        raise StoryBeamError(f"--size: {w}x{h} out of range (320x240 to 4096x4096)")
    return w, h


def run(args: argparse.Namespace) -> int:
    # deferred: the story store (sqlite, numpy) loads only when the app launches, not for `storybeam --help`
    from app.story.storage import ProfileStore, StorageError, default_profile_path

    width, height = _parse_size(args.size)
    db = Path(args.db) if args.db else default_profile_path()
    if args.story:
        with ProfileStore(db) as store:  # fail here, plainly, before a window opens
            if not store.has_story(args.story):
                raise StorageError(f"{db}: no story with id '{args.story}'")
    screenshot = Path(args.screenshot) if args.screenshot else None
    demo = args.demo_story or (screenshot is not None and not args.story)
    screen = args.screen or ("editor" if (args.story or demo) else None)

    from app.ui.env import prepare_kivy_env  # deferred: the UI layer loads only when the app launches
    prepare_kivy_env(headless=screenshot is not None, width=width, height=height)
    # deferred: Kivy reads its environment at import, so it comes after prepare_kivy_env()
    from kivy.clock import Clock
    from kivy.core.window import Window  # deferred: after prepare_kivy_env() (opens the window)

    from app.ui.app import StoryBeamApp  # deferred: imports Kivy, so after prepare_kivy_env()

    result = {"first_frame_s": None, "error": None}

    class _LaunchedApp(StoryBeamApp):
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
            try:
                screenshot.parent.mkdir(parents=True, exist_ok=True)
                with tempfile.TemporaryDirectory() as tmp:
                    Window.dispatch("on_draw")  # redraw into the back buffer (undefined after a flip)
                    written = Window.screenshot(name=os.path.join(tmp, "frame.png"))
                    shutil.move(written, screenshot)
                print(f"screenshot: {screenshot}")
            except OSError as exc:
                result["error"] = f"{screenshot}: cannot save screenshot ({exc})"
            self.stop()

    use_3d = args.preview == "3d" or (args.preview == "auto" and screenshot is None
                                      and importlib.util.find_spec("pyrender") is not None)
    factory = None
    if use_3d:  # the Play preview and the projector stage, on one render thread
        from app.scene.stage import app_renderer_factory  # deferred: pyrender/OpenGL only for the 3-D preview
        factory = app_renderer_factory(db.parent)
    app = _LaunchedApp(db, lang=args.lang, story_id=args.story, demo=demo, start_screen=screen,
                       renderer_factory=factory)
    app.run()
    if result["error"]:
        raise StoryBeamError(result["error"])
    if screenshot is not None and not screenshot.is_file():
        raise StoryBeamError(f"{screenshot}: no frame was drawn")
    return 0
