"""Drives the real StoryBeam app with simulated touches, in its own process.

Run by tests/tests/app/test_ui.py as ``python tests/support/ui_driver.py SCENARIO DB OUT``: one
Kivy app per process (Kivy keeps global window state), offscreen SDL. Each scenario is a
list of steps; between steps a few frames are drawn so layouts and canvases settle.
Results go to OUT/result.json; screenshots to OUT/*.png.

Deterministic under load: a fixed number of frames between steps is not enough on a busy
machine. A ModalView (the arc chooser fading out for 0.1 s, a message) swallows every
touch while it is on the window, and a screen rebuilt by the last step is laid out a frame
or more later. So every touch first waits (bounded by ``STEP_DEADLINE_S``) until its target
can really be touched (see :func:`why_untouchable`), and a :func:`touching` step also
waits for its effect on the story, retrying the touch (``retries``, each one recorded in
``result["retries"]``) only when it provably had none.
"""
from __future__ import annotations

import json
import os
import sys
import time
import weakref
from pathlib import Path
from typing import Callable

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.ui.env import prepare_kivy_env  # noqa: E402

prepare_kivy_env(headless=True, width=1280, height=800)

from kivy.clock import Clock  # noqa: E402
from kivy.core.window import Window  # noqa: E402
from kivy.tests.common import UnitTestTouch  # noqa: E402

from app.services.catalog import MotionCatalog  # noqa: E402
from app.ui.app import StoryBeamApp  # noqa: E402

SCENARIO, DB, OUT = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
OUT.mkdir(parents=True, exist_ok=True)
result: dict = {"steps": []}


#: The longest a step may wait for its target to become touchable or for its effect.
STEP_DEADLINE_S = 20.0


class NotReady(Exception):
    """The step's touch target cannot be touched yet: the step runs again a frame later."""


def centre(widget) -> tuple[float, float]:
    return widget.to_window(*widget.center)


_seen_at: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # widget -> (window rect, flip count)


def why_untouchable(widget) -> str | None:
    """Why a finger on ``widget``'s centre would not reach it now (None: it would).

    The widget must be on the window, under the topmost window child (a ModalView on top
    takes every touch, also while it fades out), in the current screen, inside the window
    and every enclosing ScrollView, and laid out: the same non-empty window rectangle in
    two different drawn frames (a rebuilt screen's widgets move when the layout runs).
    """
    from kivy.uix.modalview import ModalView
    from kivy.uix.screenmanager import Screen
    from kivy.uix.scrollview import ScrollView

    if widget.get_root_window() is not Window:
        return f"{type(widget).__name__} is not on the window"
    top, node = widget, widget
    while node.parent is not None and node.parent is not Window:
        node = node.parent
        if isinstance(node, Screen) and node.manager is not None and node.manager.current != node.name:
            return f"screen {node.name!r} is not the current one ({node.manager.current!r})"
        if isinstance(node, ScrollView) and not node.collide_point(*node.to_parent(*node.to_widget(*centre(widget)))):
            return "its centre is scrolled out of view"
        top = node
    if Window.children and Window.children[0] is not top:
        return f"a {type(Window.children[0]).__name__} is on top of it"
    if isinstance(top, ModalView) and (top._anim_alpha < 1 or not top._is_open):
        return "its ModalView is still opening or closing"
    x, y = widget.to_window(*widget.pos)
    rect = (round(x, 1), round(y, 1), round(widget.width, 1), round(widget.height, 1))
    cx, cy = centre(widget)
    if widget.width < 1 or widget.height < 1 or not (0 <= cx < Window.width and 0 <= cy < Window.height):
        return f"not laid out inside the window yet ({rect})"
    flips = app_ref[0]._flips
    seen = _seen_at.get(widget)
    if seen is None or seen[0] != rect:
        _seen_at[widget] = (rect, flips)
        return "its layout may still change"
    if seen[1] == flips:
        return "no frame drawn since it was first seen there"
    return None


def ensure_touchable(widget) -> None:
    why = why_untouchable(widget)
    if why is not None:
        raise NotReady(why)


def tap(widget) -> None:
    ensure_touchable(widget)
    x, y = centre(widget)
    touch = UnitTestTouch(x, y)
    touch.touch_down()
    touch.touch_up()


class TimedTouch(UnitTestTouch):
    """A test touch whose move times are set by the test (a real finger takes time;
    the simulated one would draw the whole stroke within a millisecond)."""

    fake_time = 0.0

    def move(self, args):
        super().move(args)
        self.time_update = self.fake_time


