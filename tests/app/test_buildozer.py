"""buildozer.spec is a real, valid Android spec (checked offline, no SDK download)."""
from __future__ import annotations

import configparser
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _spec() -> configparser.ConfigParser:
    cp = configparser.ConfigParser()
    cp.read(REPO / "buildozer.spec")
    return cp


def test_buildozer_accepts_the_spec_offline():
    pytest.importorskip("buildozer")
    proc = subprocess.run([sys.executable, "-c", "from buildozer import Buildozer; Buildozer().set_target('android')"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "Check configuration tokens" in proc.stdout + proc.stderr


def test_requirements_only_have_python_for_android_recipes():
    spec = _spec()
    reqs = {r.split("==")[0].strip() for r in spec["app"]["requirements"].split(",")}
    assert {"python3", "kivy", "numpy", "opencv", "sqlite3", "tflite-runtime"} <= reqs
    assert not reqs & {"numba", "llvmlite", "pyrender", "pyopengl", "trimesh", "opencv-contrib-python-headless"}
    assert spec["buildozer"]["warn_on_root"] == "0"
    assert "otf" in spec["app"]["source.include_exts"]
    # the vendored pose models (ar.body) and their licence notes ship in the APK
    assert "tflite" in spec["app"]["source.include_exts"].split(",")
    assert "assets/models/blazepose/*" in spec["app"]["source.include_patterns"].split(",")
    assert (REPO / "main.py").is_file()  # python-for-android's entry point
    for key in ("icon.filename", "presplash.filename"):
        assert (REPO / spec["app"][key].replace("%(source.dir)s/", "")).is_file(), key
