""""Act it out" by touch (issue 18) for tests/support/ui_driver.py, run through
tests/support/tablet_profile.py (the tablet's packages only) by tests/app/test_act_it_out_flow.py.

``tablet_act``: new story -> a character and its path -> *Act it out* on a video whose
picture cuts the body off (the camera is ``STORYBEAM_TEST_ACT_CUT``): the take is refused
with the step-back picture and the story is unchanged -> *Act it out* again on the
walking figure (``STORYBEAM_TEST_ACT_VIDEO``): the skeleton is drawn over the preview,
the nearest motions come back as tiles, a tap on the first gives the character that
motion -> Play draws it in 3-D on its path -> the teacher switches the camera feature
off -> the editor has no *Act it out* tile. The real pose estimator
(:class:`ar.body.BodyTracker`) and the real frontal search
(:class:`retrieval.library.ActSearch`, over the bundled library) run throughout.

The driver runs as ``__main__``; its helpers (``tap``, ``stroke``, ``touching``, ...) are
taken from there.
"""
from __future__ import annotations

import os
import sys
import time

drv = sys.modules["__main__"]


def _until(cond, what: str, seconds: float = 180.0):
    """A step that runs again until ``cond()`` holds; past ``seconds`` it fails naming ``what``."""
    state: dict = {}

    def step():
        start = state.setdefault("t0", time.monotonic())
        if cond():
            return None
        if time.monotonic() - start > seconds:
            raise AssertionError(f"waited {seconds:.0f} s for {what}")
        return "again"
    return step


def _act_once(app, name: str, camera: str):
    """Open *Act it out* on ``camera``, wait for the preview, Start, wait for the answer."""
    from kivy.core.window import Window

    ed = lambda: drv.editor(app)  # noqa: E731
    view = lambda: ed().act_view  # noqa: E731
    yield lambda: setattr(app, "act_camera", camera)
    yield drv.touching(lambda: drv.tap(ed().act_button),
                       until=lambda: getattr(ed(), "act_view", None) is not None and ed().act_view in Window.children)
    yield _until(lambda: view().state in ("ready", "failed") and view().preview.frames_shown >= 5,
                 f"{name}: the library and the camera preview")
    yield lambda: drv.result.update({f"{name}_open": {"state": view().state, "error": view().error}})
    yield drv.touching(lambda: drv.tap(view().start_button), until=lambda: view().state != "ready")
    yield _until(lambda: view().state == "take", f"{name}: the 3-2-1 countdown", 30)
    yield lambda: drv.result.update({f"{name}_countdown_seen": True, f"{name}_t_take": time.monotonic()})
    yield _until(lambda: view().state in ("results", "prompt", "failed"), f"{name}: the take and its answer", 120)
    yield lambda: drv.result.update({f"{name}_take_to_answer_s": time.monotonic() - drv.result.pop(f"{name}_t_take")})

    def record():
        v = view()
        drv.result[name] = {
            "state": v.state, "error": v.error, "verdict": v.verdict.as_dict() if v.verdict else None,
            "hits": [h.as_dict() for h in v.hits], "tiles": [t.trial for t in v.tiles],
            "prompt": v.prompt.reason, "prompt_shown": v.prompt.opacity > 0, "status": v.status.text,
            "frames_shown": v.preview.frames_shown, "skeletons_drawn": v.preview.skeletons_drawn,
            "take": dict(v.last_take),
        }
        drv.shot(name)
    yield record


