"""Which parts of the rescue detection pass pay: CLAHE, upsampling, the wider detector settings.

Six dim and blurred conditions (distance, exposure, blur) of a hand-held default ChArUco
board at 320x240, ten views each (synthetic camera, known board); every subset of the
three parts is run on the same grey frames with the board's ChArUco detector, counting the
views where it finds at least four corners, and timing it. Prints a table; ``--json OUT``
writes it."""
from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import cv2
import numpy as np

from ar.boards import DEFAULT_BOARD_SPEC, RESCUE_CLAHE_CLIP, Board, _marker_params, _rescue_params
from ar.synthetic import Degradation, SyntheticCamera, TrajectoryConfig, default_camera, handheld_trajectory

CONDITIONS = [(0.35, 0.08, 0.7), (0.35, 0.15, 0.7), (0.35, 0.3, 1.2), (0.5, 0.08, 0.0), (0.5, 0.15, 0.7),
              (0.5, 0.3, 0.7)]  # (distance m, exposure, blur sigma px)
PARTS = ("clahe", "upsample", "params")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=10)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    board = Board(DEFAULT_BOARD_SPEC)
    cam = SyntheticCamera(board, camera=default_camera().scaled(320, 240), supersample=2)
    plain_params = cv2.aruco.CharucoParameters()
    refine = cv2.aruco.CharucoParameters()
    refine.tryRefineMarkers = True
    detectors = {False: cv2.aruco.CharucoDetector(board._cv_board, plain_params, _marker_params()),
                 True: cv2.aruco.CharucoDetector(board._cv_board, refine, _rescue_params())}
    clahe = cv2.createCLAHE(RESCUE_CLAHE_CLIP, (8, 8))
    views = []
    for dist, exposure, blur in CONDITIONS:
        truth = handheld_trajectory(board, args.views, TrajectoryConfig(seed=5, distance_m=dist))
        rng = np.random.default_rng(1)
        deg = Degradation(exposure=exposure, noise_sigma=2.0, blur_sigma=blur, shot_noise=0.5)
        views.append([cv2.cvtColor(cam.render(T, degradation=deg, rng=rng), cv2.COLOR_BGR2GRAY) for T in truth])
    rows = []
    for used in itertools.chain.from_iterable(itertools.combinations(PARTS, k) for k in range(4)):
        found, seconds, per_condition = 0, 0.0, []
        for frames in views:
            k = 0
            for gray in frames:
                t0 = time.perf_counter()
                x = clahe.apply(gray) if "clahe" in used else gray
                if "upsample" in used:
                    x = cv2.resize(x, None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC)
                _cc, ids, _mc, _mids = detectors["params" in used].detectBoard(x)
                seconds += time.perf_counter() - t0
                k += ids is not None and len(ids) >= 4
            per_condition.append(int(k))
            found += k
        n = sum(len(f) for f in views)
        rows.append({"parts": "+".join(used) or "none", "found": int(found), "views": n,
                     "per_condition": per_condition, "ms_mean": 1000 * seconds / n})
        print(f"| {rows[-1]['parts']:<23} | {found:>3} / {n} | {per_condition} | {rows[-1]['ms_mean']:.1f} ms |")
    if args.json:
        args.json.write_text(json.dumps({"conditions": CONDITIONS, "rows": rows}, indent=1))
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
