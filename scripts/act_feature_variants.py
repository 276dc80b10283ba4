"""Search-only variants of Act it out's frontal feature set over all three measures.

    python scripts/act_feature_variants.py VARIANT [VARIANT ...] [--json DIR]
        [--videos /work/data/act_real] [--video-cache /work/data/act_real_cache]
        [--guard-cache /work/data/guard/cache] [--data ../shared/data/cmu]

A ``VARIANT`` is ``base`` (the frontal set with MR17's weights, floor at the 2nd
percentile) or ``+``-joined parts: ``hN`` every height weighted N, ``hipsN`` /
``anklesN`` the hips' / the ankles' heights weighted N, ``flP`` the heights' floor at the
P-th percentile of the lowest foot (``fl30+h2`` is the registered ``"frontal"`` set since
2026-11-28), ``lowN`` an added column, the lower ankle's height above that floor (both feet
off it: a flight; kind ``"lowest"``), weighted N (``lowN@C``: only what rises above C leg
lengths, ``max(0, lower ankle - C)``, so a standing foot's jitter reads 0); and library-side augmentation (:class:`retrieval.library.act_search.Augment`):
``mirror`` every clip mirrored too, ``xT`` every clip at speed T too (``x0.8``, ``x1.25``),
``hops`` every jump's hop cycle tiled into a repeated jump (``hops@D``: cut where the hips
cross their median less D, a light hop). Per variant the library (``--data``) is indexed with that set (the clips'
joint positions are read once and kept in memory) and measured, search only, on

* the real development set (``--videos``, landmarks cached by ``storybeam bench
  act-it-out --videos``; a clip not in the cache is tracked, slowly),
* the rendered guard (seed 2, 60 takes each of ``person`` and ``kid``, landmarks cached
  by ``storybeam bench act-it-out --seed 2 --limit 60 --variants person,kid --cache``;
  trial left out),
* ``storybeam bench act-cameras`` (every condition, seed 2, 60 trials),

printing one block per variant and, with ``--json``, writing ``DIR/VARIANT.json``.

``--flight-table`` prints instead, per class, the median over clips of the 10th / 50th /
90th percentile of the lower ankle's height above the 30th-percentile floor (leg lengths)
in the library's mocap and in the real set's camera joints: how far the flight cue rises
above the camera's noise.
"""
from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from lab.bench import act_it_out as rendered
from lab.bench.act_cameras import run_act_cameras_bench
from lab.bench.act_videos import read_video_labels, run_act_videos_bench, track_clip
from retrieval.features import FrontalFeatureSet, get_feature_set, leg_length, register_feature_set
from retrieval.features.frontal import FRONTAL
from retrieval.features.relational import FLOOR_PERCENTILE, MR17, FeatureSpec, clip_floor
from retrieval.library import ActSearch, Augment, read_labels
from retrieval.library.clip import Clip
from retrieval.motion import (
    canonical_joint_map, landmarks_to_positions, load_motion, positions, resample, rest_positions,
)

FPS = 30.0


@dataclass(frozen=True)
class ClearedFrontal(FrontalFeatureSet):
    """The frontal set with its ``"lowest"`` column cleared of its first ``clearance`` leg
    lengths (``lowN@C``): ``w·max(0, v/w − C)``."""

    clearance: float = 0.0

    def from_positions(self, pos: np.ndarray, joint_map: dict[str, int], body_size: float,
                       fps: float | None = None, rest: np.ndarray | None = None) -> np.ndarray:
        out = super().from_positions(pos, joint_map, body_size, fps, rest)
        for k, s in enumerate(self.specs):
            if s.kind == "lowest":
                out[:, k] = s.weight * np.maximum(0.0, out[:, k] / s.weight - self.clearance)
        return out


