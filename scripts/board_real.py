"""Materialise the public hand-held board footage of scripts/board_real.json into /work/data/board_real/.

Each source is read from a local git copy of its repository at the manifest's commit
(``--mirrors DIR``: ``DIR/<owner>+<name>/repo`` as the session's ``fetch`` leaves them, or
``DIR/<owner>/<name>`` as ``git clone`` would; the commit is checked) and written as
``OUT/<name>/`` (a video file, or the folder of images), then each variant of the manifest
(e.g. ``dim320``: smaller, darker, noisier) as ``OUT/<name>-<variant>/`` frames (PNG).
``OUT/index.json`` lists what was written with its board spec and frame rate, for
``storybeam track``. Nothing materialised is committed (licences: see the manifest)."""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

MANIFEST = Path(__file__).with_name("board_real.json")


def _repo_dir(mirrors: Path, repo: str) -> Path:
    owner, name = repo.split("/")
    for candidate in (mirrors / f"{owner}+{name}" / "repo", mirrors / owner / name):
        if candidate.exists():
            return candidate
    sys.exit(f"{repo}: no local copy under {mirrors} (git clone https://github.com/{repo} {mirrors / owner / name})")


def _git(repo_dir: Path, *args: str) -> bytes:
    return subprocess.run(["git", "-C", str(repo_dir), *args], check=True, capture_output=True).stdout


def _extract(src: dict, mirrors: Path, out: Path) -> Path:
    repo_dir = _repo_dir(mirrors, src["repo"])
    commit = src["commit"]
    try:
        _git(repo_dir, "cat-file", "-e", f"{commit}^{{commit}}")
    except subprocess.CalledProcessError:
        sys.exit(f"{src['repo']}: commit {commit} is not in {repo_dir}")
    if src["kind"] == "video":
        target = out / src["name"] / Path(src["path"]).name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(_git(repo_dir, "show", f"{commit}:{src['path']}"))
        return target
    target = out / src["name"]
    target.mkdir(parents=True, exist_ok=True)
    names = _git(repo_dir, "ls-tree", "--name-only", f"{commit}:{src['path']}").decode().split()
    pattern = src.get("glob", "*")
    for name in sorted(n for n in names if Path(n).match(pattern) and Path(n).suffix.lower() in (".png", ".jpg", ".jpeg")):
        (target / name).write_bytes(_git(repo_dir, "show", f"{commit}:{src['path']}/{name}"))
    return target


def _frames(path: Path):
    if path.is_dir():
        for f in sorted(path.iterdir()):
            image = cv2.imread(str(f), cv2.IMREAD_COLOR)
            if image is not None:
                yield image
        return
    cap = cv2.VideoCapture(str(path))
    while True:
        ok, image = cap.read()
        if not ok:
            break
        yield image
    cap.release()


def _variant(path: Path, target: Path, v: dict) -> int:
    """Frames of ``path`` resized to ``v['width']`` (area average), times ``v['exposure']``, plus
    Gaussian noise of ``v['noise_sigma']`` grey levels (seeded), as PNG files in ``target``."""
    target.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(v.get("seed", 0))
    n = 0
    for n, image in enumerate(_frames(path), 1):
        h, w = image.shape[:2]
        width = int(v["width"])
        small = cv2.resize(image, (width, int(round(h * width / w))), interpolation=cv2.INTER_AREA)
        dim = small.astype(np.float32) * float(v["exposure"]) + rng.normal(0, float(v["noise_sigma"]), small.shape)
        cv2.imwrite(str(target / f"frame_{n - 1:05d}.png"), np.clip(dim + 0.5, 0, 255).astype(np.uint8))
    return n


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mirrors", type=Path, default=Path("/work/.mirror"), help="where the repositories are")
    ap.add_argument("--out", type=Path, default=Path("/work/data/board_real"))
    ap.add_argument("--only", default=None, help="comma-separated source names")
    args = ap.parse_args(argv)
    manifest = json.loads(MANIFEST.read_text())
    wanted = None if args.only is None else set(args.only.split(","))
    index = []
    for src in manifest["sources"]:
        if wanted is not None and src["name"] not in wanted:
            continue
        path = _extract(src, args.mirrors, args.out)
        fps = src.get("fps") or cv2.VideoCapture(str(path)).get(cv2.CAP_PROP_FPS) or 30.0
        index.append({"name": src["name"], "path": str(path), "board": src["board"], "fps": fps, "variant": None})
        print(f"{src['name']}: {path}")
        for vname, v in manifest["variants"].items():
            target = args.out / f"{src['name']}-{vname}"
            n = _variant(path, target, v)
            index.append({"name": f"{src['name']}-{vname}", "path": str(target), "board": src["board"], "fps": fps,
                          "variant": vname})
            print(f"{src['name']}-{vname}: {n} frames in {target}")
    (args.out / "index.json").write_text(json.dumps(index, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
