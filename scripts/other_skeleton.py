"""Development data for issue 31: library trials re-expressed on other skeletons.

    .venv/bin/python scripts/other_skeleton.py --data ../shared/data/cmu --out /work/data/cmu-other \
        [--kinds cartoon,rig] [--fps 60] [--every 1]

Writes ``OUT/<kind>/<trial>.bvh`` for every trial of ``--data`` (every ``--every``-th),
the folder ``storybeam eval --identity --pose-identity --skeleton-from OUT/<kind>`` reads.
Each kind is the project's position-based retarget (:func:`retrieval.animation.retarget`)
onto a canonical body of other proportions, then written as a third-party converter
would:

* ``cartoon`` — a child-sized cartoon body (1.1 m; short legs, long torso and arms, big
  head), canonical joint names, Y up, metres-per-unit 0.01.
* ``rig`` — an adult game rig (1.85 m; long legs, narrow hips, wide shoulders): Mixamo
  joint names, two extra spine joints (so "the spine" is the upper one), the head joint
  at the eyes rather than the top of the neck, Z up, and a T-pose first frame (as
  converters add).

Nothing here is committed data: CMU's terms allow it, but the files are rebuilt in
minutes from ../shared/data.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from retrieval.animation import BodyProportions, canonical_skeleton, retarget
from retrieval.library import read_labels
from retrieval.motion import Joint, Motion, Skeleton, load_motion, resample, save_bvh

CARTOON = BodyProportions(thigh=0.19, shin=0.17, lower_spine=0.16, upper_spine=0.2, neck=0.05, head_top=0.22,
                          upper_arm=0.2, forearm=0.18, shoulder_half_width=0.09, hip_half_width=0.07)
RIG = BodyProportions(thigh=0.27, shin=0.27, hip_half_width=0.045, shoulder_half_width=0.13, upper_arm=0.16,
                      forearm=0.14, lower_spine=0.10, upper_spine=0.17, neck=0.12, head_top=0.06)
MIXAMO = {"hips": "mixamorig:Hips", "spine": "mixamorig:Spine", "neck": "mixamorig:Neck", "head": "mixamorig:Head",
          "left_shoulder": "mixamorig:LeftArm", "left_elbow": "mixamorig:LeftForeArm",
          "left_hand": "mixamorig:LeftHand", "right_shoulder": "mixamorig:RightArm",
          "right_elbow": "mixamorig:RightForeArm", "right_hand": "mixamorig:RightHand",
          "left_hip": "mixamorig:LeftUpLeg", "left_knee": "mixamorig:LeftLeg", "left_ankle": "mixamorig:LeftFoot",
          "left_toe": "mixamorig:LeftToeBase", "right_hip": "mixamorig:RightUpLeg",
          "right_knee": "mixamorig:RightLeg", "right_ankle": "mixamorig:RightFoot",
          "right_toe": "mixamorig:RightToeBase"}
#: native Z up from Y up: (x, y, z) -> (x, -z, y)
Y_TO_Z = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])


def as_rig(m: Motion) -> Motion:
    """Rename to Mixamo, split the spine->neck bone into three (identity rotations on the
    inserted joints), Z up, a T-pose first frame."""
    sk = m.skeleton
    joints: list[Joint] = []
    new_index: dict[int, int] = {}
    inserted: list[int] = []
    for i, j in enumerate(sk.joints):
        parent = -1 if j.parent < 0 else new_index[j.parent]
        offset = j.offset.copy()
        if j.name == "neck":  # spine -> Spine1 -> Spine2 -> neck, each a third of the bone
            for k in (1, 2):
                joints.append(Joint(f"mixamorig:Spine{k}", parent, offset / 3, list(j.channels), j.rotation_order))
                parent = len(joints) - 1
                inserted.append(parent)
            offset = offset / 3
        name = MIXAMO.get(j.name, j.name if not j.name.endswith("_end") else "End")
        new_index[i] = len(joints)
        joints.append(Joint(name, parent, offset, list(j.channels), j.rotation_order))
    t = m.n_frames
    rot = np.broadcast_to(np.eye(3), (t, len(joints), 3, 3)).copy()
    for i, k in new_index.items():
        rot[:, k] = m.rotations[:, i]
    rot = Y_TO_Z @ rot @ Y_TO_Z.T
    root = m.root_translation @ Y_TO_Z.T
    for j in joints:
        j.offset = Y_TO_Z @ j.offset
    tpose_root = np.array([0.0, 0.0, float(-sum(o[1] for o in (sk.offsets[sk.index(n)] for n in
                                                                 ("left_hip", "left_knee", "left_ankle"))))])
    rot = np.concatenate([np.broadcast_to(np.eye(3), (1, len(joints), 3, 3)), rot])
    root = np.concatenate([tpose_root[None], root])
    return Motion(Skeleton(joints, sk.metres_per_unit, "z", "rig"), rot, root, m.fps, m.name)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path("../shared/data/cmu"))
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--kinds", default="cartoon,rig")
    ap.add_argument("--fps", type=float, default=60.0)
    ap.add_argument("--every", type=int, default=1, help="every n-th trial only")
    args = ap.parse_args()
    kinds = [k for k in args.kinds.split(",") if k]
    targets = {"cartoon": canonical_skeleton(CARTOON, 1.1, "cartoon"), "rig": canonical_skeleton(RIG, 1.85, "rig")}
    rows = read_labels(args.data)[:: args.every]
    for n, row in enumerate(rows):
        motion = load_motion(row.file, row.skeleton) if row.skeleton else load_motion(row.file)
        motion = resample(motion, args.fps)
        for kind in kinds:
            moved = retarget(motion, targets[kind], name=row.trial)
            save_bvh(as_rig(moved) if kind == "rig" else moved, args.out / kind / f"{row.trial}.bvh")
        print(f"{n + 1}/{len(rows)} {row.trial}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
