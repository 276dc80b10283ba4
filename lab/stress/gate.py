"""`storybeam stress gate`: scripted children against the real grown-up check, each for a
simulated school day, and simulated grown-ups passing it.

Method. Every child gets a fresh profile (:class:`~app.story.storage.ProfileStore`, a new
install: the check's locks start from the first, shortest one) and the real
:meth:`~app.story.storage.ProfileStore.try_grownup` on a simulated monotonic clock
(:class:`SimClock`: the store's ``pin_clock`` and ``boot_id``), advanced by simulated time,
never slept. The questions are drawn as the PIN screen draws them
(:meth:`~app.story.GrownUpQuestion.draw`: a new one after every checked answer and at every
start of the app). The children (:data:`STRATEGIES`):

* ``random_taps`` -- random keys of the 12-key pad (digits, *clear*, *OK*) at a child's
  tapping pace, without a pause, OK or not, locked or not;
* ``one_answer`` -- one six-digit answer, the same all day;
* ``common_answers`` -- the answers children (and people choosing PINs) type most, in turn
  (:data:`COMMON_ANSWERS`, the issue's ``72`` among them);
* ``seen_answer`` -- the answer the child once saw a grown-up type, again and again;
* ``restarts`` -- a random six-digit answer, the app closed and reopened between tries
  (the store reopened: the lock must survive it);
* ``clock_changes`` -- a random six-digit answer, then the tablet's clock moved (hours to
  a year, either way) and the tablet restarted (a new boot id, the monotonic clock from
  zero) between tries.

Every child but the random tapper watches the countdown and answers the moment the lock
is over (the most tries a persistent child can get); what it types takes
``taps x`` :data:`CHILD_TAP_S`. ``child_attempts`` counts the answers the gate checked,
``child_refused`` the OKs it refused unchecked while locked; ``lock_violations`` counts
answers checked sooner after a wrong one than the lock that was set (must be 0: a
restart, a reboot or a moved clock never shortens a lock).

The grown-up (:func:`grownup_seconds`) is the keystroke-level model of Card, Moran and
Newell with Fitts' law for the taps, on the real question text and the real pad: read the
title and the number in words (:data:`READ_WPM` words a minute, per grown-up a log-normal
spread), one mental preparation (:data:`MENTAL_S`) per three-digit group, then each tap
``FITTS_A + FITTS_B * log2(D / W + 1)`` with ``D`` the distance from the last key on the
pad's 3 x 4 grid and ``W`` the key's width (:data:`KEY_PITCH_OVER_WIDTH`, from the PIN
screen's layout), then OK; each key is mistyped with probability :data:`TYPO_P`, and a
wrong answer costs the lock and a new question, through the real gate. The answer is
read from the words by an independent parser (:func:`read_number`), so the words must
say the number. ``grownup_seconds_median_slow`` repeats it with every time constant
doubled: the target must hold for a slow grown-up too.
"""
from __future__ import annotations

import math
import random
import statistics
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable
from unittest import mock

from app.story import GrownUpQuestion, ProfileStore
from app.story.storage import GROWNUP_MAX, GROWNUP_MIN
from app.ui.number_words import in_words
from app.ui.strings import tr

#: A school day, simulated for each child (6.5 hours).
SCHOOL_DAY_S = 6.5 * 3600
STRATEGIES = ("random_taps", "one_answer", "common_answers", "seen_answer", "restarts", "clock_changes")
#: What children type most: runs, repeats, the pad's patterns, short numbers, the issue's 72.
COMMON_ANSWERS = ("123456", "111111", "000000", "654321", "121212", "112233", "999999", "100000", "123123",
                  "666666", "147258", "123321", "1", "12", "123", "1234", "12345", "7", "72", "0", "10", "100")
