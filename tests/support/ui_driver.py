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

The touches are in tests/support/ui_touch.py, the app's scenarios in
tests/support/ui_scenarios.py (and narration, tablet and "Act it out" scenarios in files of
their own); this file holds the run's state (``result``, ``shot``, ``finish``), the step
runner (:class:`DriverApp`) and the setup each scenario needs before the app starts.
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.ui.env import prepare_kivy_env  # noqa: E402

prepare_kivy_env(headless=True, width=1280, height=800)

from kivy.clock import Clock  # noqa: E402
from kivy.core.window import Window  # noqa: E402
from ui_touch import (  # noqa: E402,F401  (the touch helpers: for the scenario files, through __main__)
    NotReady,
    TouchStep,
    centre,
    drag,
    ensure_touchable,
    stroke,
    table_px,
    tap,
    touching,
    why_untouchable,
)

from app.services.catalog import MotionCatalog  # noqa: E402
from app.ui.app import StoryBeamApp  # noqa: E402

SCENARIO, DB, OUT = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
OUT.mkdir(parents=True, exist_ok=True)
result: dict = {"steps": []}


#: The longest a step may wait for its target to become touchable or for its effect.
STEP_DEADLINE_S = 20.0


def shot(name: str) -> str:
    Window.dispatch("on_draw")  # draw into the back buffer now: after a flip its contents are undefined
    path = Window.screenshot(name=str(OUT / f"{name}.png"))
    final = OUT / f"{name}.png"
    os.replace(path, final)
    return str(final)


def finish():
    (OUT / "result.json").write_text(json.dumps(result))
    app_ref[0].stop()


from ui_scenarios import (  # noqa: E402,F401  (editor, open_new_story: for the other scenario files)
    editor,
    editor_steps,
    gate_steps,
    import_steps,
    language_steps,
    legacy_pin_steps,
    open_new_story,
    play3d_steps,
    projector3d_steps,
    recover_steps,
    teacher_steps,
    thumbs_steps,
    touch_story_steps,
)

SCENARIOS = {"touch_story": touch_story_steps, "editor": editor_steps, "language": language_steps,
             "teacher": teacher_steps, "play3d": play3d_steps, "projector3d": projector3d_steps,
             "thumbs": thumbs_steps, "import": import_steps, "teacher_gate": gate_steps,
             "teacher_recover": recover_steps, "teacher_legacy": legacy_pin_steps}
from narration_scenarios import SCENARIOS as NARRATION_SCENARIOS  # noqa: E402  (issue 14: voice, own file)

SCENARIOS.update(NARRATION_SCENARIOS)
from child_scenarios import SCENARIOS as CHILD_SCENARIOS  # noqa: E402  (issue 29: a child who cannot read, own file)

SCENARIOS.update(CHILD_SCENARIOS)
from tablet_scenarios import RENDERED as TABLET_RENDERED  # noqa: E402  (issue 13: the tablet profile, own file)
from tablet_scenarios import SCENARIOS as TABLET_SCENARIOS  # noqa: E402

SCENARIOS.update(TABLET_SCENARIOS)
from act_scenarios import RENDERED as ACT_RENDERED  # noqa: E402  (issue 18: Act it out, own file)
from act_scenarios import SCENARIOS as ACT_SCENARIOS  # noqa: E402

SCENARIOS.update(ACT_SCENARIOS)
from gate_scenarios import SCENARIOS as GATE_SCENARIOS  # noqa: E402  (issue 29: the teacher gate, own file)
from gate_scenarios import SETUPS as GATE_SETUPS  # noqa: E402

SCENARIOS.update(GATE_SCENARIOS)
from story_end_scenarios import SCENARIOS as STORY_END_SCENARIOS  # noqa: E402  (issue 29: the end, own file)

SCENARIOS.update(STORY_END_SCENARIOS)
app_ref: list = []


class RecordingSpeaker:
    """Stands in for the device's speech (app.services.speech): records what was said."""

    name = "test"

    def __init__(self):
        self.said: list[tuple[str, str]] = []

    def say(self, text: str, lang: str) -> None:
        self.said.append((text, lang))


class DriverApp(StoryBeamApp):
    def on_start(self):
        self.speaker = RecordingSpeaker()
        if SCENARIO == "teacher" and self.video_exporter is not None:
            # the real 3-D export (child process, camera view) at 2 frames per second: the
            # UI wiring is what this scenario checks; tests/test_app_integration.py checks the video
            from app.player.video_export import app_exporter
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
            Window.canvas.ask_update()  # a still first screen (the PIN pad) draws no frame by itself
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
    lang = None if lang == "device" else lang  # "device": no language asked for, as on a first launch
    demo = SCENARIO in ("editor", "language", "play3d", "projector3d", "thumbs", "story_end")
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
    if SCENARIO in GATE_SETUPS:
        GATE_SETUPS[SCENARIO](DB, OUT)
    factory = None
    if SCENARIO in ("play3d", "projector3d", *TABLET_RENDERED, *ACT_RENDERED):
        from app.player import app_renderer_factory
        factory = app_renderer_factory(DB.parent)
    catalog = MotionCatalog(Path(os.environ["STORYBEAM_TEST_MOTIONS"]), build_index=False) \
        if os.environ.get("STORYBEAM_TEST_MOTIONS") else MotionCatalog(build_index=SCENARIO in TABLET_RENDERED)
    app = DriverApp(DB, lang=lang, demo=demo, catalog=catalog, renderer_factory=factory,
                    start_screen=os.environ.get("STORYBEAM_TEST_START"))
    app_ref.append(app)
    app.run()