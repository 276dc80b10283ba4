"""The grown-up check and the locks after wrong answers (issue 29): a clock the child
cannot move (monotonic, per boot, persisted), questions whose answers do not repeat, and
the profile's last good copy. On injected clocks: no real waiting."""
from __future__ import annotations

import collections
import random
import time

import pytest

from app.story import storage
from app.story.demo_story import demo_story
from app.story.storage import (
    GROWNUP_MAX,
    GROWNUP_MIN,
    GrownUpQuestion,
    ProfileStore,
    StorageError,
    backup_path,
    backup_settings,
    grownup_lock_after,
    read_backup,
    restore_backup,
)
from app.ui.number_words import english, in_words, japanese
from lab.stress.gate import read_number


@pytest.fixture(autouse=True)
def fast_hash(monkeypatch):
    monkeypatch.setattr(storage.teacher, "PIN_ITERATIONS", 1000)


class Tablet:
    """A monotonic clock and the boot it counts from."""

    def __init__(self):
        self.mono, self.boot = 5000.0, "boot-1"

    def reboot(self, up_for: float = 30.0):
        self.mono, self.boot = up_for, self.boot + "'"


def _open(path, tablet: Tablet) -> ProfileStore:
    store = ProfileStore(path)
    store.pin_clock = lambda: tablet.mono
    store.boot_id = lambda: tablet.boot
    return store


def test_lock_schedule_matches_its_statement():
    stated = {1: 30, 2: 60, 3: 120, 4: 300, 5: 900}  # then 15 minutes for every wrong answer
    assert [grownup_lock_after(f) for f in range(0, 40)] == [0] + [stated.get(f, 900) for f in range(1, 40)]


def test_every_wrong_answer_locks_longer_and_refused_answers_are_not_even_checked(tmp_path):
    tablet = Tablet()
    with _open(tmp_path / "p.db", tablet) as store:
        q = GrownUpQuestion(472619)
        locks = []
        for _ in range(7):
            check = store.try_grownup(q, "123456")
            assert not check.ok and not check.refused
            locks.append(check.wait_s)
            right = store.try_grownup(q, "472619")  # even the right answer, during the lock
            assert right.refused and not right.ok and right.failures == check.failures
            tablet.mono += check.wait_s - 1
            assert store.grownup_wait() == pytest.approx(1.0)
            assert store.try_grownup(q, "472619").refused
            tablet.mono += 1
        assert locks == [30, 60, 120, 300, 900, 900, 900]
        assert store.try_grownup(q, "472619").ok and store.grownup_wait() == 0
        assert store.try_grownup(q, "1").wait_s == 30  # after a pass the count starts over


def test_restarts_and_reboots_never_shorten_a_lock(tmp_path):
    tablet = Tablet()
    store = _open(tmp_path / "p.db", tablet)
    for _ in range(4):
        tablet.mono += store.grownup_wait()
        assert not store.try_grownup(GrownUpQuestion(111111), "2").refused
    assert store.grownup_wait() == 300
    store.close()  # the app closed for 100 s: time passed, the lock counted down
    tablet.mono += 100
    store = _open(tmp_path / "p.db", tablet)
    assert store.grownup_wait() == pytest.approx(200)
    store.close()
    tablet.reboot(up_for=20)  # the tablet restarted: a new boot, the monotonic clock from zero
    store = _open(tmp_path / "p.db", tablet)
    assert store.grownup_wait() == pytest.approx(300)  # nothing counted since the last mark: the full lock
    tablet.mono += 250
    assert store.grownup_wait() == pytest.approx(50)  # counted from the restart on
    tablet.mono -= 1000  # a clock gone back (not possible for a monotonic one, but a damaged mark)
    assert store.grownup_wait() == pytest.approx(300)  # re-anchored: never longer than the lock set
    store.close()


def test_moving_the_wall_clock_changes_nothing(tmp_path, monkeypatch):
    store = ProfileStore(tmp_path / "p.db")  # the real clocks: time.monotonic and the boot id
    assert store.pin_clock is time.monotonic or store.pin_clock() == pytest.approx(time.monotonic(), abs=1)
    store.try_grownup(GrownUpQuestion(999999), "0")
    real_time = time.time
    for shift in (365 * 86400.0, -365 * 86400.0, 10 * 365 * 86400.0):
        monkeypatch.setattr(time, "time", lambda shift=shift: real_time() + shift)
        assert 25 < store.grownup_wait() <= 30
        assert store.try_grownup(GrownUpQuestion(999999), "999999").refused
    store.close()


def test_damaged_or_old_lock_records_still_lock(tmp_path):
    tablet = Tablet()
    with _open(tmp_path / "p.db", tablet) as store:
        store.set_setting("grownup_attempts", "{not json")
        assert store.grownup_wait() == 30
        store.set_pin("2468")
        # a record from before issue 29 (a wall-clock "until"): as locked as its failures say
        store.set_setting("teacher_pin_attempts", '{"failures": 12, "until": 0, "delay": 60}')
        assert store.pin_wait() == 60 and store.try_pin("2468").refused


