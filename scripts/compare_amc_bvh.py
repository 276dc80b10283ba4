"""Per-joint agreement of CMU take 01_01 read from its AMC and from CMU's BVH conversion.

    .venv/bin/python scripts/compare_amc_bvh.py [--data ../shared/data/cmu]

Prints, for every canonical joint, the largest distance (mm) between the two loaders'
positions over all frames, raw and after adding back the thorax bone the BVH conversion
lacks (its Neck and clavicles sit at the thorax's start).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from retrieval.motion import canonical_joint_map
from retrieval.motion import global_transforms, positions
from retrieval.motion.formats import load_motion


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path("../shared/data/cmu"))
    args = ap.parse_args()
    amc = load_motion(args.data / "extra" / "01_01.amc", args.data / "asf" / "01.asf")
    bvh = load_motion(args.data / "extra" / "01_01.bvh")
    print(f"AMC {amc.n_frames} frames at {amc.fps:g} fps; BVH {bvh.n_frames} frames at {bvh.fps:g} fps "
          f"(T-pose dropped), BVH units detected {bvh.skeleton.metres_per_unit:.6f} m")
    pa, pb = positions(amc), positions(bvh)
    ca, cb = canonical_joint_map(amc.skeleton), canonical_joint_map(bvh.skeleton)
    sk = amc.skeleton
    g, _ = global_transforms(amc)
    thorax = np.einsum("tab,b->ta", g[:, sk.index("thorax")], sk.offsets[sk.index("lowerneck")]) * sk.metres_per_unit
    print(f"{'joint':15s} {'AMC':10s} {'BVH':13s} {'raw max mm':>10s} {'+thorax mm':>10s}")
    thorax_index = sk.index("thorax")
    for part in ca:
        a, b = pa[:, ca[part]], pb[:, cb[part]]
        raw = np.linalg.norm(a - b, axis=1).max() * 1000
        above = _descends_from(sk, ca[part], thorax_index) and ca[part] != thorax_index
        fixed = f"{np.linalg.norm(a - b - thorax, axis=1).max() * 1000:10.4f}" if above else f"{'-':>10s}"
        print(f"{part:15s} {sk.names[ca[part]]:10s} {bvh.skeleton.names[cb[part]]:13s} {raw:10.4f} {fixed}")
    return 0


def _descends_from(sk, j: int, ancestor: int) -> bool:
    while j >= 0:
        if j == ancestor:
            return True
        j = sk.joints[j].parent
    return False


if __name__ == "__main__":
    raise SystemExit(main())