#: A child's time per tap on the pad (seconds, uniform between the two).
CHILD_TAP_S = (0.3, 0.7)
#: How long the app takes to close and start again, and the tablet to restart (seconds).
RESTART_S, REBOOT_S = (8.0, 25.0), (40.0, 90.0)
#: The grown-up model (see the module docstring): reading speed (median, log-normal sigma),
#: the mental preparation per digit group, Fitts' law (intercept, slope per bit) and typos.
READ_WPM, READ_SIGMA = 200.0, 0.3
MENTAL_S = 1.35
FITTS_A, FITTS_B = 0.20, 0.15
TYPO_P = 0.01
#: Kanji numerals read per second by a grown-up (Japanese: the number as characters).
KANJI_PER_S = 4.0
#: The pad's key pitch over its key width (the PIN screen: 3 keys across a 330 dp grid, 10 dp
#: apart: 103.3 dp keys, 113.3 dp apart; tests/app/test_gate_paths.py measures it on screen).
KEY_PITCH_OVER_WIDTH = (310.0 / 3 + 10.0) / (310.0 / 3)
PAD = ("123", "456", "789", "c0k")  # c: clear, k: OK


class SimClock:
    """The tablet's clocks for one simulated child: a monotonic clock and its boot id
    (what the gate reads), and a wall clock (what a child can move; the gate never reads it)."""

    def __init__(self, rng: random.Random):
        self.rng = rng
        self.mono = rng.uniform(100.0, 5000.0)
        self.boot = str(uuid.UUID(int=rng.getrandbits(128)))
        self.wall = 1_795_000_000.0

    def advance(self, seconds: float) -> None:
        self.mono += seconds
        self.wall += seconds

    def reboot(self, seconds: float) -> None:
        """The tablet restarted: a new boot id, the monotonic clock from zero."""
        self.boot = str(uuid.UUID(int=self.rng.getrandbits(128)))
        self.mono = seconds
        self.wall += seconds


@dataclass
class ChildTally:
    """What one strategy's children did over their days."""

    children: int = 0
    attempts: int = 0
    refused: int = 0
    passes: int = 0
    restarts: int = 0
    reboots: int = 0
    lock_violations: int = 0
    longest_lock_s: float = 0.0
    attempts_per_day: list = field(default_factory=list)

    def to_dict(self) -> dict:
        days = self.attempts_per_day
        return {"children": self.children, "attempts": self.attempts, "refused": self.refused,
                "passes": self.passes, "restarts": self.restarts, "reboots": self.reboots,
                "lock_violations": self.lock_violations, "longest_lock_s": self.longest_lock_s,
                "attempts_per_day_min": min(days) if days else 0, "attempts_per_day_max": max(days) if days else 0}


def _open(db: Path, clock: SimClock) -> ProfileStore:
    store = ProfileStore(db)
    store.pin_clock = lambda: clock.mono
    store.boot_id = lambda: clock.boot
    return store


def _six_digits(rng: random.Random) -> str:
    return str(rng.randint(GROWNUP_MIN, GROWNUP_MAX))


def _answers(strategy: str, rng: random.Random) -> Callable[[], str]:
    """The next answer a child of ``strategy`` types (not for the random tapper)."""
    if strategy == "one_answer":
        fixed = rng.choice((_six_digits(rng), rng.choice(COMMON_ANSWERS)))
        return lambda: fixed
    if strategy == "common_answers":
        turn = iter(range(10**9))
        return lambda: COMMON_ANSWERS[next(turn) % len(COMMON_ANSWERS)]
    if strategy == "seen_answer":
        seen = str(GrownUpQuestion.draw(rng).number)  # a question a grown-up once answered in view
        return lambda: seen
    return lambda: _six_digits(rng)


