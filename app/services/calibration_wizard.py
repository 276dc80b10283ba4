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

:class:`GrayCodeWizard` is the projector's Gray-code mode (issue 28): for each board pose
it shows the sequence (``ar.structured_light.patterns``) through the projector window's
callback, captures each image through the camera source, and decodes it at once (so a
pose the projector does not light, or where the board is not seen, is retried on the
spot); then it calibrates camera, projector and their rigid transform
(``ar.structured_light.calibrate``), saves ``projector.json`` (and ``camera.json``) and
scans the table at the last pose with the same projector window and camera.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from retrieval.errors import StoryBeamError

if TYPE_CHECKING:
    import numpy as np

    from ar.camera_sources import CameraSource


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


@dataclass
class GrayCodeWizard(CalibrationWizard):
    """Board -> one step per board pose (show the sequence, capture, decode) -> solve ->
    save ``projector.json`` (with the camera's calibration) and ``camera.json`` -> scan the
    table (:meth:`CalibrationWizard._scan_table`, captured the same way at the last pose).

    ``show`` is the projector window's callback (a projector-resolution image to show
    full screen until the next call); ``camera`` the rig's camera source. A live camera
    delivers frames some time after the projector changes, so after each change the
    wizard waits ``settle_s`` and drops ``settle_frames`` frames before it keeps one
    (:func:`app.services.table_scan.capture_sequence`). ``camera_file``: a ``camera.json``
    to keep the camera fixed (else the camera is calibrated from the same poses).
    ``before_pose(i)`` is called before pose ``i`` is captured (the synthetic rig moves
    its board there; with a real rig the teacher moves it and taps *next*).
    """

    show: Callable[["np.ndarray"], None] | None = None
    camera: "CameraSource | None" = None
    projector_size: tuple[int, int] = (1024, 768)
    n_poses: int = 5
    settle_frames: int = 2
    settle_s: float = 0.2
    camera_file: Path | None = None
    before_pose: Callable[[int], None] | None = None

    def __post_init__(self) -> None:
        self._board = None
        self._poses: list[Any] = []
        self._calibration = None
        self.steps = [CalibrationStep("board", self._make_board)]
        self.steps += [CalibrationStep(f"graycode_pose_{i + 1}", lambda i=i: self._capture_pose(i))
                       for i in range(self.n_poses)]
        self.steps += [CalibrationStep("solve", self._solve), CalibrationStep("save", self._save),
                       CalibrationStep("scan", self._scan_table)]
        if self.scan_capture is None and self.show is not None and self.camera is not None:
            self.scan_capture = self._capture_sequence

    def _capture_sequence(self) -> list:
        """The camera's frames of the whole Gray-code sequence, then black on the projector."""
        from app.services.table_scan import capture_sequence  # deferred: OpenCV, when the teacher calibrates
        from ar.errors import CalibrationError  # deferred: as above
        from ar.structured_light.patterns import graycode_sequence  # deferred: as above

        if self.show is None or self.camera is None:
            raise CalibrationError("the Gray-code mode needs the projector window and the camera")
        camera = self.camera

        def read():
            frame = camera.read()
            return None if frame is None else frame.image

        sequence = graycode_sequence(self.projector_size)
        frames = capture_sequence(sequence, self.show, read, self.settle_s, self.settle_frames)
        self.show(sequence[-1])  # black: the show is over
        return frames

    def _capture_pose(self, i: int) -> str:
        from ar.errors import CalibrationError  # deferred: OpenCV, when the teacher calibrates
        from ar.structured_light.calibrate import find_board  # deferred: as above
        from ar.structured_light.decode import decode_images  # deferred: as above

        if self.before_pose is not None:
            self.before_pose(i)
        frames = self._capture_sequence()
        decoded = decode_images(frames, self.projector_size, name=f"pose_{i + 1:02d}")
        if find_board(decoded, self._board) is None:
            raise CalibrationError("the board is not in view: move it under the projector's light and try again")
        self._poses = [p for p in self._poses if p.name != decoded.name] + [decoded]
        return f"pose {i + 1}: {100 * decoded.mask.mean():.0f} % of the camera's pixels decoded"

    def _solve(self) -> str:
        from ar.calibration import CameraCalibration  # deferred: OpenCV, when the teacher calibrates
        from ar.structured_light.calibrate import calibrate_graycode  # deferred: as above

        camera = CameraCalibration.load(self.camera_file) if self.camera_file else None
        self._calibration = calibrate_graycode(self._poses, self._board, self.projector_size, camera)
        c = self._calibration
        return (f"projector RMS {c.rms:.2f} px over {len(c.per_pose)} poses; "
                f"projector {1000 * float((c.T ** 2).sum() ** 0.5):.0f} mm from the camera")

    def _save(self) -> str:
        out = Path(self.out_dir)
        path = self._calibration.save(out / "projector.json")
        if self.camera_file is None:
            self._calibration.camera.save(out / "camera.json")
        return str(path)
