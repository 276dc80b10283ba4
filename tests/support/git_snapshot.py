"""A throw-away snapshot of a public repository, as `fetch` leaves one: a bare git
directory holding the given files in one commit. For the tests of the scripts that
materialise development data from fetched repositories (scripts/hdm05.py, scripts/utd_mhad.py)."""
from __future__ import annotations

import subprocess
from pathlib import Path


def bare_snapshot(tmp_path: Path, files: dict[str, bytes | str]) -> tuple[Path, str]:
    """(bare git directory, commit) of one commit holding ``files`` (path -> content)."""
    src = tmp_path / "src"
    for name, content in files.items():
        path = src / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, str):
            path.write_text(content)
        else:
            path.write_bytes(content)

    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(src), *args], check=True, capture_output=True, text=True).stdout.strip()

    git("init", "-q")
    git("add", ".")
    git("-c", "user.email=t@t", "-c", "user.name=t", "commit", "-qm", "snapshot")
    bare = tmp_path / "repo"
    subprocess.run(["git", "clone", "-q", "--bare", str(src), str(bare)], check=True, capture_output=True)
    return bare, git("rev-parse", "HEAD")
