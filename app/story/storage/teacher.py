"""Profile settings and the teacher gate: the grown-up check before the first PIN, the PIN,
its recovery code and the locks after wrong answers.

Settings are ``key -> text`` rows. The PIN and the recovery code are stored only as salted
PBKDF2 hashes (:func:`hashlib.pbkdf2_hmac`, parameters stored with the hash).

**Locks on a clock a child cannot move.** A wrong grown-up answer locks the check
(:func:`grownup_lock_after`: 30 s, 1, 2, 5 min, then 15 min after every further wrong
answer); wrong PINs and recovery codes are slowed down (:func:`pin_delay_after`). A lock
is a record ``{failures, remaining, mark, boot}`` in the settings: the seconds of lock
*remaining* when the monotonic clock (``time.monotonic``, which the device's clock
setting does not move) read *mark* during the boot *boot*
(``/proc/sys/kernel/random/boot_id``). The lock left now is ``remaining - (now - mark)``
when the boot is the same and the clock has not gone back; after a reboot (a new boot id,
a new monotonic origin) or a clock that went back, nothing is counted since the mark and
the record is re-anchored to the present, so the rest of the wait starts over from
there: a restart, a reboot or a moved wall clock never shortens a lock, and no lock is
ever longer than the one that was set. Where the boot id cannot be read, each process
counts as its own boot: the lock then counts down only while the app runs.

**The grown-up check** (:class:`GrownUpQuestion`): a six-digit number written in words
("four hundred seventy-two thousand, six hundred nineteen"), to be typed in digits. The
number is drawn uniformly from 100 000-999 999 (no answer is favoured; never the one just
asked), so a guess hits with probability 1/900 000, and with the locks a child gets about
29 answers checked in a 6.5-hour school day (``storybeam stress gate`` measures it).
"""
from __future__ import annotations

import hashlib
import hmac
import json
import math
import os
import random
import re
import secrets
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from app.story.storage.database import ProfileDatabase, StorageError, as_storage_error

# Teacher PIN hashing (hashlib.pbkdf2_hmac, random salt; parameters stored with the hash).
PIN_ITERATIONS = 200_000
PIN_PATTERN = re.compile(r"^[0-9]{4,8}$")
# Wrong PINs are slowed down (see :func:`pin_delay_after`); the state is kept in the
# profile, so closing the app does not reset it.
PIN_FREE_ATTEMPTS = 4
PIN_FIRST_DELAY_S = 30.0
PIN_DELAY_DOUBLES_EVERY = 5
PIN_MAX_DELAY_S = 15 * 60.0
#: Digits of the recovery code shown once when a PIN is set (10**12 codes: not guessable by tapping).
RECOVERY_CODE_DIGITS = 12
RECOVERY_PATTERN = re.compile(rf"^[0-9]{{{RECOVERY_CODE_DIGITS}}}$")
#: The grown-up check's lock after the 1st, 2nd, ... wrong answer in a row (seconds); every
#: later wrong answer locks it for the last (15 minutes).
GROWNUP_LOCKS_S = (30.0, 60.0, 120.0, 300.0, 900.0)
#: The range the grown-up check's number is drawn from, uniformly (six digits).
GROWNUP_MIN, GROWNUP_MAX = 100_000, 999_999
#: Settings keys of the three lock records.
PIN_LOCK, RECOVERY_LOCK, GROWNUP_LOCK = "teacher_pin_attempts", "teacher_recovery_attempts", "grownup_attempts"
BOOT_ID_FILE = Path("/proc/sys/kernel/random/boot_id")
_PROCESS_BOOT = f"process-{uuid.uuid4()}"


