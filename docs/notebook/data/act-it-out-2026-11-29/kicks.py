"""Ninth round (issue 27): kick captures from other studios in the Act it out library.

    python kicks.py materialise /work/kicks        # the captures, from fetched snapshots
    python kicks.py moves /work/kicks OUT NAME,... # assets/motions/moves + those kicks
    storybeam bench act-it-out --videos /work/data/act_real --data ../shared/data/cmu \
        --moves OUT --cache /work/data/act_real_cache --quiet --json real_<variant>.json

The captures: kick_captures_manifest.csv (found by a helper; its search log:
kick_captures_search_notes.txt). Crops are given in the manifest's path column, as
"(MOTION rows A-B only)" for BVH (0-based rows) and "(AMC frames A-B)" for AMC (the
file's own frame numbers); the two SNU woody2 takes are cut to 2.5 s around the kick here.
DeepMimic's kick and spin kick are read by deepmimic.py (not product code).
"""
import csv, re, shutil, subprocess, sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[4]
sys.path.insert(0, str(REPO))
HERE = Path(__file__).resolve().parent
MIRROR = Path("/work/.mirror")
CROP_S = {"snu_woody2_n_kick": (2.5, 2.5), "snu_woody2_1_kick": (4.5, 2.5)}
SKIP = {"m21_soccer_kick_cmu_like", "jumpkick_biovision"}  # a CMU copy; provenance unknown


def show(repo, commit, path):
    return subprocess.run(["git", "--git-dir", str(MIRROR / repo.replace("/", "+") / "repo"), "show",
                           f"{commit}:{path}"], capture_output=True, check=True).stdout.decode()


def materialise(out: Path):
    out.mkdir(parents=True, exist_ok=True)
    for r in csv.DictReader(open(HERE / "kick_captures_manifest.csv")):
        if r["short_name"] in SKIP:
            continue
        path = r["path"].split(" (")[0].split(" + ")[0]
        text = show(r["repository"], r["commit"], path)
        m = re.search(r"rows (\d+)-(\d+)", r["path"])
        if m:  # BVH rows [a, b]
            head, motion = re.split(r"\bMOTION\b", text, 1)
            lines = motion.strip().splitlines()
            rows = [x for x in lines[2:] if x.strip()][int(m[1]):int(m[2]) + 1]
            text = head + f"MOTION\nFrames: {len(rows)}\n{lines[1].strip()}\n" + "\n".join(rows) + "\n"
        m = re.search(r"AMC frames (\d+)-(\d+)", r["path"])
        if m:  # AMC frames [a, b], renumbered from 1
            a, b = int(m[1]), int(m[2])
            keep, cur, n = [], None, 0
            for line in text.splitlines(keepends=True):
                t = line.split()
                if len(t) == 1 and t[0].isdigit():
                    cur = a <= int(t[0]) <= b
                    if cur:
                        n += 1
                        keep.append(f"{n}\n")
                elif cur is None or cur:
                    keep.append(line)
            text = "".join(keep)
            asf = re.search(r"\+ (\S+\.asf)", r["path"])[1]
            (out / "cmu135.asf").write_text(show(r["repository"], r["commit"], asf))
        ext = ".amc" if "AMC" in r["format"] else ".bvh"
        (out / f"{r['short_name']}{ext}").write_text(text)
        print("wrote", out / f"{r['short_name']}{ext}")


def moves(src: Path, out: Path, names: list[str]):
    from retrieval.library.bundle import write_clip
    from retrieval.motion import load_motion
    if out.exists():
        shutil.rmtree(out)
    shutil.copytree(REPO / "assets" / "motions" / "moves", out)
    rows = list(csv.DictReader(open(out / "labels.csv")))
    for n in names:
        if n.startswith("dm_"):
            from deepmimic import load_deepmimic
            what = n[3:]
            (src / f"{n}.txt").write_text(show("xbpeng/DeepMimic", "1f915c52fcd4b95b5f5f15b759ae91bd81e9a801",
                                               f"data/motions/humanoid3d_{what}.txt"))
            (src / "humanoid3d.txt").write_text(show("xbpeng/DeepMimic", "1f915c52fcd4b95b5f5f15b759ae91bd81e9a801",
                                                     "data/characters/humanoid3d.txt"))
            m = load_deepmimic(src / f"{n}.txt", src / "humanoid3d.txt")
        elif (src / f"{n}.bvh").exists():
            m = load_motion(src / f"{n}.bvh")
        else:
            m = load_motion(src / f"{n}.amc", src / "cmu135.asf")
        start, seconds = CROP_S.get(n, (0.0, 10.0))
        w = write_clip(m, out / f"{n}.bvh", n, 30.0, seconds, 4, start)
        rows.append({**rows[0], "trial": n, "label": "kick", "subject": n.rsplit("_", 1)[0], "file": f"{n}.bvh",
                     "seconds": f"{w.seconds:.2f}", "description": n, "source": "kick_captures_manifest.csv"})
    with open(out / "labels.csv", "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=list(rows[0]), lineterminator="\n")
        wr.writeheader()
        wr.writerows(rows)


if __name__ == "__main__":
    sys.path.insert(0, str(HERE))
    if sys.argv[1] == "materialise":
        materialise(Path(sys.argv[2]))
    else:
        moves(Path(sys.argv[2]), Path(sys.argv[3]), sys.argv[4].split(","))
