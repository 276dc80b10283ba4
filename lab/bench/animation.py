"""Measure the animation numbers quoted in docs/design/animation.md (``storybeam bench animation``).

    storybeam bench animation [--json out/animation_bench.json] [--shared ../shared/data/cmu]
                              [--characters robot,cat,kid]

* path following of every bundled walk and run on a straight 60 cm path and on an
  S-curve (60 cm long, 8 cm amplitude), per character, at 12 cm: mean path error (cm)
  and foot skate (cm/m, swing-gated and ungated; see retrieval.animation_metrics);
* the same at the capture's own human scale (canonical adult proportions, 1.7 m, path
  scaled by 1.7/0.12);
* transitions: the code-table choice (alone, and with its shortlist re-ranked by the
  exact pose distance) against 200 random transition points, on the exact pose distance;
* retargeting of one clip per shared skeleton (when the shared CMU data is present);
* the character render alone at 640x480 (projector renderer, EGL), median ms.
"""
from __future__ import annotations

import csv
import time
from pathlib import Path
from typing import Callable

import numpy as np

from app.paths import SHARED_CMU
from app.paths import MOTIONS_DIR
from ar import default_projector, look_at
from ar.render import CHARACTER_NAMES, CharacterRig, ProjectorRenderer, build_character, scaled_model
from retrieval.animation import (
    canonical_skeleton,
    code_transition_cost,
    follow_path,
    foot_skate_cm_per_m,
    judge_transition,
    path_error_cm,
    retarget,
    s_curve_path,
    straight_path,
)
from retrieval.codes import Quantizer
from retrieval.errors import StoryBeamError
from retrieval.features import motion_features
from retrieval.motion.formats import load_motion



