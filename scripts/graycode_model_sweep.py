"""Experiment (notebook/ar.md, 2026-11-28): the Gray-code calibration's projector distortion
model against the projector's resolution and the number of poses, on the synthetic rig.

Renders 8 poses (``graycode_poses``) for a 512 x 384 and a 1024 x 768 projector, then
calibrates on the first 4, 5, 6 and 8 with three projector models (k3 fixed; also zero
tangential; also k2 fixed) and prints each one's errors against the truth. Several minutes.

    PYTHONPATH=. python scripts/graycode_model_sweep.py
"""
import cv2
import numpy as np

import ar.structured_light.calibrate as C
from ar import DEFAULT_BOARD_SPEC, Board, SyntheticCamera, rotation_angle_deg
from ar.structured_light.synthetic import GrayCodeScene, graycode_poses
from ar.structured_light.decode import decode_images
from ar.synthetic import default_projector
b=Board(DEFAULT_BOARD_SPEC)
FL = {"k3": cv2.CALIB_FIX_K3, "k3+tan": cv2.CALIB_FIX_K3|cv2.CALIB_ZERO_TANGENT_DIST, "k3k2+tan": cv2.CALIB_FIX_K3|cv2.CALIB_FIX_K2|cv2.CALIB_ZERO_TANGENT_DIST}
for size in ((512,384),(1024,768)):
  pr=default_projector().scaled(*size); cam=SyntheticCamera(b,projector=pr); sc=GrayCodeScene(cam)
  poses=graycode_poses(b,cam.proj_from_cam,8,spread_m=0.0)
  dec=[decode_images(sc.capture_graycode(T,seed=i),pr.size,name=str(i)) for i,T in enumerate(poses)]
  for n in (4,5,6,8):
    for k,f in FL.items():
      C.PROJECTOR_FLAGS=f
      c=C.calibrate_graycode(dec[:n],b,pr.size); Tt=cam.proj_from_cam; K=c.projector.camera_matrix
      print(size[0],n,k,'rms %.3f fx%% %.3f T %.2f mm R %.3f deg cx %.2f cy %.2f'%(c.rms, 100*(K[0,0]/pr.K[0,0]-1), 1000*np.linalg.norm(c.T-Tt[:3,3]), rotation_angle_deg(c.R@Tt[:3,:3].T), K[0,2]-pr.K[0,2], K[1,2]-pr.K[1,2]), flush=True)