def stroke(points_px: list[tuple[float, float]], on, dt: float = 0.05) -> None:
    """A finger stroke through window pixels on the widget ``on``, time stamps ``dt`` apart.
    Compute ``points_px`` in the same step (they depend on the widget's layout)."""
    ensure_touchable(on)
    t0 = time.time()
    touch = TimedTouch(*points_px[0])
    touch.time_start = touch.time_update = touch.fake_time = t0
    touch.touch_down()
    for i, (x, y) in enumerate(points_px[1:], start=1):
        touch.fake_time = t0 + i * dt
        touch.touch_move(x, y)
    touch.touch_up()


def drag(widget, dy: float, steps: int = 8) -> None:
    ensure_touchable(widget)
    x, y = centre(widget)
    stroke([(x, y + dy * i / steps) for i in range(steps + 1)], on=widget)


class TouchStep:
    """A step that touches the app and then waits for the effect on the model.

    ``effect`` is called just before the first touch and returns the test of success
    (so it can remember the state before). Touch handling in Kivy is synchronous, so a
    touch whose effect is still missing once a few frames are drawn had none: only then is
    it repeated, at most ``retries`` times.
    """

    def __init__(self, act: Callable[[], object], effect: Callable[[], Callable[[], bool]], retries: int = 2):
        self.act, self.effect, self.retries = act, effect, retries


def touching(act: Callable[[], object], until: Callable[[], bool] | None = None,
             changes: Callable[[], object] | None = None, retries: int = 2) -> TouchStep:
    """A :class:`TouchStep` whose effect is ``until()`` becoming true, or the value of
    ``changes()`` differing from its value before the touch."""
    if (until is None) == (changes is None):
        raise ValueError("give exactly one of until= and changes=")
    if until is not None:
        return TouchStep(act, lambda: until, retries)

    def arm():
        before = changes()
        return lambda: changes() != before
    return TouchStep(act, arm, retries)


def table_px(table, mx: float, my: float) -> tuple[float, float]:
    return table.to_window(*table.to_px(mx, my))


def shot(name: str) -> str:
    Window.dispatch("on_draw")  # draw into the back buffer now: after a flip its contents are undefined
    path = Window.screenshot(name=str(OUT / f"{name}.png"))
    final = OUT / f"{name}.png"
    os.replace(path, final)
    return str(final)


def editor(app):
    return app.sm.get_screen("editor")


# --------------------------------------------------------------------------- scenarios
def open_new_story(app):
    """Touch steps from the home screen to a new story in the editor: *New story*, then
    the first arc ("short", 3 scenes)."""
    home = app.sm.get_screen("home")
    yield touching(lambda: tap(home.new_tile), until=lambda: getattr(home, "arc_view", None) in Window.children)
    yield touching(lambda: tap(home.arc_view.children[0].children[0].children[-1]),  # "short" arc (3 scenes)
                   until=lambda: app.editor is not None and app.sm.current == "editor")


def touch_story_steps(app):
    """Three scenes made by touch alone, then wait to be killed. Each touch waits for its
    effect on the story (see :class:`TouchStep`)."""
    yield from open_new_story(app)
    story = lambda: app.editor.story  # noqa: E731
    for k in range(3):
        def pick_scene(k=k):
            thumbs = list(reversed(editor(app).strip.children))
            tap(thumbs[k])
        yield touching(pick_scene, until=lambda k=k: app.current_scene_id == story().scenes[k].id)
        kind = ["robot", "animal", "child"][k]
        yield touching(lambda kind=kind: tap(editor(app).character_buttons[kind]),
                       until=lambda k=k, kind=kind: [c.kind for c in story().scenes[k].characters] == [kind])

        def sketch(k=k):
            table = editor(app).table
            stroke([table_px(table, 0.1 + 0.1 * i, 0.2 + 0.1 * k) for i in range(9)], on=table)
        yield touching(sketch, until=lambda k=k: len(story().scenes[k].characters[0].path) >= 2)
        motion = ["walk", "jump", "dance"][k]
        yield touching(lambda motion=motion: tap(editor(app).motion_buttons[motion]),
                       until=lambda k=k, motion=motion: story().scenes[k].characters[0].motion.motion_class == motion)

    def report():
        story = app.editor.story
        result["story_id"] = story.id
        result["scenes"] = [[(c.kind, len(c.path), c.motion.motion_class) for c in s.characters] for s in story.scenes]
        (OUT / "result.json").write_text(json.dumps(result))
        print("READY", flush=True)
    yield report
    yield "hang"


