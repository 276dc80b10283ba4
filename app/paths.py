"""Where the checkout's bundled files are: the one place that turns ``__file__`` into paths.

Everything the app and its commands read from the repository (the motion library, the
font, the UI art, the generated character previews) is named here, so moving a folder
means editing one line. ``ar/`` and ``retrieval/`` never import this module (they are
lower layers): they take their paths as arguments, and the app passes these.
"""
from __future__ import annotations

import os
from pathlib import Path

#: the checkout (the folder holding ``app/``, ``ar/``, ``retrieval/`` and ``assets/``)
REPO_ROOT = Path(__file__).resolve().parent.parent
ASSETS = REPO_ROOT / "assets"
#: the bundled motion library (``labels.csv`` and the clips it lists)
MOTIONS_DIR = ASSETS / "motions"
#: its moves from other studios (a labelled folder of its own, listed in the library's
#: labels.csv too): Act it out searches them beside any ``--data`` folder
MOVES_DIR = MOTIONS_DIR / "moves"
#: rest-pose previews of the characters (``storybeam characters`` writes them)
CHARACTERS_DIR = ASSETS / "characters"
#: the launcher icon and presplash (``python -m app.ui.make_icon`` writes them)
UI_ASSETS = ASSETS / "ui"
FONTS_DIR = ASSETS / "fonts"
#: the M+ font (Latin, kana and kanji) every label uses
FONT_PATH = FONTS_DIR / "Mplus1-Medium.otf"
#: printable boards (``storybeam board`` writes them)
BOARDS_DIR = ASSETS / "boards"
#: the shared data beside the checkout (``../shared/data``; ``$STORYBEAM_SHARED_DATA``
#: overrides it), and its CMU folder: what the benchmarks and stress harnesses use when
#: present (they fall back to the bundled library, and say so, when it is not)
SHARED_DATA = Path(os.environ.get("STORYBEAM_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))
SHARED_CMU = SHARED_DATA / "cmu"

__all__ = ["REPO_ROOT", "ASSETS", "MOTIONS_DIR", "MOVES_DIR", "CHARACTERS_DIR", "UI_ASSETS", "FONTS_DIR", "FONT_PATH",
           "BOARDS_DIR", "SHARED_DATA", "SHARED_CMU"]