def run_child(strategy: str, db: Path, rng: random.Random, tally: ChildTally, day_s: float = SCHOOL_DAY_S) -> None:
    """One child of ``strategy`` for one school day on a fresh profile ``db``, into ``tally``."""
    clock = SimClock(rng)
    store = _open(db, clock)
    question = GrownUpQuestion.draw(rng)
    answer = _answers(strategy, rng)
    attempts = 0
    elapsed = 0.0  # the day's time, across reboots
    last_wrong: tuple[float, float] | None = None  # (elapsed at the wrong answer, the lock it set)
    entered = ""
    try:
        while elapsed < day_s:
            if strategy == "random_taps":
                step = rng.uniform(*CHILD_TAP_S)
                key = rng.choice("0123456789ck")
                if key.isdigit():
                    entered = (entered + key)[:6]
                    clock.advance(step)
                    elapsed += step
                    continue
                if key == "c":
                    entered = ""
                    clock.advance(step)
                    elapsed += step
                    continue
                typed = entered
                entered = ""
            else:
                typed = answer()
                step = (len(typed) + 1) * rng.uniform(*CHILD_TAP_S)
            clock.advance(step)
            elapsed += step
            with mock.patch.object(time, "time", lambda: clock.wall):
                check = store.try_grownup(question, typed)
            if check.refused:
                tally.refused += 1
                if strategy != "random_taps":  # watches the countdown; a tap or two while it runs
                    wait = check.wait_s + rng.uniform(0.5, 3.0)
                    clock.advance(wait)
                    elapsed += wait
                continue
            attempts += 1
            if last_wrong is not None and elapsed - last_wrong[0] < last_wrong[1] - 1e-6:
                tally.lock_violations += 1
            if check.ok:
                tally.passes += 1
                break
            last_wrong = (elapsed, check.wait_s)
            tally.longest_lock_s = max(tally.longest_lock_s, check.wait_s)
            question = GrownUpQuestion.draw(rng, previous=question)
            if strategy == "restarts":
                store.close()
                pause = rng.uniform(*RESTART_S)
                clock.advance(pause)
                elapsed += pause
                store = _open(db, clock)
                question = GrownUpQuestion.draw(rng)  # a new start: a new question
                tally.restarts += 1
            elif strategy == "clock_changes":
                store.close()
                clock.wall += rng.choice((-1, 1)) * rng.uniform(3600.0, 365 * 86400.0)
                pause = rng.uniform(*REBOOT_S)
                clock.reboot(pause)
                elapsed += pause
                store = _open(db, clock)
                question = GrownUpQuestion.draw(rng)
                tally.reboots += 1
    finally:
        store.close()
    tally.children += 1
    tally.attempts += attempts
    tally.attempts_per_day.append(attempts)


# ------------------------------------------------------------------ the grown-up
_UNITS = {w: n for n, w in enumerate("zero one two three four five six seven eight nine ten eleven twelve thirteen "
                                     "fourteen fifteen sixteen seventeen eighteen nineteen".split())}
_UNITS.update({w: 10 * n for n, w in enumerate("twenty thirty forty fifty sixty seventy eighty ninety".split(), 2)})
_KANJI = {c: n for n, c in enumerate("〇一二三四五六七八九")}
_KANJI_UNITS = {"十": 10, "百": 100, "千": 1000}


def read_number(text: str, lang: str) -> int:
    """The number a grown-up reads in ``text`` (English words or kanji numerals), parsed
    independently of :mod:`app.ui.number_words`; a ValueError for text that is no number."""
    if lang == "ja":
        total = section = digit = 0
        for ch in text:
            if ch in _KANJI:
                digit = _KANJI[ch]
            elif ch in _KANJI_UNITS:
                section += (digit or 1) * _KANJI_UNITS[ch]
                digit = 0
            elif ch == "万":
                total += (section + digit) * 10_000
                section = digit = 0
            else:
                raise ValueError(f"not a kanji numeral: {ch!r}")
        return total + section + digit
    total = part = 0
    for word in text.replace(",", " ").replace("-", " ").split():
        if word == "hundred":
            part *= 100
        elif word == "thousand":
            total, part = total + part * 1000, 0
        elif word in _UNITS:
            part += _UNITS[word]
        else:
            raise ValueError(f"not a number word: {word!r}")
    return total + part


def _key_position(key: str) -> tuple[int, int]:
    row = next(r for r, keys in enumerate(PAD) if key in keys)
    return row, PAD[row].index(key)


def tap_seconds(keys: str, scale: float = 1.0) -> float:
    """Fitts' law over the taps of ``keys`` on the pad, from a finger resting two keys away."""
    total, here = 0.0, None
    for key in keys:
        row, col = _key_position(key)
        distance = 2.0 if here is None else math.hypot(row - here[0], col - here[1])
        total += scale * (FITTS_A + FITTS_B * math.log2(distance * KEY_PITCH_OVER_WIDTH + 1.0))
        here = (row, col)
    return total