def editor_steps(app):
    """Sketch, hop arc, scene drag-reorder, undo, motion choice, similar clips, play."""

    chosen = lambda: app.editor.story.scene(app.current_scene_id).character(app.selected_character_id)  # noqa: E731

    def sketch():
        table = editor(app).table
        result["selected"] = app.selected_character_id
        stroke([table_px(table, 0.2 + 0.08 * i, 0.3) for i in range(10)], on=table)
    yield touching(sketch, changes=lambda: chosen().path)

    def after_sketch():
        c = app.editor.story.scenes[0].character(result["selected"])
        result["path"] = c.path
        result["marks_after_sketch"] = [m.kind for m in c.marks]
    yield after_sketch

    def hop():
        table = editor(app).table
        stroke([table_px(table, 0.4 + 0.02 * i, 0.3 + 0.1 * (1 - abs(i - 5) / 5)) for i in range(11)], on=table)
    yield touching(hop, changes=lambda: [m.kind for m in chosen().marks])
    yield lambda: result.update(marks_after_hop=[m.kind for m in app.editor.story.scenes[0].character(result["selected"]).marks])

    def spin_sketch():  # a path with a small loop in the middle
        table = editor(app).table
        pts = [(0.2 + 0.02 * i, 0.5) for i in range(11)]  # right to x = 0.4
        pts += [(0.4, 0.53), (0.4, 0.56), (0.37, 0.56), (0.35, 0.56), (0.35, 0.53), (0.35, 0.47)]  # loop back across
        pts += [(0.35 + 0.03 * i, 0.45) for i in range(1, 12)]
        stroke([table_px(table, x, y) for x, y in pts], on=table)
    yield touching(spin_sketch, changes=lambda: [m.kind for m in chosen().marks])
    yield lambda: result.update(marks_after_spin=[m.kind for m in app.editor.story.scenes[0].character(result["selected"]).marks])

    yield lambda: result.update(order_before=[s.id for s in app.editor.story.scenes])
    order = lambda: [s.id for s in app.editor.story.scenes]  # noqa: E731
    yield touching(lambda: drag(list(reversed(editor(app).strip.children))[0], -260), changes=order)
    yield lambda: result.update(order_after_drag=[s.id for s in app.editor.story.scenes])
    yield touching(lambda: tap(editor(app).undo_button), changes=order)
    yield lambda: result.update(order_after_undo=[s.id for s in app.editor.story.scenes])
    yield touching(lambda: tap(editor(app).redo_button), changes=order)
    yield lambda: result.update(order_after_redo=[s.id for s in app.editor.story.scenes])
    yield touching(lambda: tap(list(reversed(editor(app).strip.children))[0]),  # select the (moved) first scene
                   until=lambda: app.current_scene_id == app.editor.story.scenes[0].id)
    yield touching(lambda: tap(editor(app).motion_buttons["kick"]), until=lambda: chosen().motion.motion_class == "kick")


    def motion():
        scene = app.editor.story.scene(app.current_scene_id)
        c = scene.character(app.selected_character_id)
        result["motion"] = c.motion.motion_class
    yield motion

    def remove_and_undo():
        scene = app.editor.story.scene(app.current_scene_id)
        result["cast_before_remove"] = len(scene.characters)
    yield remove_and_undo
    cast = lambda: len(app.editor.story.scene(app.current_scene_id).characters)  # noqa: E731
    yield touching(lambda: tap(editor(app).remove_button), changes=cast)
    yield lambda: result.update(cast_after_remove=len(app.editor.story.scene(app.current_scene_id).characters))
    yield touching(lambda: tap(editor(app).undo_button), changes=cast)
    yield lambda: result.update(cast_after_undo=len(app.editor.story.scene(app.current_scene_id).characters))
    yield lambda: result.update(similar_for=editor(app).selected_character().motion.motion_class)
    yield lambda: editor(app).more_like_this()
    yield lambda: result.update(similar=[b.text.split()[-1] for b in editor(app).clip_view.children[0].children[1].children[0].children])
    yield lambda: shot("more_like_this")
    yield lambda: editor(app).clip_view.dismiss()
    yield lambda: shot("editor_after")
    yield touching(lambda: tap(editor(app).play_button), until=lambda: app.sm.current == "play")

    def on_play():
        result["screen_after_play"] = app.sm.current
        play = app.sm.get_screen("play")
        play.scrubber.value = 1.5
    yield on_play
    yield lambda: result.update(play_time=app.sm.get_screen("play").table.time,
                                play_scene=app.sm.get_screen("play").table.scene.id,
                                story_scenes=[s.id for s in app.editor.story.scenes])
    yield lambda: shot("play")
    yield lambda: app.go("projector")
    yield lambda: shot("projector")
    yield finish


def button_sizes(root) -> list[tuple[float, float]]:
    from app.ui.widgets import IconButton
    return [(w.width, w.height) for w in root.walk() if isinstance(w, IconButton)]


