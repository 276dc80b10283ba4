"""Teacher-gate scenarios for tests/support/ui_driver.py (issue 29), in their own file.

Every way into teacher mode without the PIN is tried by touch or by setting the screen
directly: a start screen, a screen name set on the screen manager, Back from the
projector after *Present all*, Back from anywhere, the app sent to the background; and a
damaged profile, which must show what happened and put back the last good copy. The
driver runs as ``__main__``; its helpers (``tap``, ``touching``, ``result``, ``finish``,
``shot``) are taken from there.
"""
from __future__ import annotations

import sys
from pathlib import Path

from ui_scenarios import type_on_pad
from ui_touch import tap, touching

from app.story.demo_story import demo_story
from app.story.storage import ProfileStore

drv = sys.modules["__main__"]
PIN = "2468"


def _profile_with_pin(db: Path, _out: Path) -> None:
    with ProfileStore(db) as store:
        store.save_story(demo_story())
        store.set_pin(PIN)


def _damaged_profile(db: Path, out: Path) -> None:
    """A profile with the demo story and a PIN (its good copy written on closing), then
    damaged: garbage over the first page's tables, as a failing card leaves it."""
    if db.exists():  # the second run of the restore test: the damaged file from the first run
        return
    _profile_with_pin(db, out)
    data = bytearray(db.read_bytes())
    data[100:4096] = bytes([0xA5]) * (4096 - 100)
    db.write_bytes(bytes(data))


SETUPS = {"gate_paths": _profile_with_pin, "gate_damaged": _damaged_profile}


def _where(app) -> list:
    """The screen shown, whether teacher mode is unlocked, and whether the teacher screen
    has anything drawn on it."""
    return [app.sm.current, app.teacher_unlocked, len(app.sm.get_screen("teacher").children)]


def _unlock(app):
    home = app.sm.get_screen("home")
    yield lambda: app.go_home()
    yield touching(lambda: tap(home.teacher_button), until=lambda: app.sm.current == "pin")
    yield from type_on_pad(app, PIN)


def _back_button(screen):
    return next(w for w in screen.controls.children if getattr(w, "icon", "") == "home")


def paths_steps(app):
    """Each path into teacher mode, locked and unlocked."""
    r = drv.result
    yield lambda: r.update(start=_where(app))  # the app was started with --screen teacher
    for name in ("teacher", "calibration"):  # a screen name set directly, while locked
        yield lambda name=name: setattr(app.sm, "current", name)
        yield lambda name=name: r.update(**{f"direct_{name}": _where(app)})
    yield lambda: app.go("teacher")
    yield lambda: r.update(go_teacher=_where(app))
    yield from _unlock(app)
    yield lambda: r.update(unlocked=_where(app))
    teacher = lambda: app.sm.get_screen("teacher")  # noqa: E731
    yield touching(lambda: tap(teacher().action_buttons["present_all"]), until=lambda: app.sm.current == "projector")
    yield lambda: r.update(presenting=_where(app))
    projector = lambda: app.sm.get_screen("projector")  # noqa: E731
    yield touching(lambda: tap(_back_button(projector())), until=lambda: app.sm.current != "projector")
    yield lambda: r.update(present_back=_where(app), present_back_mode=app.sm.get_screen("pin").mode)
    yield lambda: r.update(pad={k: [*b.to_window(*b.center), b.width, b.height]
                                for k, b in app.sm.get_screen("pin").keys.items()})  # the grown-up model's pad
    yield from type_on_pad(app, PIN)
    yield lambda: r.update(after_pin=_where(app))
    yield touching(lambda: tap(teacher().calibration_button), until=lambda: app.sm.current == "calibration")
    yield lambda: app.go("teacher")  # the calibration screen's Back: still teacher mode
    yield lambda: r.update(calibration_back=_where(app))
    yield lambda: app.go("editor")  # any other screen locks (the editor: no story open, home)
    yield lambda: setattr(app.sm, "current", "teacher")
    yield lambda: r.update(after_leaving=_where(app))
    yield from _unlock(app)
    yield lambda: (app.on_pause(), app.on_resume())  # Android: home button, then back to the app
    yield lambda: r.update(after_pause=_where(app))
    yield from _unlock(app)
    yield touching(lambda: tap(next(w for w in teacher().walk() if getattr(w, "icon", "") == "home")),
                   until=lambda: app.sm.current == "home")
    yield lambda: app.go("teacher")
    yield lambda: r.update(after_home_button=_where(app))
    yield from _unlock(app)  # teacher mode left alone for 10 minutes locks and goes home
    yield lambda: setattr(app.sm, "last_touch", app.sm.last_touch - 601)
    yield lambda: app._check_idle()
    yield lambda: r.update(after_idle=_where(app))
    # a recovery code shown and left on screen: dropped, and a new one shown after the PIN
    pin = lambda: app.sm.get_screen("pin")  # noqa: E731
    yield lambda: app.store.forget_recovery_code()
    yield from _unlock(app)
    yield lambda: r.update(code_shown=[pin().mode, len(pin().shown_code)])
    yield lambda: setattr(pin(), "last_key_at", pin().last_key_at - 121)
    yield lambda: pin()._tick(0)
    yield lambda: r.update(code_left=[_where(app), pin().mode, app.store.has_recovery_code(), pin().display.text])
    yield from type_on_pad(app, PIN)
    yield lambda: r.update(code_again=[pin().mode, len(pin().shown_code)])
    yield drv.finish


def damaged_steps(app):
    """A damaged profile: the picture and the sentence, the teacher's PIN still asked (not
    the first-run check); then, on a second start, the copy put back."""
    r = drv.result
    screen = lambda: app.sm.get_screen("damaged")  # noqa: E731
    yield lambda: r.update(first=app.sm.current, sentence=screen().sentence.text,
                           restore_offered=screen().restore_button is not None,
                           files=sorted(p.name for p in drv.DB.parent.iterdir()))
    yield lambda: drv.shot(f"damaged_{'restore' if drv.OUT.name.endswith('2') else 'first'}")
    if not drv.OUT.name.endswith("2"):  # first start: Continue, the PIN, a story made meanwhile
        yield touching(lambda: tap(screen().continue_button), until=lambda: app.sm.current == "home")
        yield touching(lambda: tap(app.sm.get_screen("home").teacher_button), until=lambda: app.sm.current == "pin")
        yield lambda: r.update(rescue_mode=app.sm.get_screen("pin").mode, rescue_db=str(app.db_path))
        yield from type_on_pad(app, PIN)
        yield lambda: r.update(rescue_unlocked=app.sm.current)
        yield lambda: app.sm.get_screen("teacher").leave()
        yield lambda: r.update(meanwhile=app.new_story("short").id)
        yield drv.finish
        return
    yield touching(lambda: tap(screen().restore_button), until=lambda: app.sm.current == "home")
    yield lambda: r.update(after_restore=[app.sm.current, str(app.db_path), app.store.has_pin(),
                                          app.store.verify_pin(PIN), sorted(s.id for s in app.store.list_stories())],
                           message=getattr(app, "last_message", ""),
                           files_after=sorted(p.name for p in drv.DB.parent.iterdir()))
    yield drv.finish


SCENARIOS = {"gate_paths": paths_steps, "gate_damaged": damaged_steps}
