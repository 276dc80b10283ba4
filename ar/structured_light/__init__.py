"""Gray-code structured light: projector-camera calibration and table scanning.

Modules:

* :mod:`ar.structured_light.patterns` -- the sequence to show (OpenCV's ``GrayCodePattern``,
  then white, then black);
* :mod:`ar.structured_light.decode` -- per camera pixel projector column/row, shadow masks;
* :mod:`ar.structured_light.calibrate` -- Moreno-Taubin local homographies, camera,
  projector and stereo calibration, ``projector.json``;
* :mod:`ar.structured_light.scan` -- triangulated point cloud, board plane, height map, PLY;
* :mod:`ar.structured_light.synthetic` -- the synthetic rig showing the sequence onto its
  table and boxes, with known truth.

Part of the ``ar`` core: OpenCV and numpy only.
"""
