"""A synthetic stand-in for the issue's dim hand-held clip, and the pose error of a track report on it.

``write FOLDER``: a hand-held session (:func:`ar.synthetic.record_rig_session`: a child's
wandering hand, a quick turn aside, an auto-exposure dip, a hand over the board, motion
blur, shot and read noise) of a small ChArUco board (5 x 5 squares, 16 corners, as in the
issue's clip) at 320x240 in dim light, written as PNG frames with ``truth.npz`` and
``camera.json`` (the true camera). ``score TRACK.json FOLDER``: the pose error against the
truth of every frame ``storybeam track`` found a pose on (median and 95th percentile,
degrees and millimetres, per how the pose was found), as JSON on stdout."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

from ar.boards import Board
from ar.geometry import pose_error
from ar.synthetic import SessionConfig, default_camera, load_session_truth, record_rig_session

BOARD = "charuco:5x5:0.04:0.02:DICT_6X6_250"


def write(folder: Path, frames: int, exposure: float, distance: float, shutter: float, seed: int) -> None:
    cfg = SessionConfig(exposure_level=exposure, distance_m=distance, shutter=shutter, wander_deg=8.0, seed=seed)
    session = record_rig_session(Board(BOARD), frames, default_camera().scaled(320, 240), cfg)
    session.write(folder)
    print(f"wrote {frames} frames of {BOARD} to {folder}")


def score(report_path: Path, folder: Path) -> dict:
    report = json.loads(report_path.read_text())
    poses = load_session_truth(folder)["poses"]
    out: dict = {}
    for kind in ("detected", "followed", "any"):
        errors = []
        for row in report["frames"]:
            if row["found_by"] == "lost" or (kind != "any" and row["found_by"] != kind):
                continue
            T = np.eye(4)
            T[:3, :3] = cv2.Rodrigues(np.array(row["rvec"]))[0]
            T[:3, 3] = row["tvec_m"]
            errors.append(pose_error(T, poses[row["index"]]))
        e = np.array(errors).reshape(-1, 2)
        out[kind] = {"frames": len(e), "rot_deg_median": float(np.median(e[:, 0])) if len(e) else None,
                     "trans_mm_median": float(np.median(e[:, 1])) if len(e) else None,
                     "rot_deg_p95": float(np.percentile(e[:, 0], 95)) if len(e) else None,
                     "trans_mm_p95": float(np.percentile(e[:, 1], 95)) if len(e) else None}
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    w = sub.add_parser("write")
    w.add_argument("folder", type=Path)
    w.add_argument("--frames", type=int, default=300)
    w.add_argument("--exposure", type=float, default=0.3)
    w.add_argument("--distance", type=float, default=0.35)
    w.add_argument("--shutter", type=float, default=0.8)
    w.add_argument("--seed", type=int, default=2)
    s = sub.add_parser("score")
    s.add_argument("report", type=Path)
    s.add_argument("folder", type=Path)
    args = ap.parse_args()
    if args.cmd == "write":
        write(args.folder, args.frames, args.exposure, args.distance, args.shutter, args.seed)
    else:
        print(json.dumps(score(args.report, args.folder), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
