"""The child's whole flow by touch on the tablet profile (issue 13, part 2), for
tests/support/ui_driver.py, run through tests/support/tablet_profile.py (which blocks the
desktop-only packages first).

``tablet``: new story -> sketch two characters' paths -> choose a motion by category
(walk) and one through "More like this" (a clip found by the motion index) -> Play with
3-D characters (Kivy GL) -> the projector screen through the synthetic tracked rig ->
report the story and ``READY``, then wait to be killed (the test SIGKILLs the process).
``tablet_reopen``: the killed app's profile opened again: tap the story's tile, Play
draws it in 3-D again. Both record which modules the flow imported (``modules``).

The driver runs as ``__main__``; its helpers (``tap``, ``stroke``, ``touching``, ...) are
taken from there.
"""
from __future__ import annotations

import json
import os
import sys

drv = sys.modules["__main__"]


def _imported() -> list[str]:
    return sorted({name.split(".")[0] for name in sys.modules})


def _refused() -> list[str]:
    """What the tablet profile's import blocker refused so far (tests/support/tablet_profile.py)."""
    return sorted({name for finder in sys.meta_path for name in getattr(finder, "refused", ())})


def _wait(cond, state: dict, polls: int = 1200):
    """A step that waits (re-runs) until ``cond()`` holds or the renderer failed."""
    def step():
        app = drv.app_ref[0]
        if not cond() and (app.renderer is None or app.renderer.error is None) and state.setdefault("n", 0) < polls:
            state["n"] += 1
            return "again"
        state["n"] = 0
    return step


def _play_3d_steps(app, name: str):
    play = lambda: app.sm.get_screen("play")  # noqa: E731
    yield drv.touching(lambda: drv.tap(drv.editor(app).play_button), until=lambda: app.sm.current == "play")
    yield _wait(lambda: play().player.drawn_by is not None and play().table.frame_texture is not None, {})

    def record():
        tex = play().table.frame_texture
        drv.result[name] = {"drawn_by": play().player.drawn_by, "render_error": app.renderer.error,
                            "texture": list(tex.size) if tex is not None else None,
                            "uploads": play().player.gl.uploads if play().player.gl else None}
        drv.shot(name)
    yield record


def tablet_steps(app):
    yield from drv.open_new_story(app)
    story = lambda: app.editor.story  # noqa: E731
    scene = lambda: story().scene(app.current_scene_id)  # noqa: E731
    chosen = lambda: scene().character(app.selected_character_id)  # noqa: E731
    for k, kind in enumerate(("robot", "animal")):
        yield drv.touching(lambda kind=kind: drv.tap(drv.editor(app).character_buttons[kind]),
                           until=lambda k=k: len(scene().characters) == k + 1)

        def sketch(k=k):
            table = drv.editor(app).table
            drv.stroke([drv.table_px(table, 0.15 + 0.08 * i, 0.25 + 0.3 * k + 0.02 * i) for i in range(10)], on=table)
        yield drv.touching(sketch, until=lambda: len(chosen().path) >= 5)
        if k == 0:  # by category
            yield drv.touching(lambda: drv.tap(drv.editor(app).motion_buttons["walk"]),
                               until=lambda: chosen().motion.motion_class == "walk")
        else:  # "More like this" on the chosen category: a clip the motion index finds
            yield drv.touching(lambda: drv.tap(drv.editor(app).motion_buttons["dance"]),
                               until=lambda: chosen().motion.motion_class == "dance")
            yield lambda: (app.catalog.start_index(), app.catalog.wait_index(180))
            yield lambda: drv.editor(app).more_like_this()
            yield lambda: drv.result.update(index_ready=app.catalog.index_ready,
                                            similar=[t.trial for t in drv.editor(app).clip_tiles])

            def pick_similar():
                drv.tap(drv.editor(app).clip_tiles[1])  # the first clip like it (tile 0 is the anchor)
            yield drv.touching(pick_similar, until=lambda: chosen().motion.clip_id == drv.result["similar"][1])
    yield lambda: drv.result.update(paths=[len(c.path) for c in scene().characters],
                                    motions=[[c.motion.motion_class, c.motion.clip_id] for c in scene().characters])
    yield from _play_3d_steps(app, "play")
    yield lambda: app.go("projector")
    proj = lambda: app.sm.get_screen("projector")  # noqa: E731
    yield _wait(lambda: proj().frames_shown >= 5 and proj().last_stage_frame is not None
                and proj().last_stage_frame.state == "tracking" and proj().drawn_by == "kivy-gl", {})

    def hold_still():  # the story played on while the first frames were prepared: back to scene 1
        proj().player.pause()
        proj().player.seek(1.0)
        drv.result["shown_before_hold"] = proj().frames_shown
    yield hold_still
    first = lambda: story().scenes[0].id  # noqa: E731
    yield _wait(lambda: proj().frames_shown >= drv.result["shown_before_hold"] + 2
                and proj().last_stage_frame.scene_id == first() and abs(proj().last_stage_frame.t - 1.0) < 1e-6, {})

    def record_projector():
        frame = proj().last_stage_frame
        drv.result["projector"] = {"drawn_by": proj().drawn_by, "state": frame.state, "live": frame.live,
                                   "use_stage": proj().use_stage, "frames": proj().frames_shown,
                                   "lit_pixels": int((frame.projector.max(axis=2) > 40).sum())
                                   if frame.projector is not None else None,
                                   "problems": frame.problems, "character_px": frame.character_px,
                                   "render_error": app.renderer.error}
        drv.shot("projector")
    yield record_projector

    def report():
        drv.result["story_id"] = story().id
        drv.result["story"] = story().to_dict()
        drv.result["modules"] = _imported()
        drv.result["refused"] = _refused()
        (drv.OUT / "result.json").write_text(json.dumps(drv.result))
        print("READY", flush=True)
    yield report
    yield "hang"


def tablet_reopen_steps(app):
    home = app.sm.get_screen("home")
    story_id = os.environ["STORYBEAM_TEST_STORY"]
    yield lambda: drv.result.update(tiles=[t.story_id for t in home.tiles])
    tile = lambda: next(t for t in home.tiles if t.story_id == story_id)  # noqa: E731
    yield drv.touching(lambda: drv.tap(tile()), until=lambda: app.editor is not None and app.sm.current == "editor")
    yield lambda: drv.result.update(story=app.editor.story.to_dict())
    yield from _play_3d_steps(app, "play_again")
    yield lambda: drv.result.update(modules=_imported(), refused=_refused())
    yield drv.finish


SCENARIOS = {"tablet": tablet_steps, "tablet_reopen": tablet_reopen_steps}
#: the scenarios that get the app's 3-D renderer (Kivy GL)
RENDERED = tuple(SCENARIOS)
