"""The layering the project promises: `retrieval/` usable without any UI or rendering
stack (it runs on Android without pyrender, and in batch jobs without a display), and
`ar/` usable without Kivy. Every module of each package is imported in a fresh
interpreter and the loaded modules are checked, so an indirect import is caught too."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent

FORBIDDEN = {
    "retrieval": ("kivy", "pyrender", "OpenGL", "trimesh", "cv2", "ar", "app"),
    "ar": ("kivy", "app"),
}


def _modules(package: str) -> list[str]:
    return sorted(f"{package}.{p.stem}" for p in (REPO / package).glob("*.py") if p.stem != "__init__")


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_package_imports_stay_inside_its_layer(package):
    code = (
        "import importlib, json, sys\n"
        f"for m in {_modules(package)!r}: importlib.import_module(m)\n"
        "print(json.dumps(sorted({n.split('.')[0] for n in sys.modules})))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    loaded = set(json.loads(out.stdout.strip().splitlines()[-1]))
    bad = sorted(loaded & set(FORBIDDEN[package]))
    assert not bad, f"importing {package}/ pulls in {bad}"
