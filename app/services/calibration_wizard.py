"""The teacher's calibration wizard, as steps the UI runs one at a time.

Kept free of Kivy so it can be tested and reused: each step is a title key (for the
strings table), a short explanation key and a function that does the work (the UI runs
it off the UI thread) and returns a one-line result. The work is done by ``ar/``:
board detection and ``ar.calibration.calibrate_camera``. Without a camera (this
development machine, a test) the capture step uses ``ar.synthetic.SyntheticCamera``
so the whole chain still runs end to end.

The last step, *Scan the table* (:mod:`app.services.table_scan`), projects the Gray-code
sequence over the table with its objects, scans it into a height map and stores it
beside the calibration (``table.npz``), where the projector stage finds it. A real rig
gives the wizard ``scan_capture`` (show each pattern in the projector window, keep a
camera frame: :func:`app.services.table_scan.capture_sequence`) and the Gray-code
``projector.json`` in ``out_dir``; the synthetic wizard (no camera) scans the synthetic
rig's table with boxes, a real camera without ``scan_capture`` is refused. ``scan(captures, calibration) -> HeightMap`` is replaceable (tests).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from retrieval.errors import StoryBeamError


@dataclass
class CalibrationStep:
    key: str  # identifies the step (and its explanation in the UI)
    run: Callable[[], str]
    result: str | None = None
    error: str | None = None


@dataclass
class CalibrationWizard:
    """Board -> capture views -> solve the camera -> save ``camera.json`` -> scan the table."""

    out_dir: Path
    camera_index: int | None = None  # None: synthetic camera
    n_views: int = 8
    board_spec: str | None = None
    steps: list[CalibrationStep] = field(default_factory=list)
    current: int = 0
    #: the rig's Gray-code captures at its current pose (None: the synthetic rig's table)
    scan_capture: Callable[[], list] | None = None
    #: captures + calibration -> HeightMap (default: decode, triangulate, rasterise)
    scan: Callable[[list, object], object] | None = None

    def __post_init__(self) -> None:
        self._board = None
        self._views: list = []
        self._calibration = None
        self.steps = [
            CalibrationStep("board", self._make_board),
            CalibrationStep("capture", self._capture),
            CalibrationStep("solve", self._solve),
            CalibrationStep("save", self._save),
            CalibrationStep("scan", self._scan_table),
        ]

    @property
    def done(self) -> bool:
        return self.current >= len(self.steps)

    def run_next(self) -> CalibrationStep:
        """Run the current step; on success move to the next. Errors are kept, not raised,
        so the wizard can show them and let the teacher retry the same step."""
        step = self.steps[self.current]
        try:
            step.result, step.error = step.run(), None
            self.current += 1
        except (StoryBeamError, ImportError, OSError, ValueError) as exc:
            step.error = str(exc)
        return step

    # The steps import ar (and with it OpenCV) when the teacher runs them: ~55 ms on a
    # desktop (measured), more on a tablet, that the app's start-up does not pay.
    def _make_board(self) -> str:
        from ar import DEFAULT_BOARD_SPEC, Board  # deferred: OpenCV, when the teacher calibrates
        self._board = Board(self.board_spec or DEFAULT_BOARD_SPEC)
        return f"board {self._board.spec}"

    def _capture(self) -> str:
        if self.camera_index is not None:
            from ar import capture_from_camera  # deferred: OpenCV, when the teacher calibrates
            self._views = capture_from_camera(self.camera_index, self.n_views, self._board)
            return f"{len(self._views)} camera views"
        from ar import SyntheticCamera, calibration_poses  # deferred: OpenCV, when the teacher calibrates
        cam = SyntheticCamera(self._board, supersample=1)
        self._views = [(f"synthetic_{i:02d}", cam.render(T)) for i, T in
                       enumerate(calibration_poses(self._board, self.n_views))]
        return f"{len(self._views)} synthetic views"

    def _solve(self) -> str:
        from ar import calibrate_camera  # deferred: OpenCV, when the teacher calibrates
        self._calibration = calibrate_camera(self._views, self._board)
        return f"reprojection RMS {self._calibration.rms:.2f} px over {len(self._calibration.per_view_errors)} views"

    def _save(self) -> str:
        path = self._calibration.save(Path(self.out_dir) / "camera.json")
        return str(path)

    def _scan_table(self) -> str:
        from app.services import table_scan  # deferred: OpenCV and the structured-light scan, when the teacher scans

        if self.scan_capture is None:
            if self.camera_index is not None:  # a real camera but no projector to show the patterns
                raise StoryBeamError("the projector must show the scan's patterns: connect it as a second display")
            captures, calibration = table_scan.synthetic_scan(self._board)
        else:
            from ar.structured_light.calibrate import GrayCodeCalibration  # deferred: as above
            calibration = GrayCodeCalibration.load(Path(self.out_dir) / "projector.json")
            captures = self.scan_capture()
        scan = self.scan or (lambda caps, cal: table_scan.scan_captures(caps, cal, self._board))
        height_map = scan(captures, calibration)
        table_scan.save_scan(height_map, self.out_dir)
        return table_scan.describe_scan(height_map)