def language_steps(app):
    yield lambda: shot(f"editor_{app.lang}")
    yield lambda: result.update(editor_buttons=button_sizes(editor(app)))
    hint = editor(app).hint
    yield lambda: result.update(hint_box=[*hint.to_window(*hint.pos), *hint.size], hint_text=hint.text)
    yield lambda: app.go("home")
    yield lambda: shot(f"home_{app.lang}")
    yield lambda: result.update(home_buttons=button_sizes(app.sm.get_screen("home")))
    yield touching(lambda: tap(app.sm.get_screen("home").language_button), changes=lambda: app.lang)
    yield lambda: result.update(lang_after_tap=app.lang, lang_saved=app.store.get_setting("language"),
                                title_after_tap=app.sm.get_screen("home").title_label.text)
    yield lambda: setattr(app, "editor", None)
    yield touching(lambda: tap(app.sm.get_screen("home").tiles[0]), until=lambda: app.editor is not None)
    yield lambda: result.update(after_tile=app.sm.current, opened=app.editor.story.id if app.editor else None)
    yield finish


def teacher_steps(app):
    yield lambda: result.update(teacher_button=[*centre(app.sm.get_screen("home").teacher_button), app.sm.current])
    yield touching(lambda: tap(app.sm.get_screen("home").teacher_button), until=lambda: app.sm.current == "pin")
    yield lambda: result.update(after_tap=app.sm.current)
    pin = lambda: app.sm.get_screen("pin")  # noqa: E731
    yield from type_on_pad(app, grown_up_answer(pin().question_label.text))  # the grown-up question first
    yield from type_on_pad(app, "2468")
    yield from type_on_pad(app, "2468")  # typed twice
    yield touching(lambda: tap(pin().done_button), until=lambda: app.sm.current == "teacher")  # recovery code noted
    yield lambda: result.update(after_first_pin=app.sm.current, pin_set=app.store.has_pin())
    yield lambda: shot("teacher")
    yield touching(lambda: tap(app.sm.get_screen("teacher").calibration_button),
                   until=lambda: app.sm.current == "calibration")
    calib = lambda: app.sm.get_screen("calibration")  # noqa: E731
    state = {"taps": 0, "polls": 0}

    def run_wizard():
        wizard = calib().wizard
        if wizard.done or state["polls"] > 600:
            return None
        state["polls"] += 1
        if not getattr(calib(), "_busy", False):
            if any(st.error for st in wizard.steps):
                return None
            tap(calib().next_button)  # first: it raises NotReady while the button cannot be touched
            state["taps"] += 1
        return "again"
    yield run_wizard
    yield lambda: result.update(calibration=[[st.key, st.result, st.error] for st in calib().wizard.steps],
                                calibration_taps=state["taps"])
    yield lambda: app.go("teacher")
    teacher = lambda: app.sm.get_screen("teacher")  # noqa: E731
    yield touching(lambda: tap(teacher().action_buttons["activity_log"]), changes=lambda: app.store.activity_logging)
    yield lambda: tap(teacher().action_buttons["export_packages"])
    yield lambda: tap(teacher().action_buttons["export_video"])

    def wait_video():
        if teacher().export_thread.is_alive() and state["polls"] < 1200:
            state["polls"] += 1
            return "again"
    yield wait_video
    yield lambda: result.update(video_status=teacher().status.text)
    yield lambda: tap(teacher().action_buttons["export_log"])
    yield lambda: result.update(export_dir=str(app.export_dir), log_on=app.store.activity_logging)
    yield touching(lambda: tap(teacher().action_buttons["present_all"]), until=lambda: app.sm.current == "projector")
    yield lambda: result.update(after_present=app.sm.current,
                                presented_scenes=len(app.editor.story.scenes) if app.editor else 0)
    yield lambda: app.go("teacher")
    yield lambda: app.sm.get_screen("teacher").leave()
    yield lambda: app.go("pin")
    for key in "1111":
        yield touching(lambda key=key: tap(pin().keys[key]), changes=lambda: pin().entered)
    yield touching(lambda: tap(pin().keys["ok"]), changes=lambda: pin().message.text)
    yield lambda: result.update(after_wrong_pin=app.sm.current, wrong_message=pin().message.text)
    yield lambda: shot("pin")
    yield finish


def play3d_steps(app):
    yield lambda: app.go("play")
    state = {"waited": 0}

    def wait_for_frame():
        while app.renderer.frames_rendered < 1 or app.sm.get_screen("play").table.frame_texture is None:
            if app.renderer.error or state["waited"] > 600:
                break
            state["waited"] += 1
            return "again"
    yield wait_for_frame
    yield lambda: result.update(frames=app.renderer.frames_rendered, render_error=app.renderer.error,
                                texture=list(app.sm.get_screen("play").table.frame_texture.size)
                                if app.sm.get_screen("play").table.frame_texture else None,
                                table_box=[*app.sm.get_screen("play").table.to_window(*app.sm.get_screen("play").table.pos),
                                           *app.sm.get_screen("play").table.size])
    yield lambda: shot("play3d")
    yield finish


