"""A child who cannot read, in the real app by touch (offscreen, one app per subprocess as
tests/app/test_ui.py): a line drawn before there is anyone to walk it is kept, the notice
is a picture with one spoken sentence, and the next character added takes the line."""
from __future__ import annotations

import pytest

from app.ui.strings import tr
from tests.app.test_ui import _drive

pytestmark = pytest.mark.slow  # drives the real app in a child process


@pytest.mark.parametrize("lang", ["en", "ja"])
def test_a_line_drawn_before_any_character_is_kept_for_the_next_one(tmp_path, lang):
    r, out = _drive(tmp_path, "stroke_first", lang)
    assert r["cast_before"] == 0 and r["cast_after_stroke"] == 0
    assert r["notice"] == "add_someone" and r["message"] == tr("notice_add_someone", lang)
    assert r["spoken"] == [[r["message"], lang]]
    pending = r["pending"]
    assert len(pending) >= 2 and pending[0][0] == pytest.approx(0.15, abs=0.02)
    assert (out / "stroke_first.png").is_file()
    # the robot added next walks the kept line, saved at once; the dashed line is gone
    path = r["path"]
    assert len(path) >= 2 and r["saved_path"] == path and r["pending_after"] == []
    assert path[0][:2] == pytest.approx([0.15, 0.4], abs=0.02)
    assert path[-1][:2] == pytest.approx([0.79, 0.4], abs=0.02)
