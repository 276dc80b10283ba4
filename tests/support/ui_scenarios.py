"""The app's own touch scenarios for tests/support/ui_driver.py: stories made by touch, the
editor, languages, teacher mode, 3-D play and the projector view, thumbnails, package
import, the grown-up gate and the PIN's recovery.

Each ``*_steps(app)`` yields the steps the driver runs one by one (a callable, returning
``"again"`` while it waits, or a :class:`~ui_touch.TouchStep`). The driver runs as
``__main__``; the run's state (``result``, ``shot``, ``finish``, ``OUT``, ``DB``) is taken
from there, as in the other scenario files.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from kivy.core.window import Window
from ui_touch import centre, drag, stroke, table_px, tap, touching

from app.story import GrownUpQuestion

drv = sys.modules["__main__"]


def editor(app):
    return app.sm.get_screen("editor")


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
        drv.result["story_id"] = story.id
        drv.result["scenes"] = [[(c.kind, len(c.path), c.motion.motion_class) for c in s.characters] for s in story.scenes]
        (drv.OUT / "result.json").write_text(json.dumps(drv.result))
        print("READY", flush=True)
    yield report
    yield "hang"


def editor_steps(app):
    """Sketch, hop arc, scene drag-reorder, undo, motion choice, similar clips, play."""

    chosen = lambda: app.editor.story.scene(app.current_scene_id).character(app.selected_character_id)  # noqa: E731

    def sketch():
        table = editor(app).table
        drv.result["selected"] = app.selected_character_id
        stroke([table_px(table, 0.2 + 0.08 * i, 0.3) for i in range(10)], on=table)
    yield touching(sketch, changes=lambda: chosen().path)

    def after_sketch():
        c = app.editor.story.scenes[0].character(drv.result["selected"])
        drv.result["path"] = c.path
        drv.result["marks_after_sketch"] = [m.kind for m in c.marks]
    yield after_sketch

    def hop():
        table = editor(app).table
        stroke([table_px(table, 0.4 + 0.02 * i, 0.3 + 0.1 * (1 - abs(i - 5) / 5)) for i in range(11)], on=table)
    yield touching(hop, changes=lambda: [m.kind for m in chosen().marks])
    yield lambda: drv.result.update(marks_after_hop=[m.kind for m in app.editor.story.scenes[0].character(drv.result["selected"]).marks])

    def spin_sketch():  # a path with a small loop in the middle
        table = editor(app).table
        pts = [(0.2 + 0.02 * i, 0.5) for i in range(11)]  # right to x = 0.4
        pts += [(0.4, 0.53), (0.4, 0.56), (0.37, 0.56), (0.35, 0.56), (0.35, 0.53), (0.35, 0.47)]  # loop back across
        pts += [(0.35 + 0.03 * i, 0.45) for i in range(1, 12)]
        stroke([table_px(table, x, y) for x, y in pts], on=table)
    yield touching(spin_sketch, changes=lambda: [m.kind for m in chosen().marks])
    yield lambda: drv.result.update(marks_after_spin=[m.kind for m in app.editor.story.scenes[0].character(drv.result["selected"]).marks])

    yield lambda: drv.result.update(order_before=[s.id for s in app.editor.story.scenes])
    order = lambda: [s.id for s in app.editor.story.scenes]  # noqa: E731
    yield touching(lambda: drag(list(reversed(editor(app).strip.children))[0], -260), changes=order)
    yield lambda: drv.result.update(order_after_drag=[s.id for s in app.editor.story.scenes])
    yield touching(lambda: tap(editor(app).undo_button), changes=order)
    yield lambda: drv.result.update(order_after_undo=[s.id for s in app.editor.story.scenes])
    yield touching(lambda: tap(editor(app).redo_button), changes=order)
    yield lambda: drv.result.update(order_after_redo=[s.id for s in app.editor.story.scenes])
    yield touching(lambda: tap(list(reversed(editor(app).strip.children))[0]),  # select the (moved) first scene
                   until=lambda: app.current_scene_id == app.editor.story.scenes[0].id)
    yield touching(lambda: tap(editor(app).motion_buttons["kick"]), until=lambda: chosen().motion.motion_class == "kick")


    def motion():
        scene = app.editor.story.scene(app.current_scene_id)
        c = scene.character(app.selected_character_id)
        drv.result["motion"] = c.motion.motion_class
    yield motion

    def remove_and_undo():
        scene = app.editor.story.scene(app.current_scene_id)
        drv.result["cast_before_remove"] = len(scene.characters)
    yield remove_and_undo
    cast = lambda: len(app.editor.story.scene(app.current_scene_id).characters)  # noqa: E731
    yield touching(lambda: tap(editor(app).remove_button), changes=cast)
    yield lambda: drv.result.update(cast_after_remove=len(app.editor.story.scene(app.current_scene_id).characters))
    yield touching(lambda: tap(editor(app).undo_button), changes=cast)
    yield lambda: drv.result.update(cast_after_undo=len(app.editor.story.scene(app.current_scene_id).characters))
    yield lambda: drv.result.update(similar_for=editor(app).selected_character().motion.motion_class)
    yield lambda: editor(app).more_like_this()
    yield lambda: drv.result.update(similar=[b.trial for b in editor(app).clip_view.children[0].children[1].children[0].children],
                                    similar_texts=[b.text for b in editor(app).clip_view.children[0].children[1].children[0].children])
    yield lambda: drv.shot("more_like_this")
    yield lambda: editor(app).clip_view.dismiss()
    yield lambda: drv.shot("editor_after")
    yield touching(lambda: tap(editor(app).play_button), until=lambda: app.sm.current == "play")

    def on_play():
        drv.result["screen_after_play"] = app.sm.current
        play = app.sm.get_screen("play")
        play.scrubber.value = 1.5
    yield on_play
    yield lambda: drv.result.update(play_time=app.sm.get_screen("play").table.time,
                                play_scene=app.sm.get_screen("play").table.scene.id,
                                story_scenes=[s.id for s in app.editor.story.scenes])
    yield lambda: drv.shot("play")
    yield lambda: app.go("projector")
    yield lambda: drv.shot("projector")
    yield drv.finish


def button_sizes(root) -> list[tuple[float, float]]:
    from app.ui.widgets import IconButton
    return [(w.width, w.height) for w in root.walk() if isinstance(w, IconButton)]


def language_steps(app):
    yield lambda: drv.shot(f"editor_{app.lang}")
    yield lambda: drv.result.update(editor_buttons=button_sizes(editor(app)))
    hint = editor(app).hint
    yield lambda: drv.result.update(hint_box=[*hint.to_window(*hint.pos), *hint.size], hint_text=hint.text)
    yield lambda: app.go("home")
    yield lambda: drv.shot(f"home_{app.lang}")
    yield lambda: drv.result.update(home_buttons=button_sizes(app.sm.get_screen("home")))
    yield touching(lambda: tap(app.sm.get_screen("home").language_button), changes=lambda: app.lang)
    yield lambda: drv.result.update(lang_after_tap=app.lang, lang_saved=app.store.get_setting("language"),
                                title_after_tap=app.sm.get_screen("home").title_label.text)
    yield lambda: setattr(app, "editor", None)
    yield touching(lambda: tap(app.sm.get_screen("home").tiles[0]), until=lambda: app.editor is not None)
    yield lambda: drv.result.update(after_tile=app.sm.current, opened=app.editor.story.id if app.editor else None)
    yield drv.finish


def teacher_steps(app):
    yield lambda: drv.result.update(teacher_button=[*centre(app.sm.get_screen("home").teacher_button), app.sm.current])
    yield touching(lambda: tap(app.sm.get_screen("home").teacher_button), until=lambda: app.sm.current == "pin")
    yield lambda: drv.result.update(after_tap=app.sm.current)
    pin = lambda: app.sm.get_screen("pin")  # noqa: E731
    yield from type_on_pad(app, grown_up_answer(pin().question_label.text))  # the grown-up question first
    yield from type_on_pad(app, "2468")
    yield from type_on_pad(app, "2468")  # typed twice
    yield touching(lambda: tap(pin().done_button), until=lambda: app.sm.current == "teacher")  # recovery code noted
    yield lambda: drv.result.update(after_first_pin=app.sm.current, pin_set=app.store.has_pin())
    yield lambda: drv.shot("teacher")
    yield touching(lambda: tap(app.sm.get_screen("teacher").calibration_button),
                   until=lambda: app.sm.current == "calibration")
    calib = lambda: app.sm.get_screen("calibration")  # noqa: E731
    state = {"taps": 0, "polls": 0}

    def run_wizard():
        wizard = calib().wizard
        if wizard.done or state["polls"] > 2000:  # the table scan renders 42 synthetic frames
            return None
        state["polls"] += 1
        if not getattr(calib(), "_busy", False):
            if any(st.error for st in wizard.steps):
                return None
            tap(calib().next_button)  # first: it raises NotReady while the button cannot be touched
            state["taps"] += 1
        return "again"
    yield run_wizard
    yield lambda: drv.result.update(calibration=[[st.key, st.result, st.error] for st in calib().wizard.steps],
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
    yield lambda: drv.result.update(video_status=teacher().status.text)
    yield lambda: tap(teacher().action_buttons["export_log"])
    yield lambda: drv.result.update(export_dir=str(app.export_dir), log_on=app.store.activity_logging)
    yield touching(lambda: tap(teacher().action_buttons["present_all"]), until=lambda: app.sm.current == "projector")
    yield lambda: drv.result.update(after_present=app.sm.current,
                                presented_scenes=len(app.editor.story.scenes) if app.editor else 0)
    yield lambda: app.go("teacher")
    yield lambda: app.sm.get_screen("teacher").leave()
    yield lambda: app.go("pin")
    for key in "1111":
        yield touching(lambda key=key: tap(pin().keys[key]), changes=lambda: pin().entered)
    yield touching(lambda: tap(pin().keys["ok"]), changes=lambda: pin().message.text)
    yield lambda: drv.result.update(after_wrong_pin=app.sm.current, wrong_message=pin().message.text)
    yield lambda: drv.shot("pin")
    yield drv.finish


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
    yield lambda: drv.result.update(frames=app.renderer.frames_rendered, render_error=app.renderer.error,
                                texture=list(app.sm.get_screen("play").table.frame_texture.size)
                                if app.sm.get_screen("play").table.frame_texture else None,
                                table_box=[*app.sm.get_screen("play").table.to_window(*app.sm.get_screen("play").table.pos),
                                           *app.sm.get_screen("play").table.size])
    yield lambda: drv.shot("play3d")
    yield drv.finish


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
    yield lambda: drv.result.update(stage_available=app.stage_available())
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
        np.save(drv.OUT / f"{name}.npy", frame.rgb)
        drv.result[name] = {"state": frame.state, "view": frame.view, "character_px": frame.character_px,
                        "live": frame.live, "label": proj().state_label.text, "problems": frame.problems,
                        "image_box": [*img.to_window(*img.pos), *img.size], "norm_size": list(img.norm_image_size),
                        "render_error": app.renderer.error}
        drv.shot(name)
    yield lambda: record("projector3d")

    def to_camera():
        state["seen"] = proj().frames_shown
        tap(proj().preview_button)
    yield to_camera
    yield lambda: wait_frames(1, "camera", t=1.0)
    yield lambda: record("projector_camera")
    yield drv.finish


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
        drv.result["tiles"] = [{"trial": t.trial, "text": t.text, "figure": t.figure is not None,
                            "points": t.figure.frames.points.round(4).tolist() if t.figure else None,
                            "pose": t.figure.pose if t.figure else None,
                            "box": [*t.to_window(*t.pos), *t.size]} for t in tiles]
    yield record
    yield lambda: drv.shot("more_like_this_thumbs")
    yield lambda: drv.result.update(poses_later=[t.figure.pose if t.figure else None for t in ed().clip_tiles])
    yield drv.finish


def import_steps(app):
    """Teacher's package picker: tap a malformed package (refused), then a valid one."""
    import hashlib
    teacher = lambda: app.sm.get_screen("teacher")  # noqa: E731

    def db_state():
        files = sorted(p for p in drv.DB.parent.iterdir() if p.name.startswith(drv.DB.name) and p.is_file())
        digest = hashlib.sha256(b"".join(p.name.encode() + p.read_bytes() for p in files)).hexdigest()
        return {"stories": sorted(s.id for s in app.store.list_stories()), "digest": digest}

    def unlock():
        app.teacher_unlocked = True
        app.go("teacher")
    yield unlock
    yield lambda: tap(teacher().action_buttons["import_package"])
    picker = lambda: teacher().import_picker  # noqa: E731
    yield lambda: drv.result.update(tiles=sorted(Path(k).name for k in picker().tiles), before=db_state())
    yield lambda: drv.shot("import_picker")
    picked = lambda: (picker().message, getattr(picker(), "ok", None))  # noqa: E731
    yield touching(lambda: tap(next(t for k, t in picker().tiles.items() if Path(k).name == "broken.zip")),
                   changes=picked)
    yield lambda: drv.result.update(after_bad=db_state(), bad_message=picker().message, bad_ok=picker().ok)
    yield touching(lambda: tap(next(t for k, t in picker().tiles.items() if Path(k).name == "good.zip")),
                   changes=picked)
    yield lambda: drv.result.update(after_good=db_state(), good_message=picker().message, good_ok=picker().ok,
                                imported_titles=[s.title for s in app.store.list_stories()])
    yield drv.finish


