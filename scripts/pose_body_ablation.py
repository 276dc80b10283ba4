"""Why the canonical body once lost CMU's own jump poses, and what each fix buys (issue 31).

    PYTHONPATH=. .venv/bin/python scripts/pose_body_ablation.py --data ../shared/data/cmu \
        --other /work/data/cmu-other/rig --other /work/data/cmu-other/cartoon --json OUT.json

Every trial is loaded once (30 fps positions); each variant's features are computed from
those positions and searched with :class:`~retrieval.library.PoseSearch`:

* ``bench`` -- ``storybeam bench pose-search``'s protocol: the characteristic frame of every
  jump, kick and run (:func:`~retrieval.library.characteristic_frame`), own clip left out;
  ``folds`` -- its held-out 3-fold protocol (:func:`lab.bench.pose_search.held_out_folds`);
* ``bench_top_same_subject`` -- how often the bench's top clip is the query's performer's
  (CMU names trials subject_take); ``bench_subject_left_out`` -- the bench's queries with
  every take of their performer left out (every other clip refined);
* ``own`` -- ``storybeam eval --pose-identity``: frames at 1/4, 1/2, 3/4 of every trial, own
  trial left out, same class; ``<other>`` -- with ``--skeleton-from``: the same frames of
  the other skeleton's files, (same class, same trial).

Variants: the file's own body (``mr17``); the canonical body before (the characters'
bones, the floor over the whole clip) and now (CMU's mean bones, the floor within a
second), each change alone, other floor windows; and *hybrids* -- the canonical features
with one group of MR17 columns taken from the file's own body -- which show where the
loss sits. ``--misses`` lists the jump queries the variant before missed and what
answered them. The bones are swapped for a variant by writing
:data:`retrieval.motion.body.CANONICAL_BONES` in place (restored after)."""
from __future__ import annotations

import argparse
import json
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np

from lab.bench.pose_search import held_out_folds
from lab.experiment.cross_skeleton import POSE_FRACTIONS, other_skeleton_trials
from retrieval.features import MR17, MR17_CANONICAL, leg_length
from retrieval.library import Clip, PoseSearch, characteristic_frame, read_labels
from retrieval.motion import canonical_joint_map, load_motion, positions, resample, rest_positions
from retrieval.motion import body

FPS = 30.0
#: The canonical bones before issue 31's fix (the characters' default adult body).
BEFORE_BONES = {"thigh": 0.5, "shin": 0.5, "foot": 0.19, "hip_half_width": 0.11, "lower_spine": 0.33,
                "upper_spine": 0.33, "head": 0.12, "shoulder_half_width": 0.2, "shoulder_drop": 0.06,
                "upper_arm": 0.35, "forearm": 0.31}
GROUPS = {
    "heights": ("lankle_height", "rankle_height", "hips_height"),
    "upper body": ("hand_hand", "elbow_elbow", "lhand_head", "rhand_head", "lhand_rshoulder", "rhand_lshoulder",
                   "lhand_lshoulder", "rhand_rshoulder", "lhand_above_head", "rhand_above_head"),
    "head": ("lhand_head", "rhand_head", "lhand_above_head", "rhand_above_head"),
    "legs": ("ankle_ankle", "knee_knee", "lankle_lhip", "rankle_rhip"),
}

_HEIGHTS = [MR17.names.index(c) for c in GROUPS["heights"]]


@contextmanager
def bones(values: dict[str, float] | None):
    """Canonical bones ``values`` for the block (None: as they are)."""
    saved = dict(body.CANONICAL_BONES)
    body.CANONICAL_BONES.update(values or {})
    try:
        yield
    finally:
        body.CANONICAL_BONES.update(saved)


def load(folder: Path) -> list[dict]:
    """Trial, label, 30 fps positions, joint map, leg, rest pose, file frames and rate."""
    rows = read_labels(folder) if (folder / "labels.csv").is_file() else other_skeleton_trials(folder)
    out = []
    for r in rows:
        m = load_motion(r.file, r.skeleton) if r.skeleton else load_motion(r.file)
        n0, fps0 = m.n_frames, m.fps
        m = resample(m, FPS) if abs(m.fps - FPS) > 1e-9 else m
        jm = canonical_joint_map(m.skeleton)
        out.append({"trial": r.trial, "label": getattr(r, "label", ""), "pos": positions(m), "jm": jm,
                    "leg": leg_length(m.skeleton, jm), "rest": rest_positions(m.skeleton), "n0": n0, "fps0": fps0})
    return out


def features(fs, trials: list[dict], hybrid: tuple[str, ...] = ()) -> list[np.ndarray]:
    """``fs``'s features of every trial, the ``hybrid`` columns from MR17 on the file's body."""
    cols = [MR17.names.index(c) for c in hybrid]
    out = []
    for t in trials:
        args = (t["pos"], t["jm"], t["leg"], FPS, t["rest"])
        f = fs.from_positions(*args)
        if cols:
            f[:, cols] = MR17.from_positions(*args)[:, cols]
        out.append(f)
    return out


