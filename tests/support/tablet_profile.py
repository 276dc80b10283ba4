"""Run the UI driver as on python-for-android: only the tablet's packages can be imported.

``python tests/support/tablet_profile.py SCENARIO DB OUT`` installs :class:`Blocker` -- a
meta-path finder at the front of ``sys.meta_path`` that answers ``ModuleNotFoundError``
for numba, llvmlite, pyrender, PyOpenGL (``OpenGL``), trimesh, matplotlib and imageio
(:data:`BLOCKED`), and, stricter than the issue asks, for *every* third-party top-level
module that is not one of :data:`TABLET_MODULES` (what buildozer.spec's requirements put
on the device) or of :data:`HARNESS_MODULES` (the touch simulator's) -- then runs
tests/support/ui_driver.py as ``__main__`` with the same arguments. Every refused import
is recorded in ``OUT/blocked.json`` (an optional import that was tried and fell back is
fine; the flow must still work) and every module the run imported in ``OUT/modules.json``.

Kivy is limited to the providers it uses on Android (SDL2 window, text, image, audio),
so its desktop-only optional providers (PIL, GStreamer, ffpyplayer, ...) are not tried.
"""
from __future__ import annotations

import atexit
import importlib.abc
import json
import os
import runpy
import sys
from pathlib import Path

#: top-level packages named by the issue as absent on the tablet
BLOCKED = ("numba", "llvmlite", "pyrender", "OpenGL", "trimesh", "matplotlib", "imageio", "imageio_ffmpeg")
#: python-for-android recipe -> the top-level modules it puts on the device (the kivy
#: recipe also installs its ``python_depends``: certifi, chardet, idna, requests, urllib3,
#: filetype -- python-for-android's pythonforandroid/recipes/kivy/__init__.py, Kivy 2.3.1)
RECIPE_MODULES = {"kivy": ("kivy", "filetype", "certifi", "chardet", "idna", "requests", "urllib3"), "numpy": ("numpy",), "scipy": ("scipy",), "opencv": ("cv2",),
                  "sqlite3": ("sqlite3", "_sqlite3"), "pyjnius": ("jnius",),
                  "tflite-runtime": ("tflite_runtime",)}
#: desktop stand-ins for a recipe's module, allowed here and counted as that recipe: the
#: desktop has no ``tflite_runtime`` for numpy 2, and ``ai_edge_litert`` is the same TFLite
#: interpreter (the same ``Interpreter`` API; ar.body.models tries it first, then
#: ``tflite_runtime``, which the tflite-runtime recipe puts on the device)
DESKTOP_STANDINS = {"ai_edge_litert": "tflite-runtime"}
TABLET_MODULES = tuple(m for mods in RECIPE_MODULES.values() for m in mods) + tuple(DESKTOP_STANDINS)
#: the simulated touches (kivy.tests.common) import pytest, and scripts/coverage.sh starts
#: coverage.py in every child process: allowed, never counted as the app's
HARNESS_MODULES = ("pytest", "_pytest", "pluggy", "iniconfig", "py", "pygments", "packaging", "tomli", "exceptiongroup",
                   "coverage", "$coverage")  # "$coverage": a name coverage.py's debug output puts in sys.modules
#: StoryBeam and the test support modules
OWN_MODULES = ("app", "ar", "retrieval", "main", "tests", "ui_driver", "ui_touch", "ui_scenarios", "tablet_scenarios",
               "narration_scenarios", "act_scenarios", "child_scenarios", "story_end_scenarios", "gate_scenarios",
               "tablet_profile")


def is_third_party(top: str) -> bool:
    """Neither the standard library, nor StoryBeam's, nor a private C module."""
    return not (top in sys.stdlib_module_names or top in OWN_MODULES or top.startswith("_")
                or top in sys.builtin_module_names or top == "cython_runtime")  # made by compiled modules


class Blocker(importlib.abc.MetaPathFinder):
    """Refuses :data:`BLOCKED` and every third-party module the tablet does not have."""

    def __init__(self) -> None:
        self.refused: list[str] = []

    def find_spec(self, fullname, path=None, target=None):
        top = fullname.split(".")[0]
        if top in BLOCKED or (is_third_party(top) and top not in TABLET_MODULES + HARNESS_MODULES):
            self.refused.append(fullname)
            raise ModuleNotFoundError(f"No module named {fullname!r} (blocked: the tablet profile)", name=fullname)
        return None


def main() -> None:
    out = Path(sys.argv[3])
    out.mkdir(parents=True, exist_ok=True)
    blocker = Blocker()
    sys.meta_path.insert(0, blocker)
    already = [m for m in sys.modules if m.split(".")[0] in BLOCKED
               or (is_third_party(m.split(".")[0]) and not m.startswith("__editable__")
                   and m.split(".")[0] not in HARNESS_MODULES)]
    if already:
        raise SystemExit(f"tablet profile: {already} were imported before the blocker")
    for key, value in (("KIVY_WINDOW", "sdl2"), ("KIVY_TEXT", "sdl2"), ("KIVY_IMAGE", "sdl2,tex"),
                       ("KIVY_AUDIO", "sdl2"), ("KIVY_VIDEO", "null"), ("KIVY_CAMERA", "opencv")):
        os.environ.setdefault(key, value)
    def record() -> None:
        (out / "blocked.json").write_text(json.dumps(sorted(set(blocker.refused))))
        (out / "modules.json").write_text(json.dumps(sorted({m.split(".")[0] for m in sys.modules})))
    atexit.register(record)
    driver = Path(__file__).with_name("ui_driver.py")
    sys.path.insert(0, str(driver.parent))
    sys.argv = [str(driver), *sys.argv[1:]]
    runpy.run_path(str(driver), run_name="__main__")


if __name__ == "__main__":
    main()
