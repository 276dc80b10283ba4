"""What every command does with its ``--json OUT`` option, and the Act-it-out library's
``--moves`` option, in one place."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from app.paths import MOVES_DIR
from retrieval.errors import StoryBeamError


def write_json_report(path: str | Path, report: dict, indent: int = 1) -> Path:
    """Write ``report`` as JSON to ``path`` (making its folder) and say where."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(report, indent=indent))
    print(f"wrote {path}")
    return path


def emit_json_report(dest: str | Path | None, report: dict, indent: int = 1) -> None:
    """``--json DEST`` of a command that may print its report: ``"-"`` writes the JSON to
    standard output, a path writes the file (:func:`write_json_report`), nothing else
    writes nothing."""
    if dest == "-":
        json.dump(report, sys.stdout, indent=indent)
        sys.stdout.write("\n")
    elif dest:
        write_json_report(dest, report, indent)


def add_moves_argument(parser) -> None:
    """``--moves DIR|none``: the labelled folder of moves from other studios that joins an
    Act-it-out library (default: the app's, ``assets/motions/moves``)."""
    parser.add_argument("--moves", default=None, metavar="DIR|none",
                        help="Act it out: a labelled folder whose clips join the --data library "
                             "(default: the app's moves from other studios, assets/motions/moves; "
                             "'none': --data alone)")


def moves_folder(value: str | None) -> Path | None:
    """The folder ``--moves`` names (None: ``none``). Raises :class:`StoryBeamError` for a
    folder without ``labels.csv``."""
    if value is not None and value.strip().lower() == "none":
        return None
    folder = Path(value) if value else MOVES_DIR
    if not (folder / "labels.csv").is_file():
        raise StoryBeamError(f"--moves {folder}: no labels.csv (a labelled folder, or 'none')")
    return folder