def variant_set(variant: str) -> tuple[FrontalFeatureSet, Augment]:
    """The frontal feature set a ``VARIANT`` names (module docstring), registered, and its
    augmentation."""
    specs, floor = list(MR17.specs), FLOOR_PERCENTILE
    mirror, tempos, hops, dip, clearance = False, [], False, None, 0.0
    for part in ([] if variant == "base" else variant.split("+")):
        if part.startswith("low") and "@" in part:
            part, clearance = part.split("@")[0], float(part.split("@")[1])
        if part in ("mirror", "hops") or part.startswith("hops@"):
            mirror, hops = mirror or part == "mirror", hops or part.startswith("hops")
            dip = float(part[5:]) if part.startswith("hops@") else dip
            continue
        key = part.rstrip("0123456789.")
        try:
            value = float(part[len(key):])
        except ValueError:
            raise SystemExit(f"{variant}: {part!r} needs a number (h2, hips1.5, fl30)") from None
        names = {"h": ("lankle_height", "rankle_height", "hips_height"), "hips": ("hips_height",),
                 "ankles": ("lankle_height", "rankle_height")}
        if key == "x":
            tempos.append(value)
        elif key == "fl":
            floor = value
        elif key == "low":
            specs.append(FeatureSpec("lower_ankle_height", "lowest", ("left_ankle", "right_ankle"),
                                     "both feet off the floor: a flight", value))
        elif key in names:
            specs = [replace(s, weight=value) if s.name in names[key] else s for s in specs]
        else:
            raise SystemExit(f"{variant}: unknown part {part!r} (h, hips, ankles, fl, low, x, mirror, hops)")
    base = ClearedFrontal(**{f.name: getattr(FRONTAL, f.name) for f in fields(FRONTAL)}, clearance=clearance) \
        if clearance > 0 else FRONTAL
    fs = register_feature_set(replace(base, name=f"frontal_variant_{variant}", specs=tuple(specs),
                                      floor_percentile=floor, description=f"variant {variant}"))
    return fs, Augment(mirror, tuple(tempos), hops, dip)


def library_positions(data: Path) -> list[tuple]:
    """Every library trial's (row, joint positions at FPS, joint map, leg length, rest pose)."""
    out = []
    for r in read_labels(data):
        m = load_motion(r.file, r.skeleton) if r.skeleton else load_motion(r.file)
        m = resample(m, FPS) if abs(m.fps - FPS) > 1e-9 else m
        jm = canonical_joint_map(m.skeleton)
        out.append((r, positions(m), jm, leg_length(m.skeleton, jm), rest_positions(m.skeleton)))
    return out


def measure(variant: str, library: list[tuple], args: argparse.Namespace) -> dict:
    """The three measures of one variant (module docstring)."""
    fs, augment = variant_set(variant)
    clips = [Clip(r.trial, r.label, fs.from_positions(p, jm, leg, FPS, rest), None, FPS, str(r.file), r.subject)
             for r, p, jm, leg, rest in library]
    t0 = time.perf_counter()
    search = ActSearch.from_clips(clips, feature_set=fs.name, augment=augment)
    build_s = time.perf_counter() - t0
    real = run_act_videos_bench(args.videos, args.data, args.video_cache, 3, search=search)
    real_ms = [c["search_ms"] for c in real["clips"] if c.get("search_ms") is not None]
    per = defaultdict(lambda: [0, 0])
    for c in real["clips"]:
        per[c["label"]][0] += c["predicted"] == c["label"]
        per[c["label"]][1] += 1
    rows = read_labels(args.data)
    chosen = rendered.choose_trials(rows, 60, 2)
    subjects: dict[str, set[str]] = defaultdict(set)
    for r in rows:
        if r.subject:
            subjects[r.subject].add(r.trial)
    guard = {v: rendered.evaluate_variant(search, chosen, v, 2, args.guard_cache, subjects) for v in ("person", "kid")}
    cams = run_act_cameras_bench(args.data, 60, 2, search=search)["conditions"]
    return {"variant": variant, "feature_set": repr(get_feature_set(fs.name)), "augment": augment.key(),
            "windows": len(search.index), "short_windows": len(search.short.index) if search.short else 0,
            "index_build_s": build_s, "real_search_ms_median": float(np.median(real_ms)) if real_ms else None,
            "real": {"right": sum(a for a, _ in per.values()), "clips": len(real["clips"]),
                     "per_class": {k: f"{a}/{b}" for k, (a, b) in per.items()},
                     "predicted": {c["file"]: c["predicted"] for c in real["clips"]}},
            "guard": {v: {"accuracy": g["accuracy_trial_out"], "ceiling": g["ceiling_trial_out"],
                          "subject_out": g.get("accuracy_subject_out"), "recall": g["recall"],
                          "search_ms_median": g.get("search_ms")} for v, g in guard.items()},
            "cameras": {c["condition"]["name"]: {"accuracy": c["accuracy"], "recall": c["recall"]} for c in cams}}


