"""Drives the real app through search by pose and the library's groups, by touch.

Run by tests/app/test_pose_picker.py as ``python tests/support/pose_driver.py pose DB OUT``
(the same arguments as :mod:`tests.support.ui_driver`, whose step runner, touch helpers and
app it reuses; this module only adds the scenario). The motion library is the bundled
one (the pose search and the groups need real motion files).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import tests.support.ui_driver as ui  # noqa: E402  (reads SCENARIO DB OUT from sys.argv, prepares Kivy)
from tests.support.ui_driver import editor, finish, result, shot, stroke, tap, touching  # noqa: E402

from app.services.catalog import MotionCatalog  # noqa: E402
from app.ui.pose_figure import HANDLE_DP  # noqa: E402


def _drag_handle(picker, handle: str, dx_m: float, dy_m: float) -> None:
    """A finger from a handle's drawn centre to a point (dx, dy) metres away on the figure."""
    fig = picker.figure
    x0, y0 = fig.handle_px(handle)
    s = fig.scale
    pts = [fig.to_window(x0 + dx_m * s * i / 8, y0 + dy_m * s * i / 8) for i in range(9)]
    stroke(pts, on=fig)


def _record(picker, name: str) -> None:
    result[name] = {
        "features": picker.figure.model.features().tolist(),
        "positions": picker.figure.model.positions().tolist(),
        "head_deg": picker.figure.model.head_deg,
        "hits": [h.as_dict() for h in picker.hits],
        "starts": [t._start for t in picker.tiles],
        "searches": picker.searches,
    }


def wait_until(cond, polls: int = 1200):
    """A step that runs again (every 50 ms, at most ``polls`` times) until ``cond()``."""
    state = {"polls": 0}

    def step():
        if not cond():
            state["polls"] += 1
            if state["polls"] > polls:
                raise AssertionError("waited too long")
            return "again"
    return step


def pose_steps(app):
    ed = lambda: editor(app)  # noqa: E731
    state: dict = {}
    chosen = lambda: app.editor.story.scene(app.current_scene_id).character(app.selected_character_id)  # noqa: E731
    yield lambda: ed().select_character(app.editor.story.scenes[0].characters[0].id)
    yield lambda: result.update(pose_button=[ed().pose_button.width, ed().pose_button.height, ed().pose_button.text],
                                groups_button=[ed().groups_button.width, ed().groups_button.height,
                                               ed().groups_button.text])
    yield touching(lambda: tap(ed().pose_button), until=lambda: getattr(ed(), "pose_view", None) is not None)
    picker = lambda: ed().pose_view  # noqa: E731
    yield wait_until(lambda: picker().searches >= 1)  # the library loads, the standing pose is searched
    yield lambda: _record(picker(), "standing")
    yield lambda: result.update(pose_title=picker().title.text, handle_dp=HANDLE_DP)
    yield lambda: shot("pose_standing")
    # a kick: the right foot forward and up to hip height
    yield touching(lambda: _drag_handle(picker(), "right_foot", 0.65, 0.75), until=lambda: picker().searches >= 2)
    yield lambda: _record(picker(), "kick")
    # a jump: the hips up, then both hands far above the head (out of reach: pulled back)
    yield touching(lambda: _drag_handle(picker(), "hips", 0.0, 0.3), until=lambda: picker().searches >= 3)
    yield touching(lambda: _drag_handle(picker(), "left_hand", -0.1, 1.6), until=lambda: picker().searches >= 4)
    yield touching(lambda: _drag_handle(picker(), "right_hand", 0.1, 1.6), until=lambda: picker().searches >= 5)
    # the head pulled far forwards: it tilts only so far
    yield touching(lambda: _drag_handle(picker(), "head", 0.6, -0.1), until=lambda: picker().searches >= 6)
    yield lambda: _record(picker(), "jump")
    yield lambda: shot("pose_jump")
    yield lambda: result.update(tile_boxes=[[*t.to_window(*t.pos), *t.size] for t in picker().tiles])

    def pick_first():
        state["picked"] = picker().tiles[0].trial
        tap(picker().tiles[0])
    yield touching(pick_first, changes=lambda: chosen().motion.clip_id)
    yield lambda: result.update(picked=state["picked"], clip_after_pose=chosen().motion.clip_id,
                                class_after_pose=chosen().motion.motion_class)

    yield touching(lambda: tap(ed().groups_button), until=lambda: getattr(ed(), "group_view", None) is not None)
    groups = lambda: ed().group_view  # noqa: E731
    yield wait_until(lambda: len(groups().group_tiles) > 0)
    yield lambda: result.update(groups_title=groups().title.text, group_texts=[t.text for t in groups().group_tiles],
                                group_reps=[t.trial for t in groups().group_tiles],
                                group_boxes=[[*t.to_window(*t.pos), *t.size] for t in groups().group_tiles])
    yield lambda: shot("groups")
    yield touching(lambda: tap(groups().group_tiles[0]), until=lambda: groups().opened_group == 0)
    yield lambda: result.update(group0_clips=[t.trial for t in groups().clip_tiles], group0_title=groups().title.text)
    yield touching(lambda: tap(groups().back_button), until=lambda: groups().opened_group is None)
    yield touching(lambda: tap(groups().group_tiles[-1]), until=lambda: groups().opened_group is not None)

    def pick_in_group():
        state["group_pick"] = groups().clip_tiles[-1].trial
        tap(groups().clip_tiles[-1])
    yield touching(pick_in_group, changes=lambda: chosen().motion.clip_id)
    yield lambda: result.update(group_pick=state["group_pick"], clip_after_group=chosen().motion.clip_id)
    yield finish


ui.SCENARIOS["pose"] = pose_steps

if __name__ == "__main__":
    app = ui.DriverApp(ui.DB, lang=os.environ.get("STORYBEAM_TEST_LANG", "en"), demo=True,
                       catalog=MotionCatalog(build_index=False))
    ui.app_ref.append(app)
    app.run()