def projector3d_steps(app):
    """The projector screen through the synthetic rig: wait for tracked stage frames, then
    hold still on one frame and shoot it; then the camera view (Preview)."""
    yield lambda: app.go("projector")
    proj = lambda: app.sm.get_screen("projector")  # noqa: E731
    state = {"polls": 0, "seen": 0}

    def wait_frames(n=3, view="projector", t=None):
        frame = proj().last_stage_frame
        ready = proj().frames_shown >= state["seen"] + n and frame is not None and frame.view == view \
            and (t is None or (frame.scene_id == app.editor.story.scenes[0].id and abs(frame.t - t) < 1e-6))
        if not ready and not app.renderer.error and state["polls"] < 900:
            state["polls"] += 1
            return "again"
        state["polls"] = 0
    yield lambda: result.update(stage_available=app.stage_available())
    yield wait_frames

    def hold_still():
        proj().player.pause()
        state["seen"] = proj().frames_shown
        proj().player.seek(1.0)
    yield hold_still
    yield lambda: wait_frames(1, t=1.0)

    def record(name):
        frame = proj().last_stage_frame
        img = proj().stage_image
        import numpy as np
        np.save(OUT / f"{name}.npy", frame.rgb)
        result[name] = {"state": frame.state, "view": frame.view, "character_px": frame.character_px,
                        "live": frame.live, "label": proj().state_label.text, "problems": frame.problems,
                        "image_box": [*img.to_window(*img.pos), *img.size], "norm_size": list(img.norm_image_size),
                        "render_error": app.renderer.error}
        shot(name)
    yield lambda: record("projector3d")

    def to_camera():
        state["seen"] = proj().frames_shown
        tap(proj().preview_button)
    yield to_camera
    yield lambda: wait_frames(1, "camera", t=1.0)
    yield lambda: record("projector_camera")
    yield finish


def thumbs_steps(app):
    """"More like this" with the real library: tiles show animated stick figures."""
    ed = lambda: editor(app)  # noqa: E731
    yield lambda: ed().select_character(app.editor.story.scenes[0].characters[0].id)
    yield lambda: ed().more_like_this()
    state = {"polls": 0}

    def wait_figures():
        if any(t.figure is None for t in ed().clip_tiles) and state["polls"] < 600:
            state["polls"] += 1
            return "again"
    yield wait_figures

    def record():
        tiles = ed().clip_tiles
        result["tiles"] = [{"trial": t.trial, "text": t.text, "figure": t.figure is not None,
                            "points": t.figure.frames.points.round(4).tolist() if t.figure else None,
                            "pose": t.figure.pose if t.figure else None,
                            "box": [*t.to_window(*t.pos), *t.size]} for t in tiles]
    yield record
    yield lambda: shot("more_like_this_thumbs")
    yield lambda: result.update(poses_later=[t.figure.pose if t.figure else None for t in ed().clip_tiles])
    yield finish


def import_steps(app):
    """Teacher's package picker: tap a malformed package (refused), then a valid one."""
    import hashlib
    teacher = lambda: app.sm.get_screen("teacher")  # noqa: E731

    def db_state():
        files = sorted(p for p in DB.parent.iterdir() if p.name.startswith(DB.name) and p.is_file())
        digest = hashlib.sha256(b"".join(p.name.encode() + p.read_bytes() for p in files)).hexdigest()
        return {"stories": sorted(s.id for s in app.store.list_stories()), "digest": digest}

    def unlock():
        app.teacher_unlocked = True
        app.go("teacher")
    yield unlock
    yield lambda: tap(teacher().action_buttons["import_package"])
    picker = lambda: teacher().import_picker  # noqa: E731
    yield lambda: result.update(tiles=sorted(Path(k).name for k in picker().tiles), before=db_state())
    yield lambda: shot("import_picker")
    picked = lambda: (picker().message, getattr(picker(), "ok", None))  # noqa: E731
    yield touching(lambda: tap(next(t for k, t in picker().tiles.items() if Path(k).name == "broken.zip")),
                   changes=picked)
    yield lambda: result.update(after_bad=db_state(), bad_message=picker().message, bad_ok=picker().ok)
    yield touching(lambda: tap(next(t for k, t in picker().tiles.items() if Path(k).name == "good.zip")),
                   changes=picked)
    yield lambda: result.update(after_good=db_state(), good_message=picker().message, good_ok=picker().ok,
                                imported_titles=[s.title for s in app.store.list_stories()])
    yield finish


