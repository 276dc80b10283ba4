"""Materialise third-party conversions of CMU trials (issue 31's cross-skeleton check).

    python scripts/cmu_third.py --out /work/data/cmu-third [--mirror /work/.mirror]
                                [--manifest lab/datasets/cmu_third_manifest.csv] [--sources mocapnet,...]

The files are **not** in the repository (their repository states no licence; CMU's own
terms would allow it, but nothing here needs them committed).
``lab/datasets/cmu_third_manifest.csv`` names each one: the ``source`` (the converter's
release, one output folder each), the library ``trial`` it converts, the public GitHub
``repository``, the ``commit`` that holds that version of the file, its ``path``, who
converted it (``converter``), what the target ``skeleton`` is, the ``licence`` found and
``notes`` (frame counts, a header's frame time).

Getting the repositories: ``MIRROR/<owner>+<name>/repo`` is a bare git directory, as a
``fetch`` of ``github:<owner>/<name>`` leaves it (or ``git clone --bare`` of the
repository). Every file is read from its named commit with ``git show COMMIT:PATH`` —
several sources are different commits of the same path.

Output: ``OUT/<source>/<trial>.bvh``, byte for byte, the folder ``storybeam eval --identity
--pose-identity --skeleton-from OUT/<source>`` reads (files matched to the library by
name). These conversions are for measuring only: no feature weight or threshold is tuned
on them (docs/notebook/results.md, issue 31). A row whose repository or commit is missing
is reported and skipped; the exit status is 1 if any was.
"""
from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MANIFEST = REPO / "lab" / "datasets" / "cmu_third_manifest.csv"
COLUMNS = ("source", "trial", "repository", "commit", "path", "converter", "skeleton", "licence", "notes")


class ManifestError(ValueError):
    """A malformed manifest row (file and line in the message)."""


def read_manifest(path: Path) -> list[dict[str, str]]:
    """The manifest's rows, checked: every column present and filled in, a 40-digit commit,
    a trial named like the library's (``02_03``), each (source, trial) once."""
    with open(path, newline="", encoding="utf-8") as f:
        table = list(csv.reader(f))
    header = table[0] if table else []
    absent = [c for c in COLUMNS if c not in header]
    if absent:
        raise ManifestError(f"{path}:1: missing column(s) {', '.join(absent)}")
    rows: list[dict[str, str]] = []
    for line, values in enumerate(table[1:], 2):
        row = dict(zip(header, values))
        _check_row(row, f"{path}:{line}", {(r["source"], r["trial"]) for r in rows})
        rows.append(row)
    return rows


def _check_row(row: dict[str, str], where: str, seen: set[tuple[str, str]]) -> None:
    empty = [c for c in COLUMNS if not (row.get(c) or "").strip()]
    if empty:
        raise ManifestError(f"{where}: empty column(s) {', '.join(empty)}")
    if len(row["commit"]) != 40 or any(ch not in "0123456789abcdef" for ch in row["commit"]):
        raise ManifestError(f"{where}: commit {row['commit']!r} is not 40 hex digits")
    subject, _, take = row["trial"].partition("_")
    if not (subject.isdigit() and take.isdigit()):
        raise ManifestError(f"{where}: trial {row['trial']!r} is not SUBJECT_TAKE")
    if (row["source"], row["trial"]) in seen:
        raise ManifestError(f"{where}: {row['source']}/{row['trial']} listed twice")


def materialise(rows: list[dict[str, str]], mirror: Path, out: Path) -> list[str]:
    """Write every row's file to ``out/<source>/<trial>.bvh``; the problems (skipped rows)."""
    problems = []
    for row in rows:
        git_dir = mirror / row["repository"].replace("/", "+") / "repo"
        if not git_dir.is_dir():
            problems.append(f"{row['source']}/{row['trial']}: no snapshot of {row['repository']} at {git_dir} "
                            f"(fetch github:{row['repository']})")
            continue
        blob = subprocess.run(["git", "--git-dir", str(git_dir), "show", f"{row['commit']}:{row['path']}"],
                              capture_output=True)
        if blob.returncode != 0:
            problems.append(f"{row['source']}/{row['trial']}: {row['repository']}@{row['commit'][:10]}:"
                            f"{row['path']}: {blob.stderr.decode(errors='replace').strip()}")
            continue
        target = out / row["source"] / f"{row['trial']}.bvh"
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(blob.stdout)
        print(f"{target}  ({len(blob.stdout)} bytes, {row['repository']}@{row['commit'][:10]})")
    return problems


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    for flag, kind, default, what in (
        ("--out", Path, None, "folder to write OUT/<source>/<trial>.bvh into"),
        ("--mirror", Path, Path("/work/.mirror"), "folder of the repository snapshots"),
        ("--manifest", Path, MANIFEST, "the manifest CSV"),
        ("--sources", str, "", "comma-separated sources to write (default: all)"),
    ):
        ap.add_argument(flag, type=kind, default=default, required=default is None, help=what)
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = _arguments(argv)
    try:
        rows = read_manifest(args.manifest)
    except (ManifestError, OSError) as e:
        print(e, file=sys.stderr)
        return 2
    wanted = {s for s in args.sources.split(",") if s}
    problems = materialise([r for r in rows if not wanted or r["source"] in wanted], args.mirror, args.out)
    for p in problems:
        print("skipped:", p, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
