"""Experiment (notebook/ar.md, 2026-11-28): how far beside the board's centre the Gray-code
calibration poses aim (``graycode_poses(spread_m=...)``) against the scanned table's
flatness away from the board, on the synthetic rig.

    PYTHONPATH=. python scripts/graycode_spread_sweep.py 0.0 0.05 0.08
"""
import sys, numpy as np
from ar import Board, DEFAULT_BOARD_SPEC, SyntheticCamera, rotation_angle_deg
from ar.structured_light.synthetic import GrayCodeScene, graycode_poses, scan_view, default_scan_box, height_map_errors
from ar.structured_light.decode import decode_images
from ar.structured_light.calibrate import calibrate_graycode
from ar.structured_light.scan import scan_pose
b = Board(DEFAULT_BOARD_SPEC); cam = SyntheticCamera(b); box = default_scan_box(b); sc = GrayCodeScene(cam, [box])
Ts = scan_view(b, box, cam.proj_from_cam)
ds = decode_images(sc.capture_graycode(Ts, seed=9), cam.projector.size, name="scan")
for spread in [float(v) for v in sys.argv[1:]]:
    dec = [decode_images(sc.capture_graycode(T, seed=i), cam.projector.size, name=f"p{i}") for i, T in enumerate(graycode_poses(b, cam.proj_from_cam, 5, spread_m=spread))]
    c = calibrate_graycode(dec + [ds], b, cam.projector.size); Tt = cam.proj_from_cam; K = c.projector.camera_matrix
    s = scan_pose(ds, c, b); e = height_map_errors(s.height_map, [box])
    print(spread, 'rms %.3f fx%% %.3f T %.3f R %.4f' % (c.rms, 100*(K[0,0]/cam.projector.K[0,0]-1), 1000*np.linalg.norm(c.T-Tt[:3,3]), rotation_angle_deg(c.R@Tt[:3,:3].T)), 'corners', [v['corners'] for v in c.per_pose.values()], 'rejected', list(c.rejected_poses), 'box', round(e['boxes'][0]['error_mm'],2), 'table', e['table'], flush=True)