def grownup_seconds(db: Path, rng: random.Random, lang: str = "en", scale: float = 1.0) -> tuple[float, int]:
    """One simulated grown-up passing the check on a fresh profile ``db``: (seconds, wrong
    answers). ``scale`` multiplies every time constant (the slow grown-up)."""
    clock = SimClock(rng)
    store = _open(db, clock)
    wpm = READ_WPM * math.exp(rng.gauss(0.0, READ_SIGMA)) / scale
    seconds, wrong = 0.0, 0
    title_words = len(tr("gate_title", lang).split())
    try:
        question = GrownUpQuestion.draw(rng)
        while True:
            text = in_words(question.number, lang)
            reading = len(text) / (KANJI_PER_S / scale) if lang == "ja" else len(text.split()) / wpm * 60.0
            digits = str(read_number(text, lang))
            typed = "".join(d if rng.random() >= TYPO_P else rng.choice("0123456789".replace(d, ""))
                            for d in digits)
            spent = (title_words / wpm * 60.0 + reading + 2 * MENTAL_S * scale + tap_seconds(typed + "k", scale))
            seconds += spent
            clock.advance(spent)
            check = store.try_grownup(question, typed)
            if check.ok:
                return seconds, wrong
            wrong += 1
            seconds += check.wait_s
            clock.advance(check.wait_s)
            question = GrownUpQuestion.draw(rng, previous=question)
    finally:
        store.close()


def run_gate_campaign(work: Path, children: int = 60, grownups: int = 400, day_s: float = SCHOOL_DAY_S,
                      seed: int = 0, progress: Callable[[int], None] | None = None) -> dict:
    """``children`` children of each strategy for a school day each, and ``grownups``
    grown-ups in each language; the figures of ``storybeam stress gate``."""
    work.mkdir(parents=True, exist_ok=True)
    rng = random.Random(seed)
    started = time.monotonic()
    tallies = {s: ChildTally() for s in STRATEGIES}
    for i in range(children):
        for strategy in STRATEGIES:
            db = work / f"child-{strategy}-{i}.db"
            run_child(strategy, db, random.Random(rng.getrandbits(64)), tallies[strategy], day_s)
            for leftover in work.glob(f"{db.name}*"):
                leftover.unlink()
            if progress:
                progress(1)
    grown: dict[str, dict] = {}
    for lang in ("en", "ja"):
        for scale, name in ((1.0, ""), (2.0, "_slow")):
            times, wrongs = [], 0
            for k in range(grownups):
                db = work / f"grownup-{lang}{name}-{k}.db"
                s, w = grownup_seconds(db, random.Random(rng.getrandbits(64)), lang, scale)
                times.append(s)
                wrongs += w
                for leftover in work.glob(f"{db.name}*"):
                    leftover.unlink()
            grown[f"{lang}{name}"] = {"median": round(statistics.median(times), 2),
                                      "p90": round(sorted(times)[int(0.9 * (len(times) - 1))], 2),
                                      "max": round(max(times), 2), "wrong_answers": wrongs, "grownups": grownups}
            if progress:
                progress(1)
    total = {k: sum(getattr(t, k) for t in tallies.values()) for k in ("attempts", "refused", "passes",
                                                                       "lock_violations", "children")}
    median = max(grown["en"]["median"], grown["ja"]["median"])
    out = {
        "child_attempts": total["attempts"], "child_passes": total["passes"], "child_refused": total["refused"],
        "lock_violations": total["lock_violations"], "child_days": total["children"],
        "grownup_seconds_median": median,
        "grownup_seconds_median_slow": max(grown["en_slow"]["median"], grown["ja_slow"]["median"]),
        "grownup": grown, "strategies": {s: t.to_dict() for s, t in tallies.items()},
        "model": {"read_wpm": READ_WPM, "read_sigma": READ_SIGMA, "kanji_per_s": KANJI_PER_S, "mental_s": MENTAL_S,
                  "fitts_a_s": FITTS_A, "fitts_b_s_per_bit": FITTS_B, "typo_p": TYPO_P,
                  "key_pitch_over_width": KEY_PITCH_OVER_WIDTH, "child_tap_s": list(CHILD_TAP_S)},
        "day_seconds": day_s, "children_per_strategy": children, "seed": seed,
    }
    out["failures"] = int(out["child_passes"] > 0) + int(out["lock_violations"] > 0) + int(median >= 30.0)
    out["seconds"] = round(time.monotonic() - started, 1)
    return out


__all__ = ["STRATEGIES", "COMMON_ANSWERS", "SCHOOL_DAY_S", "SimClock", "ChildTally", "run_child", "read_number",
           "tap_seconds", "grownup_seconds", "run_gate_campaign"]
