"""Project exceptions.

Every problem a user can cause (a malformed file, a bad option, a missing folder) is
raised as a subclass of :class:`StoryBeamError`, so the CLI and the app can show one clear
message instead of a traceback from deep inside a parser.
"""
from __future__ import annotations

from pathlib import Path


class StoryBeamError(Exception):
    """Base class of every error StoryBeam reports to a user."""


class MotionFormatError(StoryBeamError):
    """A motion file (BVH, ASF, AMC) is malformed.

    The message names the file, the line (when known) and the problem, e.g.
    ``walk.bvh, line 12: expected 6 channel values, found 5``.
    """

    def __init__(self, path: str | Path | None, problem: str, line: int | None = None):
        self.path = str(path) if path is not None else "<memory>"
        self.line = line
        self.problem = problem
        where = self.path if line is None else f"{self.path}, line {line}"
        super().__init__(f"{where}: {problem}")


class DatasetError(StoryBeamError):
    """A labelled dataset folder (labels.csv and its files) is unusable."""


class IndexFormatError(StoryBeamError):
    """A saved retrieval index cannot be read."""


class QuantizerError(StoryBeamError):
    """A quantiser cannot be fitted or applied (too few frames, wrong feature width)."""
