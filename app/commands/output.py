"""What every command does with its ``--json OUT`` option, in one place."""
from __future__ import annotations

import json
import sys
from pathlib import Path


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