_WORDS = {"three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8, "nine": 9, "twelve": 12,
          "thirteen": 13, "fourteen": 14, "fifteen": 15, "sixteen": 16, "seventeen": 17, "eighteen": 18,
          "nineteen": 19}


def grown_up_answer(question: str) -> str:
    """What a grown-up types for the English question shown ("seventeen times eight")."""
    a, _times, b = question.split()
    return str(_WORDS[a] * _WORDS[b])


def type_on_pad(app, digits: str, ok: bool = True):
    """Steps that tap ``digits`` on the PIN pad, then OK (waiting for the mode or the
    message to change)."""
    pin = lambda: app.sm.get_screen("pin")  # noqa: E731
    yield touching(lambda: tap(pin().keys["clear"]), until=lambda: pin().entered == "")
    for key in digits:
        yield touching(lambda key=key: tap(pin().keys[key]), changes=lambda: pin().entered)
    if ok:
        yield touching(lambda: tap(pin().keys["ok"]), changes=lambda: (pin().submits, app.sm.current))


def gate_steps(app):
    """A fresh install: taps alone do not set a PIN; the grown-up question, the PIN twice
    (a mismatch first), the recovery code shown once; then wrong PINs slowed down."""
    import random
    pin = lambda: app.sm.get_screen("pin")  # noqa: E731
    home = lambda: app.sm.get_screen("home")  # noqa: E731
    yield touching(lambda: tap(home().teacher_button), until=lambda: app.sm.current == "pin")
    yield lambda: result.update(first_mode=pin().mode, first_question=pin().question_label.text)

    def seeded_questions():  # the child's taps below are then the same every run
        pin().question.rng = random.Random(3)
        pin().question.next()
        pin().refresh()
    yield seeded_questions
    yield lambda: shot("gate")
    # a child's taps: OK at once, then 80 random keys of the pad (seeded)
    yield touching(lambda: tap(pin().keys["ok"]), changes=lambda: pin().submits)
    yield lambda: result.update(after_empty_ok=[pin().mode, pin().note, pin().question_label.text])
    rng = random.Random(7)
    keys = [rng.choice("0123456789" + "o" * 3 + "c") for _ in range(80)]
    for k in keys:
        key = {"o": "ok", "c": "clear"}.get(k, k)
        yield lambda key=key: tap(pin().keys[key])
    yield lambda: result.update(after_random=[pin().mode, app.store.has_pin(), app.sm.current])
    # the grown-up answers from the words on the screen
    yield lambda: result.update(question=pin().question_label.text)
    yield from type_on_pad(app, grown_up_answer(pin().question_label.text))
    yield lambda: result.update(after_answer=pin().mode)
    yield from type_on_pad(app, "2468")
    yield lambda: result.update(after_first=pin().mode)
    yield from type_on_pad(app, "2469")
    yield lambda: result.update(after_mismatch=[pin().mode, pin().note, app.store.has_pin()])
    yield from type_on_pad(app, "2468")
    yield from type_on_pad(app, "2468")
    yield lambda: result.update(code_mode=pin().mode, code_shown=pin().display.text, pin_set=app.store.has_pin(),
                                code_button=[pin().done_button.width, pin().done_button.height])
    yield lambda: shot("recovery_code")
    yield touching(lambda: tap(pin().done_button), until=lambda: app.sm.current == "teacher")
    yield lambda: result.update(after_code=app.sm.current)
    # wrong PINs, on a clock the test moves (no real waiting)
    clock = [1_000_000.0]
    yield lambda: setattr(app.store, "pin_clock", lambda: clock[0])
    yield lambda: app.sm.get_screen("teacher").leave()
    yield touching(lambda: tap(home().teacher_button), until=lambda: app.sm.current == "pin")
    yield lambda: result.update(enter_mode=pin().mode, pad_sizes=[[b.width, b.height] for b in pin().keys.values()])
    notes: list = []
    for _ in range(6):
        yield from type_on_pad(app, "1111")
        yield lambda: notes.append([pin().note, app.sm.current])
    yield lambda: result.update(wrong_notes=notes)
    yield from type_on_pad(app, "2468")  # the right PIN, during the wait
    yield lambda: result.update(right_during_wait=[pin().note, app.sm.current])
    yield lambda: clock.__setitem__(0, clock[0] + 31)
    yield from type_on_pad(app, "2468")
    yield lambda: result.update(right_after_wait=app.sm.current)
    yield finish


