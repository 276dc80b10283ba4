"""Kivy environment set-up; must run before anything imports kivy.

Kivy reads environment variables and its config when first imported, so the command and
the tests call :func:`prepare_kivy_env` first. Headless runs (a screenshot, CI) use SDL's
``offscreen`` video driver, which still has OpenGL through EGL.
"""
from __future__ import annotations

import os
import sys
import tempfile


def prepare_kivy_env(headless: bool = False, width: int = 1280, height: int = 800) -> None:
    """Set Kivy's environment: no argv parsing, a writable KIVY_HOME, quiet logs, and
    (headless or no display) the offscreen SDL driver. Call before importing kivy."""
    if "kivy" in sys.modules and "kivy.core.window" in sys.modules:
        return  # too late to change anything; the caller already has a window
    os.environ["KIVY_NO_ARGS"] = "1"
    os.environ.setdefault("KIVY_NO_CONSOLELOG", "1")
    os.environ.setdefault("KIVY_LOG_MODE", "PYTHON")
    if "KIVY_HOME" not in os.environ:
        home = os.path.join(os.path.expanduser("~"), ".kivy")
        if not os.access(os.path.dirname(home), os.W_OK):
            home = os.path.join(tempfile.gettempdir(), "storybeam-kivy")
        os.environ["KIVY_HOME"] = home
    os.makedirs(os.environ["KIVY_HOME"], exist_ok=True)
    no_display = sys.platform.startswith("linux") and not os.environ.get("DISPLAY") \
        and not os.environ.get("WAYLAND_DISPLAY") and "ANDROID_ARGUMENT" not in os.environ
    if headless or no_display:
        os.environ["SDL_VIDEODRIVER"] = "offscreen"
    # deferred: Kivy reads the environment set above when it is first imported
    from kivy.config import Config
    Config.set("graphics", "width", str(width))
    Config.set("graphics", "height", str(height))
    Config.set("input", "mouse", "mouse,disable_multitouch")
    Config.set("kivy", "exit_on_escape", "0")
