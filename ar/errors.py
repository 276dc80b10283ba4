"""Errors raised by the AR geometry chain.

They subclass :class:`retrieval.errors.StoryBeamError`, so the CLI prints them as one
line (file and problem) instead of a traceback from deep inside OpenCV.
"""
from __future__ import annotations

from pathlib import Path

from retrieval.errors import StoryBeamError


class BoardSpecError(StoryBeamError):
    """A board spec string (``charuco:5x7:0.04:0.02:DICT_6X6_250``...) is malformed."""


class CalibrationError(StoryBeamError):
    """A calibration cannot be computed, or a calibration file is unusable.

    The message names the file (when there is one) and the problem, e.g.
    ``camera.json: camera_matrix must be 3x3, got shape (2, 3)``.
    """

    def __init__(self, problem: str, path: str | Path | None = None):
        self.path = str(path) if path is not None else None
        self.problem = problem
        super().__init__(f"{self.path}: {problem}" if self.path else problem)


class RigError(StoryBeamError):
    """The rig cannot deliver frames: its camera stopped or never sent one (the message names the source)."""