def recover_steps(app):
    """A forgotten PIN: "Forgot PIN?", a wrong code, the code, a new PIN twice, the next code."""
    pin = lambda: app.sm.get_screen("pin")  # noqa: E731
    setup = json.loads((OUT / "setup.json").read_text())
    yield touching(lambda: tap(app.sm.get_screen("home").teacher_button), until=lambda: app.sm.current == "pin")
    yield touching(lambda: tap(pin().forgot_button), until=lambda: pin().mode == "recover")
    yield lambda: result.update(recover_title=pin().title_label.text)
    wrong = "9" * 12 if setup["code"] != "9" * 12 else "8" * 12
    yield from type_on_pad(app, wrong)
    yield lambda: result.update(after_wrong_code=[pin().mode, pin().note])
    yield from type_on_pad(app, setup["code"])
    yield lambda: result.update(after_code=pin().mode)
    yield from type_on_pad(app, "9753")
    yield from type_on_pad(app, "9753")
    yield lambda: result.update(new_code=pin().display.text.replace(" ", ""), code_mode=pin().mode)
    yield touching(lambda: tap(pin().done_button), until=lambda: app.sm.current == "teacher")
    yield lambda: result.update(after_reset=app.sm.current)
    yield finish


def legacy_pin_steps(app):
    """A PIN set before recovery codes existed: the right PIN first shows a new code once."""
    pin = lambda: app.sm.get_screen("pin")  # noqa: E731
    yield touching(lambda: tap(app.sm.get_screen("home").teacher_button), until=lambda: app.sm.current == "pin")
    yield from type_on_pad(app, "1357")
    yield lambda: result.update(legacy_mode=pin().mode, legacy_code=pin().display.text.replace(" ", ""))
    yield touching(lambda: tap(pin().done_button), until=lambda: app.sm.current == "teacher")
    yield lambda: result.update(after_legacy=app.sm.current)
    yield finish


def finish():
    (OUT / "result.json").write_text(json.dumps(result))
    app_ref[0].stop()


SCENARIOS = {"touch_story": touch_story_steps, "editor": editor_steps, "language": language_steps,
             "teacher": teacher_steps, "play3d": play3d_steps, "projector3d": projector3d_steps,
             "thumbs": thumbs_steps, "import": import_steps, "teacher_gate": gate_steps,
             "teacher_recover": recover_steps, "teacher_legacy": legacy_pin_steps}
from narration_scenarios import SCENARIOS as NARRATION_SCENARIOS  # noqa: E402  (issue 14: voice, own file)

SCENARIOS.update(NARRATION_SCENARIOS)
from tablet_scenarios import RENDERED as TABLET_RENDERED  # noqa: E402  (issue 13: the tablet profile, own file)
from tablet_scenarios import SCENARIOS as TABLET_SCENARIOS  # noqa: E402

SCENARIOS.update(TABLET_SCENARIOS)
from act_scenarios import RENDERED as ACT_RENDERED  # noqa: E402  (issue 18: Act it out, own file)
from act_scenarios import SCENARIOS as ACT_SCENARIOS  # noqa: E402

SCENARIOS.update(ACT_SCENARIOS)
app_ref: list = []


