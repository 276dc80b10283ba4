"""What every command does with its ``--json OUT`` option, in one place."""
from __future__ import annotations

import json
from pathlib import Path


def write_json_report(path: str | Path, report: dict, indent: int = 1) -> Path:
    """Write ``report`` as JSON to ``path`` (making its folder) and say where."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(report, indent=indent))
    print(f"wrote {path}")
    return path