def tablet_act_steps(app):
    from app.services.act_it_out import act_it_out_allowed

    home = app.sm.get_screen("home")
    yield from drv.open_new_story(app)
    story = lambda: app.editor.story  # noqa: E731
    scene = lambda: story().scene(app.current_scene_id)  # noqa: E731
    chosen = lambda: scene().character(app.selected_character_id)  # noqa: E731
    yield drv.touching(lambda: drv.tap(drv.editor(app).character_buttons["robot"]),
                       until=lambda: len(scene().characters) == 1)

    def sketch():
        table = drv.editor(app).table
        drv.stroke([drv.table_px(table, 0.15 + 0.07 * i, 0.4 + 0.02 * i) for i in range(10)], on=table)
    yield drv.touching(sketch, until=lambda: len(chosen().path) >= 5)
    yield lambda: (drv.result.update(before=story().to_dict()), drv.shot("editor"))

    # a camera that cannot be opened: said on the view, nothing else happens
    yield lambda: setattr(app, "act_camera", str(drv.OUT / "no-such-camera.mp4"))
    yield drv.touching(lambda: drv.tap(drv.editor(app).act_button),
                       until=lambda: getattr(drv.editor(app), "act_view", None) is not None
                       and drv.editor(app).act_view in drv.Window.children)
    yield _until(lambda: drv.editor(app).act_view.state == "failed", "the missing camera to be reported", 30)
    yield lambda: drv.result.update(no_camera={"error": drv.editor(app).act_view.error,
                                               "status": drv.editor(app).act_view.status.text,
                                               "notice": getattr(drv.editor(app).act_view, "notice", None),
                                               "start_disabled": drv.editor(app).act_view.start_button.disabled})
    yield drv.touching(lambda: drv.tap(drv.editor(app).act_view.back_button),
                       until=lambda: drv.editor(app).act_view._closing.is_set())
    yield _until(lambda: drv.editor(app).act_view not in drv.Window.children, "the view to close", 20)

    # a picture that cuts the body off: a picture prompt, and nothing changes
    yield from _act_once(app, "cut", os.environ["STORYBEAM_TEST_ACT_CUT"])
    yield lambda: drv.result.update(after_cut=story().to_dict())

    def other_pictures():  # the other two pictures, drawn for the screenshots (their takes are unit-tested)
        prompt = drv.editor(app).act_view.prompt
        for reason in ("lift_head", "no_body"):
            prompt.reason = reason
            drv.shot(f"prompt_{reason}")
        prompt.reason = "step_back"
    yield other_pictures
    yield drv.touching(lambda: drv.tap(drv.editor(app).act_view.back_button),
                       until=lambda: drv.editor(app).act_view._closing.is_set())
    yield _until(lambda: drv.editor(app).act_view not in drv.Window.children, "the view to close", 20)

    # the walking figure: results as tiles, a tap gives the character the motion
    yield from _act_once(app, "walk", os.environ["STORYBEAM_TEST_ACT_VIDEO"])
    view = lambda: drv.editor(app).act_view  # noqa: E731
    yield drv.touching(lambda: drv.tap(view().tiles[0]),
                       until=lambda: chosen().motion.clip_id == drv.result["walk"]["tiles"][0])
    yield lambda: drv.result.update(motion=[chosen().motion.motion_class, chosen().motion.clip_id],
                                    path=len(chosen().path), camera_closed=not view()._thread.is_alive()
                                    if view()._thread else None)
    yield _until(lambda: not view()._thread.is_alive(), "the camera worker to stop", 20)
    yield lambda: drv.result.update(worker_stopped=True, texture_released=view().preview.texture is None)
    from tablet_scenarios import _play_3d_steps
    yield from _play_3d_steps(app, "play")

    # the teacher switches the camera feature off for the class
    yield lambda: (setattr(app, "teacher_unlocked", True), app.go("teacher"))
    teacher = lambda: app.sm.get_screen("teacher")  # noqa: E731
    yield drv.touching(lambda: drv.tap(teacher().action_buttons["act_it_out"]),
                       until=lambda: not act_it_out_allowed(app.store))
    yield lambda: (drv.result.update(switch_label=teacher().action_buttons["act_it_out"].text), drv.shot("teacher"))
    yield lambda: teacher().leave()
    yield _until(lambda: app.sm.current == "home", "home")
    yield drv.touching(lambda: drv.tap(next(t for t in home.tiles if t.story_id == story().id)),
                       until=lambda: app.sm.current == "editor")
    yield lambda: drv.result.update(act_tile_after_off=drv.editor(app).act_button is not None)

    def report():
        from tablet_scenarios import _imported, _refused
        drv.result["story"] = story().to_dict()
        drv.result["modules"] = _imported()
        drv.result["refused"] = _refused()
    yield report
    yield drv.finish


SCENARIOS = {"tablet_act": tablet_act_steps}
#: the scenarios that get the app's 3-D renderer (Kivy GL)
RENDERED = tuple(SCENARIOS)
