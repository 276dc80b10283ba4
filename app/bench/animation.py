"""Measure the animation numbers quoted in docs/animation.md.

    python -m app.animation_bench [--json out/animation_bench.json] [--shared ../shared/data/cmu]

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

import argparse
import csv
import json
import os
import time
from pathlib import Path

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
MOTIONS = REPO / "assets" / "motions"


def _rows(label_set=("walk", "run")):
    return [r for r in csv.DictReader(open(MOTIONS / "labels.csv")) if r["label"] in label_set]


def path_following(characters=("robot", "cat", "kid")) -> list[dict]:
    from ar.render.characters import build_character
    from retrieval.animation import foot_skate_cm_per_m, path_error_cm
    from retrieval.motion.formats import load_motion
    from retrieval.animation import follow_path, s_curve_path, straight_path
    from retrieval.animation import canonical_skeleton, retarget

    out = []
    scale_human = 1.7 / 0.12
    targets = [(c, build_character(c).skeleton, 1.0) for c in characters]
    targets.append(("human-1.7m", canonical_skeleton(height_m=1.7), scale_human))
    for row in _rows():
        src = load_motion(MOTIONS / row["file"])
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
    from ar.render.characters import build_character
    from retrieval.features import motion_features
    from retrieval.motion.formats import load_motion
    from retrieval.codes import Quantizer
    from retrieval.animation import retarget
    from retrieval.animation import code_transition_cost, judge_transition

    sk = build_character("robot").skeleton
    rows = list(csv.DictReader(open(MOTIONS / "labels.csv")))
    clips = {r["trial"]: retarget(load_motion(MOTIONS / r["file"]), sk) for r in rows}
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
    from ar.render.characters import build_character
    from retrieval.motion.formats import load_motion
    from retrieval.animation import retarget

    sk = build_character("robot").skeleton
    rows = list(csv.DictReader(open(cmu / "labels.csv")))
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
    from ar.render.character_render import CharacterRig, scaled_model
    from ar.render.characters import build_character
    from ar.geometry import look_at
    from ar.render.projector_view import ProjectorRenderer
    from ar.synthetic import default_projector
    from retrieval.motion.formats import load_motion
    from retrieval.animation import follow_path, straight_path
    from retrieval.animation import retarget

    ch = build_character("robot")
    m = follow_path(retarget(load_motion(MOTIONS / "bvh" / "02_01.bvh"), ch.skeleton), straight_path(0.2, start=(-0.1, 0))).motion
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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m app.animation_bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", type=Path, default=Path("out/animation_bench.json"))
    p.add_argument("--shared", type=Path, default=REPO.parent / "shared" / "data" / "cmu")
    p.add_argument("--characters", default="robot,cat,kid")
    args = p.parse_args(argv)
    from tqdm import tqdm

    steps = ["path following", "transitions", "retarget shared", "render timing"]
    result: dict = {}
    for step in tqdm(steps, desc="animation bench", unit="step"):
        if step == "path following":
            result["path_following"] = path_following(tuple(args.characters.split(",")))
        elif step == "transitions":
            result["transitions"] = transitions()
        elif step == "retarget shared":
            result["retarget_shared"] = retarget_shared(args.shared) if (args.shared / "labels.csv").is_file() else []
        else:
            result["render"] = render_timing()
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=1))
    print(_summary(result["path_following"], result["transitions"]))
    print("render:", json.dumps(result["render"]))
    print("retargeted shared skeletons:", len(result["retarget_shared"]))
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