def _labels(folder: Path) -> list[dict[str, str]]:
    """The rows of ``folder/labels.csv``."""
    with open(folder / "labels.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _rows(label_set: tuple[str, ...] = ("walk", "run")) -> list[dict[str, str]]:
    return [r for r in _labels(MOTIONS_DIR) if r["label"] in label_set]


def path_following(characters=("robot", "cat", "kid")) -> list[dict]:
    out = []
    scale_human = 1.7 / 0.12
    targets = [(c, build_character(c).skeleton, 1.0) for c in characters]
    targets.append(("human-1.7m", canonical_skeleton(height_m=1.7), scale_human))
    for row in _rows():
        src = load_motion(MOTIONS_DIR / row["file"])
        for name, sk, s in targets:
            m = retarget(src, sk)
            for shape, path in (("straight", straight_path(0.6 * s)), ("S", s_curve_path(0.6 * s, 0.08 * s))):
                res = follow_path(m, path)
                out.append({
                    "trial": row["trial"], "label": row["label"], "character": name, "path": shape,
                    "path_error_cm": path_error_cm(res.motion, path.points),
                    "path_error_cm_at_12cm": path_error_cm(res.motion, path.points) / s,
                    "skate_cm_per_m": foot_skate_cm_per_m(res.motion),
                    "skate_ungated_cm_per_m": foot_skate_cm_per_m(res.motion, swing_speed_legs=None),
                    "rate": res.rate,
                })
    return out


def transitions() -> list[dict]:
    sk = build_character("robot").skeleton
    rows = _labels(MOTIONS_DIR)
    clips = {r["trial"]: retarget(load_motion(MOTIONS_DIR / r["file"]), sk) for r in rows}
    q = Quantizer.fit(np.concatenate([motion_features(m) for m in clips.values()]), 6)
    cost = code_transition_cost(q)
    by_label: dict[str, list[str]] = {}
    for r in rows:
        by_label.setdefault(r["label"], []).append(r["trial"])
    out = []
    for walk in by_label["walk"][:4]:
        for label in ("jump", "kick", "dance", "run"):
            for other in by_label[label][:2]:
                plain = judge_transition(clips[walk], clips[other], cost, window=9)
                refined = judge_transition(clips[walk], clips[other], cost, window=9, refine=True)
                out.append({"from": walk, "to": other, "to_label": label,
                            "code_only": plain.chosen_pose_cost, "code_refined": refined.chosen_pose_cost,
                            "random_mean": refined.random_pose_cost_mean,
                            "random_median": refined.random_pose_cost_median,
                            "refined_beats_random_fraction": refined.random_beaten_fraction})
    return out


def retarget_shared(cmu: Path) -> list[dict]:
    sk = build_character("robot").skeleton
    rows = _labels(cmu)
    seen, out = set(), []
    for r in rows:
        key = r["skeleton"] or "CC_Base BVH"
        if key in seen:
            continue
        seen.add(key)
        t0 = time.perf_counter()
        m = load_motion(cmu / r["file"], (cmu / r["skeleton"]) if r["skeleton"] else None)
        retarget(m, sk)
        out.append({"skeleton": key, "trial": r["trial"], "frames": m.n_frames, "ms": (time.perf_counter() - t0) * 1000})
    return out


def render_timing(n: int = 60, size=(640, 480)) -> dict:
    ch = build_character("robot")
    m = follow_path(retarget(load_motion(MOTIONS_DIR / "bvh" / "02_01.bvh"), ch.skeleton), straight_path(0.2, start=(-0.1, 0))).motion
    model = scaled_model(default_projector(), *size)
    r = ProjectorRenderer(size[0], size[1], model.K)
    rig = CharacterRig(r, ch)
    rig.bind(m)
    r.set_view(look_at(np.array([0.0, 0.5, 0.2]), np.zeros(3), np.array([0.0, 0.0, -1.0])))
    times = []
    for i in range(n + 1):
        rig.show_frame(i % m.n_frames)
        t0 = time.perf_counter()
        r.render()
        times.append((time.perf_counter() - t0) * 1000)
    r.close()
    t = np.array(times[1:])  # the first render compiles shaders
    return {"size": list(size), "frames": n, "first_ms": times[0], "median_ms": float(np.median(t)),
            "p90_ms": float(np.percentile(t, 90)), "parts": len(ch.parts)}


def _summary(pf: list[dict], tr: list[dict]) -> str:
    lines = ["| clip | label | target | path | error cm (at 12 cm) | skate cm/m | skate ungated |", "|---|---|---|---|---|---|---|"]
    for r in pf:
        lines.append(f"| {r['trial']} | {r['label']} | {r['character']} | {r['path']} | {r['path_error_cm_at_12cm']:.3f} | "
                     f"{r['skate_cm_per_m']:.2f} | {r['skate_ungated_cm_per_m']:.2f} |")
    lines += ["", "| from | to | code only | code + exact shortlist | random mean | beats random |", "|---|---|---|---|---|---|"]
    for r in tr:
        lines.append(f"| {r['from']} | {r['to']} ({r['to_label']}) | {r['code_only']:.3f} | {r['code_refined']:.3f} | "
                     f"{r['random_mean']:.3f} | {r['refined_beats_random_fraction']:.2f} |")
    return "\n".join(lines)


def check_characters(characters: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """``characters`` as a tuple; :class:`StoryBeamError` if it is empty or names an
    unknown character."""
    characters = tuple(characters)
    unknown = [c for c in characters if c not in CHARACTER_NAMES]
    if unknown or not characters:
        raise StoryBeamError(f"unknown character(s) {', '.join(unknown) or '(none given)'}; "
                             f"choose from {', '.join(CHARACTER_NAMES)}")
    return characters


#: The steps of one run, in order (the progress bar counts them).
STEPS = ("path following", "transitions", "retarget shared", "render timing")


def run_animation_bench(shared: Path = SHARED_CMU,
                        characters: tuple[str, ...] = ("robot", "cat", "kid"),
                        progress: Callable[[int, int], None] | None = None) -> dict:
    """Run every step of the module docstring; returns the JSON-ready result
    (``path_following``, ``transitions``, ``retarget_shared``, ``render``).
    ``progress(done, total)`` is called after each step. Unknown characters are a
    :class:`StoryBeamError` before any work starts."""
    characters = check_characters(characters)
    shared = Path(shared)
    result: dict = {}
    for done, step in enumerate(STEPS, 1):
        if step == "path following":
            result["path_following"] = path_following(characters)
        elif step == "transitions":
            result["transitions"] = transitions()
        elif step == "retarget shared":
            result["retarget_shared"] = retarget_shared(shared) if (shared / "labels.csv").is_file() else []
        else:
            result["render"] = render_timing()
        if progress:
            progress(done, len(STEPS))
    return result


def format_summary(result: dict) -> str:
    """The tables printed after a run: path following, transitions, render, shared skeletons."""
    return "\n".join([
        _summary(result["path_following"], result["transitions"]),
        "render: " + ", ".join(f"{k} {v:.1f}" if isinstance(v, float) else f"{k} {v}" for k, v in result["render"].items()),
        f"retargeted shared skeletons: {len(result['retarget_shared'])}",
    ])