def rates(hits: dict[str, list[bool]]) -> dict[str, float]:
    return {c: round(float(np.mean(v)), 3) for c, v in sorted(hits.items())}


def evaluate(fs, lib: list[dict], others: dict[str, list[dict]], hybrid: tuple[str, ...] = ()) -> dict:
    """The module docstring's figures for one variant, and the bench's misses."""
    clips = [Clip(t["trial"], t["label"], f, None, FPS) for t, f in zip(lib, features(fs, lib, hybrid))]
    search = PoseSearch.from_clips(clips, 6)
    bench: dict[str, list[bool]] = {}
    same_subject: dict[str, list[bool]] = {}
    subject_out: dict[str, list[bool]] = {}
    misses = []
    for c in clips:
        frame = characteristic_frame(c.features, c.label)
        if frame is None:
            continue
        hit = search.search(c.features[frame], k=5, exclude=c.trial)[0]
        bench.setdefault(c.label, []).append(hit.label == c.label)
        same_subject.setdefault(c.label, []).append(_subject(hit.trial) == _subject(c.trial))
        # the whole subject left out, every other clip refined: no help from the performer's proportions
        rest = [o for o in clips if _subject(o.trial) != _subject(c.trial)]
        nearest = min(rest, key=lambda o: float(np.min(np.linalg.norm(o.features - c.features[frame], axis=1))))
        subject_out.setdefault(c.label, []).append(nearest.label == c.label)
        if hit.label != c.label:
            answer = clips[search.index.position(hit.trial)].features[hit.frame]
            misses.append(f"{c.trial} ({c.label}) frame {frame} -> {hit.trial} ({hit.label}) frame {hit.frame}, "
                          "its ankles/hips above the floor " + "/".join(f"{answer[k]:.2f}" for k in _HEIGHTS))
    own: dict[str, list[bool]] = {}
    for t, c in zip(lib, clips):
        for q in _fraction_rows(t, c.features):
            own.setdefault(c.label, []).append(search.search(q, k=1, exclude=c.trial)[0].label == c.label)
    out = {"bench": rates(bench), "folds": {c: round(v["accuracy"], 3) for c, v in
                                            held_out_folds(clips, 6, "auto", 5)["classes"].items()},
           "own": round(float(np.mean([x for v in own.values() for x in v])), 3), "own_by_class": rates(own),
           "bench_top_same_subject": rates(same_subject), "bench_subject_left_out": rates(subject_out),
           "bench_misses": misses}
    label = {c.trial: c.label for c in clips}
    for name, trials in others.items():
        same_class = same_trial = 0
        for t, f in zip(trials, features(fs, trials, hybrid)):
            for q in _fraction_rows(t, f):
                hit = search.search(q, k=1)[0]
                same_class += hit.label == label[t["trial"]]
                same_trial += hit.trial == t["trial"]
        n = 3 * len(trials)
        out[name] = {"same_class": round(same_class / n, 3), "same_trial": round(same_trial / n, 3)}
    return out


def _subject(trial: str) -> str:
    """CMU's subject of a trial name (``118_11`` -> ``118``)."""
    return trial.split("_")[0]


def _fraction_rows(t: dict, feats: np.ndarray) -> list[np.ndarray]:
    """The feature rows of the file frames at :data:`POSE_FRACTIONS` (``search --pose``'s)."""
    frames = [int(round(f * (t["n0"] - 1))) for f in POSE_FRACTIONS]
    return [feats[min(int(round(fr * FPS / t["fps0"])), len(feats) - 1)] for fr in frames]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path("../shared/data/cmu"))
    ap.add_argument("--other", type=Path, action="append", default=[], help="an other-skeleton folder (repeatable)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    lib = load(args.data)
    others = {p.name: load(p) for p in args.other}
    whole = replace(MR17_CANONICAL, floor_window=0.0)
    variants = [
        ("file's own body (mr17)", MR17, None, ()),
        ("canonical before: characters' bones, floor over the clip", whole, BEFORE_BONES, ()),
        ("CMU's mean bones only", whole, None, ()),
        ("floor within 1 s only", MR17_CANONICAL, BEFORE_BONES, ()),
        ("now: CMU's mean bones, floor within 1 s", MR17_CANONICAL, None, ()),
        ("now, floor within 0.5 s", replace(MR17_CANONICAL, floor_window=0.5), None, ()),
        ("now, floor within 2 s", replace(MR17_CANONICAL, floor_window=2.0), None, ()),
    ] + [(f"before, with MR17's {g} columns", whole, BEFORE_BONES, cols) for g, cols in GROUPS.items()]
    results = {}
    for name, fs, values, hybrid in variants:
        with bones(values):
            r = evaluate(fs, lib, others if not hybrid else {}, hybrid)
        results[name] = r
        shown = {k: v for k, v in r.items() if k != "bench_misses"}
        print(f"{name}: {json.dumps(shown)}", flush=True)
    print("jump/kick misses of the canonical body before:")
    for m in results["canonical before: characters' bones, floor over the clip"]["bench_misses"]:
        print("  " + m)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