def test_questions_are_uniform_six_digit_numbers_that_never_repeat_back_to_back():
    rng = random.Random(5)
    q = GrownUpQuestion.draw(rng)
    firsts = collections.Counter()
    for _ in range(90_000):
        nxt = GrownUpQuestion.draw(rng, previous=q)
        assert nxt.number != q.number and GROWNUP_MIN <= nxt.number <= GROWNUP_MAX
        firsts[nxt.number // 100_000] += 1
        q = nxt
    assert sorted(firsts) == list(range(1, 10))
    assert max(firsts.values()) / min(firsts.values()) < 1.1  # no leading digit favoured (10 000 each)
    assert not GrownUpQuestion(472619).check("４７２６１９")  # full-width digits are not the pad's
    assert not GrownUpQuestion(472619).check("") and not GrownUpQuestion(472619).check(" 472619")
    assert GrownUpQuestion(472619).check("472619")


def test_numbers_in_words_read_back_exactly():
    assert english(472619) == "four hundred seventy-two thousand, six hundred nineteen"
    assert english(100000) == "one hundred thousand" and english(910011) == "nine hundred ten thousand, eleven"
    assert japanese(472619) == "四十七万二千六百十九" and japanese(100000) == "十万" and japanese(110001) == "十一万一"
    rng = random.Random(1)
    for n in [GROWNUP_MIN, GROWNUP_MAX] + [rng.randint(GROWNUP_MIN, GROWNUP_MAX) for _ in range(5000)]:
        for lang in ("en", "ja"):
            assert read_number(in_words(n, lang), lang) == n


def test_the_last_good_copy_is_rotated_and_carries_the_pin(tmp_path):
    db = tmp_path / "p.db"
    tablet = Tablet()
    with _open(db, tablet) as store:
        assert read_backup(db).stories == 0 and not read_backup(db).has_pin  # made on opening
        assert not store.back_up()  # nothing changed: the same copy is kept
        store.set_pin("2468")
        info = read_backup(db)
        assert info.has_pin and info.stories == 0  # a PIN change is copied at once
        store.save_story(demo_story())
    assert read_backup(db).stories == 1  # and everything on closing
    assert set(backup_settings(db, ("teacher_pin", "teacher_recovery"))) == {"teacher_pin", "teacher_recovery"}
    backup_path(db).write_bytes(b"SQLite format 3\x00" + b"\x00" * 500)  # a damaged copy is no copy
    assert read_backup(db) is None and backup_settings(db, ("teacher_pin",)) == {}


def test_restoring_keeps_the_damaged_file_and_brings_back_stories_and_pin(tmp_path):
    db = tmp_path / "p.db"
    with ProfileStore(db) as store:
        store.save_story(demo_story())
        store.set_pin("2468")
    data = bytearray(db.read_bytes())
    data[100:4096] = b"\xa5" * (4096 - 100)
    db.write_bytes(bytes(data))
    with pytest.raises(StorageError):
        ProfileStore(db)
    (tmp_path / "p.db-wal").write_bytes(b"a wal of the damaged file")  # goes aside with it
    kept = restore_backup(db)
    assert kept.read_bytes() == bytes(data) and (tmp_path / (kept.name + "-wal")).read_bytes().startswith(b"a wal")
    with ProfileStore(db) as store:
        assert store.verify_pin("2468") and store.has_story(demo_story().id) and store.journal_mode == "wal"


def test_without_a_good_copy_nothing_is_moved(tmp_path):
    db = tmp_path / "p.db"
    db.write_bytes(b"not a database at all")
    with pytest.raises(StorageError, match="no good copy of the profile to put back"):
        restore_backup(db)
    assert db.read_bytes() == b"not a database at all" and sorted(p.name for p in tmp_path.iterdir()) == ["p.db"]


def test_a_child_cannot_lock_the_teacher_out(tmp_path):
    """Wrong PINs and wrong recovery codes are locked apart, and each lock ends: a child at
    the pad can delay the teacher by at most the lock in force, never for good."""
    tablet = Tablet()
    with _open(tmp_path / "p.db", tablet) as store:
        code = store.set_pin("2468")
        for _ in range(60):  # a child at "Forgot PIN?" all morning
            tablet.mono += store.recovery_wait()
            store.try_recovery_code("0" * 12)
        assert store.pin_wait() == 0 and store.try_pin("2468").ok  # the PIN is untouched
        for _ in range(60):  # and at the PIN pad
            tablet.mono += store.pin_wait()
            store.try_pin("0000")
        assert 0 < store.pin_wait() <= 900
        tablet.mono += 900
        assert store.try_pin("2468").ok  # at most 15 minutes later
        tablet.mono += 900
        assert store.reset_pin(code, "1357") and store.verify_pin("1357")


def test_an_unconfirmed_recovery_code_is_dropped_and_the_pin_kept(tmp_path):
    with _open(tmp_path / "p.db", Tablet()) as store:
        code = store.set_pin("2468")
        store.forget_recovery_code()
        assert not store.has_recovery_code() and store.verify_pin("2468")
        with pytest.raises(StorageError, match="no recovery code was set"):
            store.try_recovery_code(code)
        assert store.new_recovery_code() != code and store.has_recovery_code()
