"""Random-touch monkey test of the real app under offscreen Kivy.

:func:`run_monkey` starts ``python -m lab.stress.monkey DB OUT SECONDS SEED`` (one Kivy app
per process: Kivy keeps global window state) and reads its ``result.json``. Inside, the
real :class:`app.ui.app.StoryBeamApp` runs with a scheduled "monkey" that, every few
frames, taps a random button of the current screen or open popup (60 %), taps a random
point (15 %), draws a random finger stroke (20 %) or presses Back/Escape (5 %).

Checked:

* **crashes**: an exception escaping a touch handler or a scheduled callback (the
  monkey wraps each action; Kivy's ExceptionManager catches the rest and counts them);
* **stuck states**: the main loop stops ticking for 10 s (a watchdog thread), a popup
  stays open for over 20 s, or a screen other than home offers no button at all;
* **lost stories**: every ``save_story``/``delete_story`` (and ``rename_story``,
  ``empty_bin``) the app makes is recorded; at the end the profile is reopened and every
  story must equal its last save (on the home screen or in the bin), and deleted ones
  must be gone.

With ``teacher=True`` the monkey works **behind the teacher PIN**: the profile has a PIN,
and the monkey gets in the way a teacher does, by tapping the PIN on the real pad (again
whenever its taps have left teacher mode), so it spends its time on the teacher screens
(sessions, calibration, exports, import picker, present all) and on the PIN screen's
other modes. The PIN delays run on a clock that jumps an hour before each of the
teacher's unlocks (the monkey's own wrong taps would otherwise lock the pad), and videos
are exported in 2-D (the 3-D child process is tested elsewhere). ``unlocks`` counts the
PIN entries that reached the teacher screen; ``teacher_actions`` the actions taken there.
"""
from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from pathlib import Path

from tqdm import tqdm

from app.paths import REPO_ROOT
from app.services.catalog import MotionCatalog
from app.story.storage import ProfileStore, StorageError
from app.ui.env import prepare_kivy_env

#: Seconds between monkey actions (a busy child taps a few times a second).
ACTION_INTERVAL_S = 0.08


def _run_with_bar(cmd: list[str], env: dict, seconds: float, timeout: float, progress: bool) -> tuple[int, str]:
    """Run the app process; with ``progress`` show a bar of the monkey's seconds."""
    with tempfile.TemporaryFile("w+") as log:
        proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT, text=True,
                                cwd=str(REPO_ROOT))
        bar = None
        if progress:
            bar = tqdm(total=int(seconds), desc="monkey touches", unit="s")
        start = time.monotonic()
        try:
            while proc.poll() is None:
                if time.monotonic() - start > timeout:
                    proc.kill()
                    proc.wait()
                    raise subprocess.TimeoutExpired(cmd, timeout)
                time.sleep(1.0)
                if bar is not None:
                    bar.n = min(int(seconds), int(time.monotonic() - start))
                    bar.refresh()
        finally:
            if bar is not None:
                bar.close()
        log.seek(0)
        return proc.returncode, log.read()[-2000:]


def run_monkey(work: Path, seconds: float = 60.0, seed: int = 0, timeout_margin_s: float = 120.0,
               progress: bool = False, teacher: bool = False) -> dict:
    """Run the monkey for ``seconds`` in a subprocess (``teacher``: behind the teacher PIN);
    returns its summary."""
    work.mkdir(parents=True, exist_ok=True)
    db = work / "monkey.db"
    out = work / "out"
    for suffix in ("", "-wal", "-shm"):
        Path(f"{db}{suffix}").unlink(missing_ok=True)
    env = dict(os.environ, KIVY_NO_ARGS="1", SDL_VIDEODRIVER="offscreen",
               KIVY_HOME=str(work / "kivy_home"))
    cmd = [sys.executable, "-m", "lab.stress.monkey", str(db), str(out), str(seconds), str(seed),
           "teacher" if teacher else "child"]
    try:
        rc, tail = _run_with_bar(cmd, env, seconds, seconds + timeout_margin_s, progress)
    except subprocess.TimeoutExpired:
        rc, tail = None, "the app did not finish (killed after the time limit)"
    result_file = out / "result.json"
    if not result_file.is_file():
        return {"crashes": 1, "hangs": int(rc is None), "stuck": 0, "stories_lost": 0, "actions": 0,
                "failures": 1, "error": f"no result (exit {rc}): {tail}"}
    result = json.loads(result_file.read_text())
    result["exit_code"] = rc
    if rc not in (0, None) and not result.get("crashes"):
        result["crashes"] = 1
        result.setdefault("crash_examples", []).append(f"app exited {rc}: {tail[-800:]}")
    result["failures"] = result.get("crashes", 0) + result.get("stuck", 0) + result.get("stories_lost", 0) \
        + result.get("hangs", 0)
    return result