def grown_up_answer(question: str) -> str:
    """What a grown-up types for the English number shown in words ("four hundred
    seventy-two thousand, six hundred nineteen" -> "472619"): read by the stress
    harness's own parser, independent of the app's words."""
    from lab.stress.gate import read_number  # deferred: the lab is not in the tablet profile (not in the APK)
    return str(read_number(question, "en"))


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
    yield lambda: drv.result.update(first_mode=pin().mode, first_question=pin().question_label.text)
    clock = [1_000_000.0]  # the gate's monotonic clock, moved by the test (no real waiting)
    yield lambda: setattr(app.store, "pin_clock", lambda: clock[0])

    def seeded_questions():  # the child's taps below are then the same every run
        pin().question = GrownUpQuestion.draw(random.Random(3))
        pin().refresh()
    yield seeded_questions
    yield lambda: drv.shot("gate")
    # a child's taps: OK at once, then 80 random keys of the pad (seeded)
    yield touching(lambda: tap(pin().keys["ok"]), changes=lambda: pin().submits)
    yield lambda: drv.result.update(after_empty_ok=[pin().mode, pin().note, pin().question_label.text])
    rng = random.Random(7)
    keys = [rng.choice("0123456789" + "o" * 3 + "c") for _ in range(80)]
    for k in keys:
        key = {"o": "ok", "c": "clear"}.get(k, k)
        yield lambda key=key: tap(pin().keys[key])
    yield lambda: drv.result.update(after_random=[pin().mode, app.store.has_pin(), app.sm.current],
                                    gate_failures=app.store.try_grownup(pin().question, "").failures)
    yield lambda: clock.__setitem__(0, clock[0] + app.store.grownup_wait() + 1)  # the grown-up comes after the lock
    # the grown-up answers from the words on the screen
    yield lambda: drv.result.update(question=pin().question_label.text)
    yield from type_on_pad(app, grown_up_answer(pin().question_label.text))
    yield lambda: drv.result.update(after_answer=pin().mode)
    yield from type_on_pad(app, "2468")
    yield lambda: drv.result.update(after_first=pin().mode)
    yield from type_on_pad(app, "2469")
    yield lambda: drv.result.update(after_mismatch=[pin().mode, pin().note, app.store.has_pin()])
    yield from type_on_pad(app, "2468")
    yield from type_on_pad(app, "2468")
    yield lambda: drv.result.update(code_mode=pin().mode, code_shown=pin().display.text, pin_set=app.store.has_pin(),
                                code_button=[pin().done_button.width, pin().done_button.height])
    yield lambda: drv.shot("recovery_code")
    yield touching(lambda: tap(pin().done_button), until=lambda: app.sm.current == "teacher")
    yield lambda: drv.result.update(after_code=app.sm.current)
    # wrong PINs, on the clock the test moves (no real waiting)
    yield lambda: app.sm.get_screen("teacher").leave()
    yield touching(lambda: tap(home().teacher_button), until=lambda: app.sm.current == "pin")
    yield lambda: drv.result.update(enter_mode=pin().mode, pad_sizes=[[b.width, b.height] for b in pin().keys.values()])
    notes: list = []
    for _ in range(6):
        yield from type_on_pad(app, "1111")
        yield lambda: notes.append([pin().note, app.sm.current])
    yield lambda: drv.result.update(wrong_notes=notes)
    yield from type_on_pad(app, "2468")  # the right PIN, during the wait
    yield lambda: drv.result.update(right_during_wait=[pin().note, app.sm.current])
    yield lambda: clock.__setitem__(0, clock[0] + 31)
    yield from type_on_pad(app, "2468")
    yield lambda: drv.result.update(right_after_wait=app.sm.current)
    yield drv.finish


