"""Touch scenarios of a child who cannot read yet (issue 29), for tests/support/ui_driver.py:
a line drawn before there is a character to walk it, and the notices that answer.

Each ``*_steps(app)`` yields the steps the driver runs one by one (see ui_scenarios.py).
"""
from __future__ import annotations

import sys

from ui_scenarios import editor, open_new_story
from ui_touch import stroke, table_px, tap, touching

drv = sys.modules["__main__"]


def stroke_first_steps(app):
    """New story; draw a line on the empty table (nobody there yet): a notice with a
    picture, the line kept and drawn; add a robot: it takes the line as its path."""
    yield from open_new_story(app)
    story = lambda: app.editor.story  # noqa: E731
    scene = lambda: story().scene(app.current_scene_id)  # noqa: E731
    yield lambda: drv.result.update(cast_before=len(scene().characters))

    def sketch():
        table = editor(app).table
        stroke([table_px(table, 0.15 + 0.08 * i, 0.4) for i in range(9)], on=table)
    yield touching(sketch, until=lambda: app.last_notice is not None)
    yield lambda: drv.result.update(notice=app.last_notice, message=app.last_message,
                                    spoken=list(app.speaker.said), pending=list(editor(app).table.pending),
                                    cast_after_stroke=len(scene().characters))
    yield lambda: drv.shot("stroke_first")
    yield touching(lambda: tap(editor(app).character_buttons["robot"]), until=lambda: len(scene().characters) == 1)
    yield lambda: drv.result.update(path=[list(p) for p in scene().characters[0].path],
                                    pending_after=list(editor(app).table.pending),
                                    saved_path=[list(p) for p in app.store.load_story(story().id)
                                                .scene(app.current_scene_id).characters[0].path])
    yield drv.finish


def first_launch_steps(app):
    """Nothing touched: which language the app opened in, and what it saved."""
    yield lambda: drv.result.update(lang=app.lang, title=app.sm.get_screen("home").title_label.text,
                                    saved=app.store.get_setting("language"))
    yield drv.finish


SCENARIOS = {"stroke_first": stroke_first_steps, "first_launch": first_launch_steps}
