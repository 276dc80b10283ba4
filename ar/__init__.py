"""The projector-camera rig: boards, pose tracking, calibration and a synthetic test bench.

Modules (each imports the others of this package directly; other packages import the
names below from ``ar``):

* :mod:`ar.errors` -- ``BoardSpecError``, ``CalibrationError`` (file-and-line messages), ``RigError``;
* :mod:`ar.geometry` -- 4x4 rigid transforms, projection, rays onto the table plane;
* :mod:`ar.boards` -- board spec strings, detection, printing (the *board frame*);
* :mod:`ar.pose` -- board pose from one camera frame (IPPE + refinement);
* :mod:`ar.filtering` -- temporal filtering and the tracking / holding / lost state;
* :mod:`ar.calibration` -- camera and projector-camera calibration, validated JSON;
* :mod:`ar.synthetic` -- an exact synthetic camera and projector with known truth, and
  recorded hand-held rig sessions (blur, noise, exposure, a hand) with their true poses;
* :mod:`ar.height_map` -- the scanned table: heights over the board plane (``HeightMap``);
* :mod:`ar.camera_sources` -- camera frames from a device, a video file, a folder of images;
* :mod:`ar.live` -- tracking on its own threads (newest frame wins, dropped frames counted);
* :mod:`ar.rig` -- the rig's one frame loop (``RigTracker.step``: region detection, pose,
  filter, projector pose -> ``RigState``) and the rigs that feed it: ``SyntheticRig``
  (no rig attached) and ``LiveRig`` (a camera and calibration files), ``open_rig``;
* :mod:`ar.structured_light` -- Gray-code projector-camera calibration and table scanning
  (imported by its own path: ``storybeam calibrate projector --graycode``, ``storybeam scan``).

Needs OpenCV and numpy only. Rendering (pyrender, trimesh, OpenGL) lives in the
subpackage :mod:`ar.render`, which is *not* imported here, so ``import ar`` works where
there is no GL (Android, batch jobs); :mod:`ar.closed_loop` (where projected light lands)
renders through it and is imported by its own path for the same reason. ``ar`` never
imports ``app`` or Kivy.
"""
from __future__ import annotations

from ar.boards import BOARD_KINDS, DEFAULT_BOARD_SPEC, Board, BoardDetection, BoardSpec, board_dictionary, write_board
from ar.calibration import (
    CAPTURE_LOG,
    CameraCalibration,
    CaptureStep,
    ProjectorCalibration,
    ProjectorCalibrationSequence,
    ProjectorPattern,
    ProjectorViewData,
    calibrate_camera,
    calibrate_from_correspondences,
    calibrate_projector,
    calibrate_projector_from_folder,
    capture_from_camera,
    detect_projected_corners,
    extract_projector_view,
    extrinsics_error,
    load_images,
    make_projector_pattern,
    place_pattern,
    rig_pose_for_step,
    validate_intrinsics,
    write_capture,
)
from ar.camera_sources import (
    CameraFrame,
    CameraSource,
    CameraSourceError,
    FrameListSource,
    ImageFolderSource,
    OpenCVDeviceSource,
    VideoFileSource,
    open_camera_source,
)
from ar.errors import BoardSpecError, CalibrationError, RigError
from ar.filtering import (
    HOLDING,
    LOST,
    TRACKING,
    KalmanParams,
    OneEuroParams,
    PoseKalmanFilter,
    PoseOneEuroFilter,
    PoseTracker,
    TrackerOutput,
)
from ar.geometry import (
    from_rvec_tvec,
    invert,
    look_at,
    make_transform,
    pixels_to_plane,
    pose_error,
    project_points,
    rays_to_plane,
    rotation_angle_deg,
    to_rvec_tvec,
)
from ar.height_map import HEIGHT_MAP_FILE, HeightMap, HeightMapError
from ar.live import LiveStats, LiveTracker
from ar.pose import (
    PoseEstimate,
    RegionPoseEstimator,
    draw_pose,
    estimate_board_pose,
    pose_confidence,
    pose_covariance,
    solve_board_pose,
)
from ar.rig import RIG_SIZE, LiveRig, ProjectedLight, RigState, RigTracker, SyntheticRig, open_rig
from ar.synthetic import (
    Degradation,
    PinholeModel,
    RigSession,
    SessionConfig,
    SyntheticCamera,
    TrajectoryConfig,
    calibration_poses,
    capture_projector_sequence,
    default_camera,
    default_proj_from_cam,
    default_projector,
    handheld_trajectory,
    load_session_truth,
    make_table_texture,
    record_rig_session,
)

__all__ = [
    # errors
    "BoardSpecError", "CalibrationError", "RigError",
    # geometry
    "make_transform", "from_rvec_tvec", "to_rvec_tvec", "invert", "rotation_angle_deg", "pose_error", "look_at",
    "project_points", "pixels_to_plane", "rays_to_plane",
    # boards
    "DEFAULT_BOARD_SPEC", "BOARD_KINDS", "BoardSpec", "BoardDetection", "Board", "board_dictionary", "write_board",
    # pose
    "PoseEstimate", "pose_covariance", "pose_confidence", "solve_board_pose", "estimate_board_pose", "draw_pose",
    "RegionPoseEstimator",
    # camera sources and live tracking
    "CameraSourceError", "CameraFrame", "CameraSource", "OpenCVDeviceSource", "VideoFileSource", "ImageFolderSource",
    "FrameListSource", "open_camera_source", "LiveStats", "LiveTracker",
    # the rig's frame loop and the rigs
    "RIG_SIZE", "ProjectedLight", "RigState", "RigTracker", "SyntheticRig", "LiveRig", "open_rig",
    # filtering
    "TRACKING", "HOLDING", "LOST", "OneEuroParams", "PoseOneEuroFilter", "KalmanParams", "PoseKalmanFilter",
    "TrackerOutput", "PoseTracker",
    # calibration
    "CameraCalibration", "ProjectorCalibration", "CaptureStep", "ProjectorCalibrationSequence", "ProjectorPattern",
    "ProjectorViewData", "CAPTURE_LOG", "validate_intrinsics", "load_images", "capture_from_camera",
    "calibrate_from_correspondences", "calibrate_camera", "make_projector_pattern", "place_pattern",
    "detect_projected_corners", "rig_pose_for_step", "extract_projector_view", "calibrate_projector",
    "write_capture", "calibrate_projector_from_folder", "extrinsics_error",
    # the scanned table (issue 28)
    "HEIGHT_MAP_FILE", "HeightMap", "HeightMapError",
    # synthetic bench
    "PinholeModel", "default_camera", "default_projector", "default_proj_from_cam", "Degradation",
    "make_table_texture", "SyntheticCamera", "TrajectoryConfig", "handheld_trajectory", "calibration_poses",
    "capture_projector_sequence", "SessionConfig", "RigSession", "record_rig_session", "load_session_truth",
]
