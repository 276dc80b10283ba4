"""The teacher gate: a grown-up question before the first PIN, the PIN typed twice, wrong
PINs slowed down (persisted), a recovery code that resets a forgotten PIN and keeps every
story. The store is tested on an injected clock (no real waiting); the screens by touch,
offscreen, through tests/support/ui_driver.py like tests/app/test_ui.py."""
from __future__ import annotations

import json
import sqlite3

import pytest

from app.story import storage
from app.story.demo_story import demo_story
from app.story.storage import (
    PIN_FIRST_DELAY_S,
    PIN_FREE_ATTEMPTS,
    PIN_MAX_DELAY_S,
    RECOVERY_CODE_DIGITS,
    ProfileStore,
    StorageError,
    pin_delay_after,
)
from tests.app.test_ui import _drive
from lab.stress.gate import read_number


@pytest.fixture(autouse=True)
def fast_hash(monkeypatch):
    monkeypatch.setattr(storage.teacher, "PIN_ITERATIONS", 1000)


class Clock:
    def __init__(self, t: float = 1_700_000_000.0):
        self.t = t

    def __call__(self) -> float:
        return self.t


def _store(path, clock: Clock) -> ProfileStore:
    store = ProfileStore(path)
    store.pin_clock = clock
    return store


def _reference_delay(failures: int) -> float:
    """The schedule written out independently: 4 free, then 30 s doubling every 5, ≤ 15 min."""
    if failures < 5:
        return 0.0
    return min(30.0 * 2 ** ((failures - 5) // 5), 900.0)


def test_delay_schedule_matches_its_statement():
    assert [pin_delay_after(f) for f in range(0, 60)] == [_reference_delay(f) for f in range(0, 60)]
    assert pin_delay_after(PIN_FREE_ATTEMPTS) == 0 and pin_delay_after(PIN_FREE_ATTEMPTS + 1) == PIN_FIRST_DELAY_S
    assert pin_delay_after(10_000) == PIN_MAX_DELAY_S  # no overflow, capped


def test_twenty_wrong_pins_in_a_row_take_minutes_and_the_wait_survives_reopening(tmp_path):
    clock = Clock()
    start = clock.t
    store = _store(tmp_path / "p.db", clock)
    store.set_pin("2468")
    refused = 0
    for attempt in range(1, 21):
        while store.pin_wait() > 0:  # a child keeps tapping: refused, not even checked, not counted
            check = store.try_pin("2468")  # even the right PIN is refused during a wait
            assert check.refused and not check.ok
            refused += 1
            clock.t += store.pin_wait()
            if attempt % 3 == 0:  # closing and reopening the app does not reset the wait
                store.close()
                store = _store(tmp_path / "p.db", clock)
        check = store.try_pin("1111")
        assert not check.ok and not check.refused and check.failures == attempt
        assert check.wait_s == _reference_delay(attempt)
    assert clock.t - start == sum(_reference_delay(f) for f in range(1, 20)) == 1050.0  # 17.5 minutes
    assert refused == 15  # after failures 5..19
    clock.t += store.pin_wait()
    assert store.try_pin("2468").ok  # the right PIN after the wait, and the count starts over
    assert store.try_pin("1111").failures == 1 and store.pin_wait() == 0
    store.close()


def test_a_clock_put_back_cannot_lock_the_teacher_out(tmp_path):
    clock = Clock()
    with _store(tmp_path / "p.db", clock) as store:
        store.set_pin("2468")
        for _ in range(5):
            store.try_pin("0000")
        assert store.pin_wait() == PIN_FIRST_DELAY_S
        clock.t -= 86_400  # the tablet's clock goes back a day
        assert store.pin_wait() == PIN_FIRST_DELAY_S  # never more than the wait that was set


def test_a_damaged_attempts_record_still_slows_down(tmp_path):
    clock = Clock()
    with _store(tmp_path / "p.db", clock) as store:
        store.set_pin("2468")
        store.set_setting("teacher_pin_attempts", "{not json")
        assert store.pin_wait() == PIN_FIRST_DELAY_S
        assert store.try_pin("2468").refused


def test_recovery_code_resets_a_forgotten_pin_and_keeps_every_story(tmp_path):
    clock = Clock()
    with _store(tmp_path / "p.db", clock) as store:
        story = demo_story()
        store.save_story(story)
        store.put_asset(story.id, "bg.png", b"\x89PNG picture")
        sid = store.create_session("2年1組")
        code = store.set_pin("2468")
        assert len(code) == RECOVERY_CODE_DIGITS and code.isdecimal()
        assert code not in json.dumps([store.get_setting("teacher_pin"), store.get_setting("teacher_recovery")])
        for _ in range(8):  # a child locked the PIN pad: recovery still works at once
            store.try_pin("0000")
        assert store.pin_wait() > 0 and store.recovery_wait() == 0
        with pytest.raises(StorageError, match="^recovery code: wrong code$"):
            store.reset_pin("1" * RECOVERY_CODE_DIGITS, "9753")
        with pytest.raises(StorageError, match="teacher PIN: must be 4 to 8 digits"):
            store.reset_pin(code, "97")
        spaced = " ".join(code[i:i + 4] for i in range(0, len(code), 4))  # as the screen shows it
        new_code = store.reset_pin(spaced, "9753")
        assert new_code != code
        assert store.verify_pin("9753") and not store.verify_pin("2468")
        assert store.pin_wait() == 0  # the reset clears the wait
        assert not store.try_recovery_code(code).ok  # a code works once
        assert store.try_recovery_code(new_code).ok
        assert store.load_story(story.id).to_dict() == story.to_dict()
        assert store.read_asset(story.id, "bg.png") == b"\x89PNG picture"
        assert store.list_sessions() == [(sid, "2年1組")]


def test_wrong_recovery_codes_are_slowed_down_too(tmp_path):
    clock = Clock()
    with _store(tmp_path / "p.db", clock) as store:
        code = store.set_pin("2468")
        for _ in range(5):
            assert not store.try_recovery_code("123").ok  # malformed codes count as wrong
        with pytest.raises(StorageError, match=r"^recovery code: wrong code; try again in 30 s$"):
            store.reset_pin(code, "9753")
        clock.t += 30
        store.reset_pin(code, "9753")
        assert store.verify_pin("9753")


def test_a_pin_from_before_recovery_codes_gets_one(tmp_path):
    with ProfileStore(tmp_path / "p.db") as store:
        with pytest.raises(StorageError) as err:
            store.new_recovery_code()
        assert str(err.value) == f"{tmp_path / 'p.db'}: no teacher PIN to make a recovery code for"
        store.set_pin("2468")
    with sqlite3.connect(tmp_path / "p.db") as conn:  # as an app from before recovery codes left it
        conn.execute("DELETE FROM settings WHERE key = 'teacher_recovery'")
    conn.close()
    with ProfileStore(tmp_path / "p.db") as store:
        assert store.has_pin() and not store.has_recovery_code()
        code = store.new_recovery_code()
        assert store.has_recovery_code() and store.verify_pin("2468")
        assert store.reset_pin(code, "1357") and store.verify_pin("1357")


def test_damaged_or_foreign_pin_records_say_so(tmp_path):
    with ProfileStore(tmp_path / "p.db") as store:
        db = str(tmp_path / "p.db")
        with pytest.raises(StorageError, match="no recovery code was set with this PIN"):
            store.try_recovery_code("1" * 12)
        store.set_pin("2468")
        cases = {
            "bcrypt$12$aa$bb": "unknown scheme 'bcrypt'",
            "pbkdf2_sha256$1000$zz$00": "non-hexadecimal",
            "pbkdf2_sha256$0$00$00": "0 iterations",
            "only-one-field": "1 fields instead of 4",
        }
        for record, problem in cases.items():
            store.set_setting("teacher_pin", record)
            with pytest.raises(StorageError) as err:
                store.try_pin("2468")
            message = str(err.value)
            assert message.startswith(f"{db}: the teacher PIN record is damaged (")
            assert problem in message and message.endswith("reset the PIN with the recovery code")
        assert not store.verify_pin("12")  # not a PIN at all: no hash is even computed


# ------------------------------------------------------------------ by touch, offscreen
@pytest.mark.slow  # starts the app in a child process
def test_fresh_install_gate_taps_alone_cannot_claim_teacher_mode(tmp_path):
    r, out = _drive(tmp_path, "teacher_gate")
    assert r["first_mode"] == "gate" and len(str(read_number(r["first_question"], "en"))) == 6  # a number in words
    mode, note, question = r["after_empty_ok"]
    assert mode == "gate" and note == "Not quite. Please ask a grown-up.\nLocked. Try again in 0:30"
    assert question != r["first_question"]  # a new number after the wrong answer
    assert r["after_random"] == ["gate", False, "pin"]  # 80 random taps: still the question, no PIN
    assert r["gate_failures"] == 1  # every OK among them came during the lock: refused, not even checked
    assert r["after_answer"] == "new1" and r["after_first"] == "new2"
    mode, note, has_pin = r["after_mismatch"]
    assert (mode, note, has_pin) == ("new1", "The two PINs were different. Choose again.", False)
    code = r["code_shown"].replace(" ", "")
    assert r["code_mode"] == "code" and r["pin_set"] and len(code) == 12 and code.isdecimal()
    assert min(r["code_button"]) >= 48 and min(min(s) for s in r["pad_sizes"]) >= 48  # big touch targets
    assert r["after_code"] == "teacher" and r["enter_mode"] == "enter"
    notes = r["wrong_notes"]
    assert [n[1] for n in notes] == ["pin"] * 6
    assert [n[0] for n in notes[:4]] == ["Wrong PIN"] * 4
    assert notes[4][0] == "Wrong PIN\nToo many wrong tries. Try again in 0:30"
    assert notes[5][0] == "Too many wrong tries. Try again in 0:30"  # refused, unchecked
    assert r["right_during_wait"] == ["Too many wrong tries. Try again in 0:30", "pin"]
    assert r["right_after_wait"] == "teacher"
    with ProfileStore(tmp_path / "p.db") as store:
        assert store.verify_pin("2468")
        assert store.try_recovery_code(code).ok  # the code shown is the one that works


@pytest.mark.slow  # starts the app in a child process
def test_forgotten_pin_reset_by_touch_keeps_the_stories(tmp_path):
    r, out = _drive(tmp_path, "teacher_recover")
    setup = json.loads((out / "setup.json").read_text())
    assert r["recover_title"] == "Type the 12-digit recovery code"
    assert r["after_wrong_code"] == ["recover", "Wrong recovery code"]
    assert r["after_code"] == "new1" and r["code_mode"] == "code" and r["after_reset"] == "teacher"
    with ProfileStore(tmp_path / "p.db") as store:
        assert store.verify_pin("9753") and not store.verify_pin("1357")
        assert store.load_story(setup["story"]["id"]).to_dict() == setup["story"]
        assert [s.id for s in store.list_stories()] == [setup["story"]["id"]]
        assert r["new_code"] != setup["code"] and store.try_recovery_code(r["new_code"]).ok


@pytest.mark.slow  # starts the app in a child process
def test_a_pin_from_before_recovery_codes_shows_a_new_code_once_by_touch(tmp_path):
    r, _out = _drive(tmp_path, "teacher_legacy")
    assert r["legacy_mode"] == "code" and len(r["legacy_code"]) == 12 and r["after_legacy"] == "teacher"
    with ProfileStore(tmp_path / "p.db") as store:
        assert store.try_recovery_code(r["legacy_code"]).ok and store.verify_pin("1357")