def lower_ankle_percentiles(pos: np.ndarray, jm: dict[str, int], leg: float) -> np.ndarray:
    """10th / 50th / 90th percentile of the lower ankle above the frontal floor, in leg lengths."""
    floor = clip_floor(np.stack([pos[:, jm[j], 1] for j in ("left_ankle", "left_toe", "right_ankle", "right_toe")],
                                axis=1), 0, FRONTAL.floor_percentile)
    low = np.minimum(pos[:, jm["left_ankle"], 1], pos[:, jm["right_ankle"], 1]) - floor
    return np.percentile(low, [10, 50, 90]) / leg


def flight_table(library: list[tuple], args: argparse.Namespace) -> None:
    """Print ``--flight-table`` (module docstring)."""
    per: dict[tuple[str, str], list[np.ndarray]] = defaultdict(list)
    for r, p, jm, leg, _rest in library:
        per[("library", r.label)].append(lower_ankle_percentiles(p, jm, leg))
    for video, label in read_video_labels(args.videos):
        t = track_clip(video, args.video_cache)
        pos, jm, leg = landmarks_to_positions(t["world"], t["image_xy"], t["valid"], tuple(t["image_size"]), t["fps"])
        per[("real", label)].append(lower_ankle_percentiles(pos, jm, leg))
    for (where, label), rows in sorted(per.items()):
        a = np.array(rows)
        print(f"{where:8s} {label:6s} {len(a):3d} clips: lower ankle p10/p50/p90 {np.median(a, axis=0).round(3)}, "
              f"p90 from {a[:, 2].min():.2f} to {a[:, 2].max():.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("variants", nargs="*")
    ap.add_argument("--flight-table", action="store_true", help="print the lower ankle's height per class")
    ap.add_argument("--json", type=Path, help="write DIR/VARIANT.json")
    ap.add_argument("--videos", type=Path, default=Path("/work/data/act_real"))
    ap.add_argument("--video-cache", type=Path, default=Path("/work/data/act_real_cache"))
    ap.add_argument("--guard-cache", type=Path, default=Path("/work/data/guard/cache"))
    ap.add_argument("--data", type=Path, default=Path("../shared/data/cmu"))
    args = ap.parse_args()
    library = library_positions(args.data)
    if args.flight_table:
        flight_table(library, args)
    for v in args.variants:
        r = measure(v, library, args)
        cams = r["cameras"]
        print(f"{v}: real {r['real']['right']}/{r['real']['clips']} {r['real']['per_class']}; "
              + "; ".join(f"{k} {g['accuracy']:.3f} (subject out {g['subject_out']})" for k, g in r["guard"].items())
              + f"; windows {r['windows']}+{r['short_windows']}, build {r['index_build_s']:.2f} s, "
              f"real search {r['real_search_ms_median']} ms"
              + f"; cameras mean {np.mean([c['accuracy'] for c in cams.values()]):.3f}\n  "
              + ", ".join(f"{k} {c['accuracy']:.3f} (kick {c['recall'].get('kick', 0):.2f})" for k, c in cams.items()))
        if args.json:
            args.json.mkdir(parents=True, exist_ok=True)
            (args.json / f"{v}.json").write_text(json.dumps(r, indent=1))


if __name__ == "__main__":
    main()