def pin_delay_after(failures: int) -> float:
    """Seconds to wait before the next PIN try after ``failures`` wrong ones in a row.

    The first :data:`PIN_FREE_ATTEMPTS` (4) are free (a teacher mistypes); from the 5th,
    30 s, doubling every 5 failures, at most 15 minutes (phones do the same: Android waits
    30 s after 5 failures). So failures 5-9 wait 30 s each, 10-14 60 s, 15-19 120 s, and
    the 20th wrong PIN in a row can be typed no earlier than
    ``5·30 + 5·60 + 5·120 = 1 050 s`` (17.5 minutes) after the first.
    """
    if failures <= PIN_FREE_ATTEMPTS:
        return 0.0
    doublings = min((failures - PIN_FREE_ATTEMPTS - 1) // PIN_DELAY_DOUBLES_EVERY, 32)
    return min(PIN_FIRST_DELAY_S * 2.0 ** doublings, PIN_MAX_DELAY_S)


def grownup_lock_after(failures: int) -> float:
    """Seconds the grown-up check stays locked after ``failures`` wrong answers in a row:
    none before the first, then :data:`GROWNUP_LOCKS_S` (30 s, 1 min, 2 min, 5 min,
    15 min), 15 minutes for every one after the fifth."""
    if failures <= 0:
        return 0.0
    return GROWNUP_LOCKS_S[min(failures, len(GROWNUP_LOCKS_S)) - 1]


def valid_pin(pin: object) -> bool:
    """Whether ``pin`` has the form of a teacher PIN (4 to 8 digits)."""
    return isinstance(pin, str) and PIN_PATTERN.match(pin) is not None


def current_boot_id() -> str:
    """This boot's id (Linux and Android: ``/proc/sys/kernel/random/boot_id``, new at every
    start of the device); where it cannot be read, an id of this process, so a lock then
    counts down only while the app runs (never faster)."""
    try:
        text = BOOT_ID_FILE.read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError):
        return _PROCESS_BOOT
    return text or _PROCESS_BOOT


@dataclass(frozen=True)
class GrownUpQuestion:
    """One grown-up check: type :attr:`number` (shown in words, :mod:`app.ui.teacher`) in
    digits. :meth:`draw` picks it uniformly from :data:`GROWNUP_MIN`-:data:`GROWNUP_MAX`."""

    number: int

    @classmethod
    def draw(cls, rng: random.Random | None = None, previous: "GrownUpQuestion | None" = None) -> "GrownUpQuestion":
        """A new question, uniform over the six-digit numbers, never ``previous`` again."""
        rng = rng or random.SystemRandom()
        while True:
            number = rng.randint(GROWNUP_MIN, GROWNUP_MAX)
            if previous is None or number != previous.number:
                return cls(number)

    def check(self, answer: str) -> bool:
        """Whether the digits typed are the number (no sign, no spaces: the pad has none)."""
        return isinstance(answer, str) and answer.isascii() and answer.isdecimal() and int(answer) == self.number


@dataclass(frozen=True)
class PinCheck:
    """The answer to one try (a PIN, a recovery code or a grown-up answer).

    ``ok``: it matched. ``refused``: it was not even checked, because the lock after the
    last wrong tries is not over. ``wait_s``: seconds before the next try is accepted.
    ``failures``: wrong tries in a row so far.
    """

    ok: bool
    refused: bool
    wait_s: float
    failures: int


@dataclass(frozen=True)
class _Lock:
    failures: int
    remaining: float
    mark: float
    boot: str


class Settings:
    """The ``settings`` table: text values by key."""

    def __init__(self, db: ProfileDatabase):
        self._db = db

    def get(self, key: str, default: str | None = None) -> str | None:
        """The value under ``key``, or ``default`` when none is set."""
        with as_storage_error(self._db.db_path, "settings cannot be read"):
            row = self._db.conn.execute("SELECT value FROM settings WHERE key = ?", (key,)).fetchone()
        return default if row is None else row[0]

    def set(self, key: str, value: str) -> None:
        """Insert or replace the value under ``key`` (one transaction)."""
        with self._db.transaction() as conn:
            conn.execute("INSERT INTO settings (key, value) VALUES (?, ?) "
                         "ON CONFLICT(key) DO UPDATE SET value = excluded.value", (key, value))