class DriverApp(StoryBeamApp):
    def on_start(self):
        if SCENARIO == "teacher" and self.video_exporter is not None:
            # the real 3-D export (child process, camera view) at 2 frames per second: the
            # UI wiring is what this scenario checks; tests/test_app_integration.py checks the video
            from app.scene.video_export import app_exporter
            self.video_exporter = app_exporter("camera", fps=2.0)
        self._steps = iter(SCENARIOS[SCENARIO](self))
        self._flips = 0
        Window.bind(on_flip=self._count_flip)
        Clock.schedule_once(self._first, 0.1)

    def _count_flip(self, *_):
        self._flips += 1

    def _first(self, _dt):
        """Start only after two drawn frames: before that the layout may not have run."""
        if self._flips < 2:
            Clock.schedule_once(self._first, 0.05)
            return
        Clock.schedule_once(self._next, 0.1)

    def _next(self, _dt):
        if self._flips < getattr(self, "_wait_for_flips", 0):
            Clock.schedule_once(self._next, 0.02)  # the last step's new widgets are not laid out yet
            return
        if getattr(self, "_current", None) is None:
            try:
                step = next(self._steps)
            except StopIteration:
                return
            if step == "hang":
                return  # wait to be killed
            self._current = step
            self._step_deadline = time.monotonic() + STEP_DEADLINE_S  # for a TouchStep's effect
            self._touch = None  # TouchStep progress: check, tries, flips at the last touch
            self._not_ready_since = None
        step = self._current
        try:
            status = self._run_touch_step(step) if isinstance(step, TouchStep) else step()
        except NotReady as exc:
            now = time.monotonic()
            self._not_ready_since = self._not_ready_since or now
            if now - self._not_ready_since > STEP_DEADLINE_S:
                self._fail(f"its target stayed untouchable for {STEP_DEADLINE_S:.0f} s: {exc}")
                return
            status = "again"
            Window.canvas.ask_update()  # frames must come: touchable means laid out in two frames
        except Exception:  # record and stop: the test reports which step failed
            import traceback
            self._fail(traceback.format_exc())
            return
        else:
            self._not_ready_since = None
            if isinstance(step, TouchStep) and status == "again" and time.monotonic() > self._step_deadline:
                self._fail(f"no effect of the touch after {STEP_DEADLINE_S:.0f} s")
                return
        if status == "again":  # the step waits for something: run it again shortly
            Clock.schedule_once(self._next, 0.05)
            return
        self._current = None
        result["steps"].append("ok")
        self._wait_for_flips = self._flips + 2
        Window.canvas.ask_update()  # make sure frames are drawn even if the step changed nothing
        Clock.schedule_once(lambda dt: Window.canvas.ask_update(), 0.01)
        Clock.schedule_once(self._next, 0.02)

    def _run_touch_step(self, step: TouchStep) -> str | None:
        """Touch (when the target is touchable), then wait for the effect; touch again
        only when the last touch is over, frames were drawn, and nothing happened."""
        Window.canvas.ask_update()  # keep frames coming while the step waits
        state = self._touch
        if state is None:
            state = self._touch = {"check": step.effect(), "tries": 0, "flips": None}
        elif state["flips"] is not None:  # touched: wait for the effect
            if state["check"]():
                return None
            if self._flips < state["flips"] + 3:
                return "again"
            if state["tries"] > step.retries:
                raise AssertionError(f"the touch had no effect, {state['tries']} times")
            result.setdefault("retries", []).append(f"step {len(result['steps'])}: no effect, touched again")
            state["flips"] = None
        step.act()  # raises NotReady until the target is touchable
        state["tries"] += 1
        state["flips"] = self._flips
        return None if state["check"]() else "again"

    def _fail(self, why: str) -> None:
        result["error"] = f"step {len(result['steps'])}: {why}"
        (OUT / "result.json").write_text(json.dumps(result))
        self.stop()


if __name__ == "__main__":
    lang = os.environ.get("STORYBEAM_TEST_LANG", "en")
    demo = SCENARIO in ("editor", "language", "play3d", "projector3d", "thumbs")
    if SCENARIO == "teacher":  # one saved story for the exports (made outside the UI)
        from app.story.demo_story import demo_story
        from app.story.storage import ProfileStore
        with ProfileStore(DB) as store:
            store.save_story(demo_story())
    if SCENARIO == "teacher_legacy":  # a PIN set by an app from before recovery codes
        import sqlite3

        from app.story.storage import ProfileStore
        with ProfileStore(DB) as store:
            store.set_pin("1357")
        with sqlite3.connect(DB) as conn:
            conn.execute("DELETE FROM settings WHERE key = 'teacher_recovery'")
        conn.close()
    if SCENARIO == "teacher_recover":  # a PIN set before (its recovery code kept) and one story
        from app.story.demo_story import demo_story
        from app.story.storage import ProfileStore
        with ProfileStore(DB) as store:
            store.save_story(demo_story())
            code = store.set_pin("1357")
            (OUT / "setup.json").write_text(json.dumps({"code": code, "story": demo_story().to_dict()}))
    if SCENARIO == "import":  # a valid package and a malformed one in the inbox (made outside the UI)
        import zipfile

        from app.story.demo_story import demo_story
        from app.story.storage import ProfileStore
        inbox = DB.with_name(DB.name + ".inbox")
        inbox.mkdir(parents=True, exist_ok=True)
        with ProfileStore(DB.parent / "other" / "source.db") as store:
            story = demo_story()
            story.title = "Imported by tap"
            store.save_story(story)
            store.export_package(story.id, inbox / "good.zip")
        with zipfile.ZipFile(inbox / "broken.zip", "w") as zf:
            zf.writestr("manifest.json", "{not json")
            zf.writestr("story.json", "{}")
    factory = None
    if SCENARIO in ("play3d", "projector3d", *TABLET_RENDERED, *ACT_RENDERED):
        from app.scene import app_renderer_factory
        factory = app_renderer_factory(DB.parent)
    catalog = MotionCatalog(Path(os.environ["STORYBEAM_TEST_MOTIONS"]), build_index=False) \
        if os.environ.get("STORYBEAM_TEST_MOTIONS") else MotionCatalog(build_index=SCENARIO in TABLET_RENDERED)
    app = DriverApp(DB, lang=lang, demo=demo, catalog=catalog, renderer_factory=factory)
    app_ref.append(app)
    app.run()