def recover_steps(app):
    """A forgotten PIN: "Forgot PIN?", a wrong code, the code, a new PIN twice, the next code."""
    pin = lambda: app.sm.get_screen("pin")  # noqa: E731
    setup = json.loads((drv.OUT / "setup.json").read_text())
    yield touching(lambda: tap(app.sm.get_screen("home").teacher_button), until=lambda: app.sm.current == "pin")
    yield touching(lambda: tap(pin().forgot_button), until=lambda: pin().mode == "recover")
    yield lambda: drv.result.update(recover_title=pin().title_label.text)
    wrong = "9" * 12 if setup["code"] != "9" * 12 else "8" * 12
    yield from type_on_pad(app, wrong)
    yield lambda: drv.result.update(after_wrong_code=[pin().mode, pin().note])
    yield from type_on_pad(app, setup["code"])
    yield lambda: drv.result.update(after_code=pin().mode)
    yield from type_on_pad(app, "9753")
    yield from type_on_pad(app, "9753")
    yield lambda: drv.result.update(new_code=pin().display.text.replace(" ", ""), code_mode=pin().mode)
    yield touching(lambda: tap(pin().done_button), until=lambda: app.sm.current == "teacher")
    yield lambda: drv.result.update(after_reset=app.sm.current)
    yield drv.finish


def legacy_pin_steps(app):
    """A PIN set before recovery codes existed: the right PIN first shows a new code once."""
    pin = lambda: app.sm.get_screen("pin")  # noqa: E731
    yield touching(lambda: tap(app.sm.get_screen("home").teacher_button), until=lambda: app.sm.current == "pin")
    yield from type_on_pad(app, "1357")
    yield lambda: drv.result.update(legacy_mode=pin().mode, legacy_code=pin().display.text.replace(" ", ""))
    yield touching(lambda: tap(pin().done_button), until=lambda: app.sm.current == "teacher")
    yield lambda: drv.result.update(after_legacy=app.sm.current)
    yield drv.finish