# ============================================================================ inside the app process


#: The PIN the monkey's "teacher" types.
TEACHER_PIN = "2468"


def _main(db: Path, out: Path, seconds: float, seed: int,
          teacher: bool = False) -> int:  # pragma: no cover - runs in a subprocess
    prepare_kivy_env(headless=True, width=1280, height=800)
    # deferred: Kivy reads its environment at import, so every Kivy import (and the app,
    # which imports Kivy) comes after prepare_kivy_env(); each line below says so.
    from kivy.base import ExceptionHandler, ExceptionManager  # deferred: after prepare_kivy_env()
    from kivy.clock import Clock  # deferred: after prepare_kivy_env()
    from kivy.core.window import Window  # deferred: after prepare_kivy_env() (opens the window)
    from kivy.tests.common import UnitTestTouch  # deferred: after prepare_kivy_env()
    from kivy.uix.behaviors import ButtonBehavior  # deferred: after prepare_kivy_env()
    from kivy.uix.modalview import ModalView  # deferred: after prepare_kivy_env()

    from app.ui.app import StoryBeamApp  # deferred: imports Kivy, so after prepare_kivy_env()

    out.mkdir(parents=True, exist_ok=True)
    rng = random.Random(seed)
    report: dict = {"seconds": seconds, "seed": seed, "actions": 0, "taps": 0, "strokes": 0, "backs": 0,
                    "crashes": 0, "crash_examples": [], "stuck": 0, "stuck_examples": [], "hangs": 0,
                    "screens_seen": {}, "saves": 0, "deletes": 0, "stories_lost": 0, "popups_seen": 0,
                    "teacher": teacher, "unlocks": 0, "unlock_tries": 0, "teacher_actions": 0, "long_presses": 0}
    saved: dict[str, dict | None] = {}  # last saved body per story id (None: deleted)
    heartbeat = [time.monotonic()]
    finished = threading.Event()

    def write_report() -> None:
        (out / "result.json").write_text(json.dumps(report, indent=1, default=str))

    def watchdog() -> None:
        while not finished.wait(1.0):
            if time.monotonic() - heartbeat[0] > 10.0:
                report["hangs"] += 1
                report["stuck_examples"].append("main loop did not tick for 10 s")
                write_report()
                os._exit(3)

    class CountingHandler(ExceptionHandler):
        def handle_exception(self, exc):
            report["crashes"] += 1
            if len(report["crash_examples"]) < 10:
                report["crash_examples"].append("".join(traceback.format_exception(exc))[-1500:])
            return ExceptionManager.PASS

    ExceptionManager.add_handler(CountingHandler())

    def buttons(root) -> list:
        found, stack = [], [root]
        while stack:
            w = stack.pop()
            if isinstance(w, ButtonBehavior) and not getattr(w, "disabled", False) and w.get_root_window() is not None:
                found.append(w)
            stack.extend(w.children)
        return found

    def tap_at(x: float, y: float) -> None:
        touch = UnitTestTouch(x, y)
        touch.touch_down()
        touch.touch_up()

    def stroke() -> None:
        w, h = Window.size
        x, y = rng.uniform(0, w), rng.uniform(0, h)
        touch = UnitTestTouch(x, y)
        touch.touch_down()
        for _ in range(rng.randrange(3, 25)):
            x = min(max(0, x + rng.uniform(-60, 60)), w)
            y = min(max(0, y + rng.uniform(-60, 60)), h)
            touch.touch_move(x, y)
        touch.touch_up()

    pin_clock = [time.time()]  # teacher mode: jumps an hour before each unlock

    class MonkeyApp(StoryBeamApp):
        def build(self):
            if teacher:
                self.video_view = "2d"  # teacher exports: the 2-D video (no 3-D child process)
            root = super().build()
            if teacher:
                self.store.pin_clock = lambda: pin_clock[0]
            real_save, real_delete = self.store.save_story, self.store.delete_story

            def save_story(story):
                real_save(story)  # raises on failure: then nothing was saved
                saved[story.id] = story.to_dict()
                report["saves"] += 1

            def delete_story(story_id):
                real_delete(story_id)
                saved[story_id] = None
                report["deletes"] += 1

            real_rename, real_empty = self.store.rename_story, self.store.empty_bin

            def rename_story(story_id, title=None, cover=None):  # a rename is a save of the whole story
                story = real_rename(story_id, title, cover)
                saved[story.id] = story.to_dict()
                report["saves"] += 1
                return story

            def empty_bin():  # the teacher deletes the binned stories for good
                binned = [s.id for s in self.store.binned_stories()]
                n = real_empty()
                for sid in binned:
                    saved[sid] = None
                report["deletes"] += len(binned)
                return n

            self.store.save_story, self.store.delete_story = save_story, delete_story
            self.store.rename_story, self.store.empty_bin = rename_story, empty_bin
            return root

        def on_start(self):
            self._t0 = time.monotonic()
            self._modal_since: dict[int, float] = {}
            self._plan: list = []  # the teacher's taps in progress (one per action)
            if teacher:
                self._plan_unlock()
            Clock.schedule_interval(self._tick, 0)
            Clock.schedule_once(self._act, 0.5)

        def _plan_unlock(self) -> None:
            """The teacher comes back: home, the teacher button, the PIN on the pad, OK."""
            def tap_widget(get):
                def act():
                    w = get()
                    if w is not None and w.get_root_window() is not None:
                        tap_at(*w.to_window(*w.center))
                return act

            def go_home():
                pin_clock[0] += 3600.0
                report["unlock_tries"] += 1
                self.go_home()
            pin = lambda: self.sm.get_screen("pin")  # noqa: E731
            key = lambda k: tap_widget(lambda: getattr(pin(), "keys", {}).get(k))  # noqa: E731
            self._plan = [go_home, tap_widget(lambda: getattr(self.sm.get_screen("home"), "teacher_button", None)),
                          key("clear"), *(key(k) for k in TEACHER_PIN), key("ok"), self._count_unlock]

        def _long_press(self) -> None:
            """A finger held down a little longer than the projector screen's long press."""
            w, h = Window.size
            touch = UnitTestTouch(rng.uniform(0, w), rng.uniform(0, h))
            touch.touch_down()
            hold = getattr(self.sm.current_screen, "LONG_PRESS_S", 1.0) + 0.3
            Clock.schedule_once(lambda _dt: touch.touch_up(), hold)
            report["long_presses"] += 1

        def _count_unlock(self) -> None:
            report["unlocks"] += self.sm.current == "teacher"

        def _tick(self, _dt):
            heartbeat[0] = time.monotonic()

        def _popups(self) -> list:
            return [w for w in Window.children if isinstance(w, ModalView)]

        def _check_stuck(self) -> None:
            now = time.monotonic()
            popups = self._popups()
            alive = {id(p) for p in popups}
            for p in popups:
                if id(p) not in self._modal_since:
                    self._modal_since[id(p)] = now
                    report["popups_seen"] += 1
                elif now - self._modal_since[id(p)] > 20.0:
                    report["stuck"] += 1
                    report["stuck_examples"].append(f"a popup stayed open 20 s on {self.sm.current}")
                    p.dismiss()
            self._modal_since = {k: v for k, v in self._modal_since.items() if k in alive}
            full_screen = getattr(self.sm.current_screen, "projector_mode", False)  # no buttons by design
            if self.sm.current != "home" and not popups and not full_screen and not buttons(self.sm.current_screen):
                report["stuck"] += 1
                report["stuck_examples"].append(f"screen {self.sm.current} has no button")
                self.go_home()

        def _act(self, _dt):
            if time.monotonic() - self._t0 > seconds:
                self.stop()
                return
            screen = self.sm.current
            report["screens_seen"][screen] = report["screens_seen"].get(screen, 0) + 1
            try:
                self._check_stuck()
                if teacher and not self._plan and not self._popups() and (
                        screen == "home" or (screen in ("editor", "play", "projector", "pin")
                                             and rng.random() < 0.1)):
                    self._plan_unlock()  # the monkey left teacher mode: the teacher types the PIN again
                if self._plan:
                    self._plan.pop(0)()
                    report["actions"] += 1
                    Clock.schedule_once(self._act, ACTION_INTERVAL_S)
                    return
                if screen in ("teacher", "calibration"):
                    report["teacher_actions"] += 1
                if getattr(self.sm.current_screen, "projector_mode", False) and rng.random() < 0.2:
                    self._long_press()  # the projector's full screen has no button: a held finger leaves it
                    report["actions"] += 1
                    Clock.schedule_once(self._act, ACTION_INTERVAL_S)
                    return
                r = rng.random()
                popups = self._popups()
                if r < 0.60:
                    pool = buttons(popups[-1]) if popups else buttons(self.sm.current_screen)
                    if pool:
                        b = rng.choice(pool)
                        x, y = b.to_window(*b.center)
                        tap_at(x + rng.uniform(-3, 3), y + rng.uniform(-3, 3))
                        report["taps"] += 1
                elif r < 0.75:
                    w, h = Window.size
                    tap_at(rng.uniform(0, w), rng.uniform(0, h))
                    report["taps"] += 1
                elif r < 0.95:
                    stroke()
                    report["strokes"] += 1
                else:
                    Window.dispatch("on_keyboard", 27, 0, None, [])
                    report["backs"] += 1
            except Exception as exc:  # noqa: BLE001 - a crash of the app under a touch
                report["crashes"] += 1
                if len(report["crash_examples"]) < 10:
                    report["crash_examples"].append(f"on {screen}: " + "".join(traceback.format_exception(exc))[-1500:])
            report["actions"] += 1
            Clock.schedule_once(self._act, ACTION_INTERVAL_S)

    threading.Thread(target=watchdog, daemon=True).start()
    if teacher:  # a profile whose teacher PIN was set before
        with ProfileStore(db) as store:
            store.set_pin(TEACHER_PIN)
    # Start in the editor of the demo story (as a teacher's demo would), so even a short run
    # edits and autosaves; the monkey reaches home and every other screen from there.
    app = MonkeyApp(db, lang=rng.choice(["en", "ja"]), demo=True, catalog=MotionCatalog(build_index=False))
    try:
        app.run()
    except Exception as exc:  # noqa: BLE001
        report["crashes"] += 1
        report["crash_examples"].append("app.run: " + "".join(traceback.format_exception(exc))[-1500:])
    finally:
        finished.set()
    # The app may have moved to a rescue profile if the first was refused; check the one it used.
    used_db = Path(getattr(app, "db_path", db))
    try:
        with ProfileStore(used_db) as store:
            # a story in the bin is not lost: it is there until the teacher empties the bin
            present = {s.id for s in store.list_stories()} | {s.id for s in store.binned_stories()}
            for sid, body in saved.items():
                if body is None:
                    report["stories_lost"] += sid in present  # a deleted story came back
                elif sid not in present or store.load_story(sid).to_dict() != body:
                    report["stories_lost"] += 1
            report["stories_in_profile"] = len(present)
    except StorageError as exc:
        report["stories_lost"] += sum(1 for b in saved.values() if b is not None)
        report["crash_examples"].append(f"profile does not reopen: {exc}")
    report["stories_saved"] = sum(1 for b in saved.values() if b is not None)
    write_report()
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(_main(Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]),
                   len(sys.argv) > 5 and sys.argv[5] == "teacher"))