class TeacherGate:
    """The grown-up check, the teacher PIN and its recovery code, kept as settings.

    ``clock`` is monotonic (seconds; the device's clock setting does not move it) and
    ``boot`` names the boot it counts from (:func:`current_boot_id`): the locks are
    measured on them (see the module docstring), so closing the app, restarting the
    tablet or moving its clock never shortens one."""

    def __init__(self, db: ProfileDatabase, settings: Settings, clock: Callable[[], float],
                 boot: Callable[[], str] = current_boot_id):
        self._db = db
        self._settings = settings
        self._clock = clock
        self._boot = boot

    def has_pin(self) -> bool:
        return self._settings.get("teacher_pin") is not None

    def _hash_secret(self, secret: str) -> str:
        salt = os.urandom(16)
        digest = hashlib.pbkdf2_hmac("sha256", secret.encode(), salt, PIN_ITERATIONS)
        return f"pbkdf2_sha256${PIN_ITERATIONS}${salt.hex()}${digest.hex()}"

    def _secret_matches(self, key: str, secret: str, what: str) -> bool:
        """Compare ``secret`` with the salted hash under setting ``key`` (constant time).
        A damaged record is an error that says so, not a silent "wrong PIN" forever."""
        record = self._settings.get(key)
        if record is None:
            return False
        damaged = f"{self._db.db_path}: the {what} record is damaged"
        parts = record.split("$")
        if len(parts) != 4:
            raise StorageError(f"{damaged} ({len(parts)} fields instead of 4); "
                               "reset the PIN with the recovery code")
        scheme, iterations, salt_hex, digest_hex = parts
        if scheme != "pbkdf2_sha256":
            raise StorageError(f"{damaged} (unknown scheme {scheme[:32]!r}); reset the PIN with the recovery code")
        try:
            rounds = int(iterations)
            salt, want = bytes.fromhex(salt_hex), bytes.fromhex(digest_hex)
            if not 1 <= rounds <= 10_000_000:
                raise ValueError(f"{rounds} iterations")
        except ValueError as exc:
            raise StorageError(f"{damaged} ({exc}); reset the PIN with the recovery code") from None
        return hmac.compare_digest(hashlib.pbkdf2_hmac("sha256", secret.encode(), salt, rounds), want)

    def _set_pin_records(self, pin: str) -> str:
        if not valid_pin(pin):
            raise StorageError("teacher PIN: must be 4 to 8 digits")
        code = "".join(secrets.choice("0123456789") for _ in range(RECOVERY_CODE_DIGITS))
        records = {"teacher_pin": self._hash_secret(pin), "teacher_recovery": self._hash_secret(code)}
        with self._db.transaction() as conn:  # PIN, recovery code and cleared delays: all or nothing
            for key, value in records.items():
                conn.execute("INSERT INTO settings (key, value) VALUES (?, ?) "
                             "ON CONFLICT(key) DO UPDATE SET value = excluded.value", (key, value))
            conn.execute("DELETE FROM settings WHERE key IN (?, ?)", (PIN_LOCK, RECOVERY_LOCK))
        return code

    def has_recovery_code(self) -> bool:
        return self._settings.get("teacher_recovery") is not None

    def new_recovery_code(self) -> str:
        """A new recovery code for the PIN in place (the old code stops working): for a
        profile whose PIN was set before recovery codes existed. The UI calls it only right
        after the right PIN was typed, and shows the code once."""
        if not self.has_pin():
            raise StorageError(f"{self._db.db_path}: no teacher PIN to make a recovery code for")
        code = "".join(secrets.choice("0123456789") for _ in range(RECOVERY_CODE_DIGITS))
        self._settings.set("teacher_recovery", self._hash_secret(code))
        return code

    def forget_recovery_code(self) -> None:
        """Drop the recovery code of the PIN in place (a code shown but never confirmed as
        written down: the screen was left alone). The next right PIN makes and shows a new
        one (:meth:`new_recovery_code`), so no code stays valid that no grown-up kept."""
        with self._db.transaction() as conn:
            conn.execute("DELETE FROM settings WHERE key = 'teacher_recovery'")

    def set_pin(self, pin: str) -> str:
        """Set the teacher PIN (4-8 digits) and return a new recovery code
        (:data:`RECOVERY_CODE_DIGITS` digits) to show the teacher once; only salted PBKDF2
        hashes of both are stored. The UI asks a grown-up question before the first PIN."""
        return self._set_pin_records(pin)

    def verify_pin(self, pin: str) -> bool:
        """True when ``pin`` matches the stored PIN (no delays: the UI uses :meth:`try_pin`)."""
        if not valid_pin(pin):
            return False
        return self._secret_matches("teacher_pin", pin, "teacher PIN")

    def _lock(self, key: str, schedule: Callable[[int], float]) -> _Lock:
        """The lock record under ``key``; a damaged one counts as one failure more than the
        free ones, locked for that failure's full time from now (never fewer delays)."""
        raw = self._settings.get(key)
        if raw is None:
            return _Lock(0, 0.0, self._clock(), self._boot())
        try:
            data = json.loads(raw)
            lock = _Lock(max(int(data["failures"]), 0), float(data["remaining"]), float(data["mark"]),
                         str(data["boot"]))
            if not (math.isfinite(lock.remaining) and math.isfinite(lock.mark)):
                raise ValueError("not finite")
            return lock
        except (ValueError, TypeError, KeyError, AttributeError):  # damaged, or a wall-clock record of old
            failures = next(f for f in range(1, 64) if schedule(f) > 0)
            if isinstance(data := _json_or_none(raw), dict) and isinstance(data.get("failures"), int):
                failures = max(failures, data["failures"])
            lock = _Lock(failures, schedule(failures), self._clock(), self._boot())
            self._store_lock(key, lock)
            return lock

    def _store_lock(self, key: str, lock: _Lock) -> None:
        self._settings.set(key, json.dumps({"failures": lock.failures, "remaining": lock.remaining,
                                            "mark": lock.mark, "boot": lock.boot}))

    def _wait(self, key: str, schedule: Callable[[int], float]) -> float:
        """Seconds of lock left under ``key``: counted down on the monotonic clock of the
        boot that set it; re-anchored (nothing counted) after a reboot or a clock gone back."""
        lock = self._lock(key, schedule)
        if lock.remaining <= 0:
            return 0.0
        now, boot = self._clock(), self._boot()
        if boot == lock.boot and now >= lock.mark:
            return max(0.0, lock.remaining - (now - lock.mark))
        self._store_lock(key, _Lock(lock.failures, lock.remaining, now, boot))
        return lock.remaining

    def _throttled_try(self, key: str, schedule: Callable[[int], float], matches: Callable[[], bool]) -> PinCheck:
        """One try of the secret (or answer) whose lock is under ``key``: refused unchecked
        (``matches`` not called) while locked; right: the record is cleared; wrong: one
        failure more and the lock ``schedule(failures)`` from now, persisted."""
        wait = self._wait(key, schedule)
        failures = self._lock(key, schedule).failures
        if wait > 0:
            return PinCheck(False, True, wait, failures)
        if matches():
            with self._db.transaction() as conn:
                conn.execute("DELETE FROM settings WHERE key = ?", (key,))
            return PinCheck(True, False, 0.0, 0)
        failures += 1
        delay = schedule(failures)
        self._store_lock(key, _Lock(failures, delay, self._clock(), self._boot()))
        return PinCheck(False, False, delay, failures)

    # -- the grown-up check ---------------------------------------------------------------
    def grownup_wait(self) -> float:
        """Seconds before the grown-up check takes an answer again (0: now)."""
        return self._wait(GROWNUP_LOCK, grownup_lock_after)

    def try_grownup(self, question: GrownUpQuestion, answer: str) -> PinCheck:
        """One answer to the grown-up check: refused unchecked while it is locked; a wrong
        answer locks it (:func:`grownup_lock_after`), persisted; a right one clears the lock.
        The UI then asks a new question (:meth:`GrownUpQuestion.draw`) whatever the answer."""
        return self._throttled_try(GROWNUP_LOCK, grownup_lock_after, lambda: question.check(answer))

    def pin_wait(self) -> float:
        """Seconds before the next teacher PIN try is accepted (0: now)."""
        return self._wait(PIN_LOCK, pin_delay_after)

    def recovery_wait(self) -> float:
        """Seconds before the next recovery-code try is accepted (0: now)."""
        return self._wait(RECOVERY_LOCK, pin_delay_after)

    def try_pin(self, pin: str) -> PinCheck:
        """One PIN try from the number pad: refused unchecked while a wait runs; a wrong
        PIN adds a failure and sets the next wait (:func:`pin_delay_after`), persisted."""
        return self._throttled_try(PIN_LOCK, pin_delay_after,
                                   lambda: valid_pin(pin) and self._secret_matches("teacher_pin", pin, "teacher PIN"))

    def try_recovery_code(self, code: str) -> PinCheck:
        """One recovery-code try (spaces and dashes ignored), slowed down like the PIN but
        counted apart, so a child's wrong PINs never block the teacher's recovery."""
        if self._settings.get("teacher_recovery") is None:
            raise StorageError(f"{self._db.db_path}: no recovery code was set with this PIN")
        code = code.replace(" ", "").replace("-", "") if isinstance(code, str) else ""
        return self._throttled_try(RECOVERY_LOCK, pin_delay_after, lambda: RECOVERY_PATTERN.match(code) is not None
                                   and self._secret_matches("teacher_recovery", code, "recovery code"))

    def reset_pin(self, recovery_code: str, new_pin: str) -> str:
        """Replace a forgotten PIN: the recovery code must match; returns the next
        recovery code (the used one stops working). Stories and every other setting are
        untouched."""
        if not valid_pin(new_pin):
            raise StorageError("teacher PIN: must be 4 to 8 digits")
        check = self.try_recovery_code(recovery_code)
        if not check.ok:
            wait = f"; try again in {math.ceil(check.wait_s)} s" if check.wait_s > 0 else ""
            raise StorageError(f"recovery code: wrong code{wait}")
        return self._set_pin_records(new_pin)


def _json_or_none(raw: str) -> object:
    try:
        return json.loads(raw)
    except ValueError:
        return None
