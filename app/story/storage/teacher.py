"""Profile settings and the teacher gate: the PIN, its recovery code and the delays after
wrong tries.

Settings are ``key -> text`` rows. The PIN and the recovery code are stored only as salted
PBKDF2 hashes (:func:`hashlib.pbkdf2_hmac`, parameters stored with the hash); wrong tries
are slowed down (:func:`pin_delay_after`) with the state kept in the settings, so closing
the app does not reset it.
"""
from __future__ import annotations

import hashlib
import hmac
import json
import math
import os
import re
import secrets
from dataclasses import dataclass
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


def valid_pin(pin: object) -> bool:
    """Whether ``pin`` has the form of a teacher PIN (4 to 8 digits)."""
    return isinstance(pin, str) and PIN_PATTERN.match(pin) is not None


@dataclass(frozen=True)
class PinCheck:
    """The answer to one PIN (or recovery code) try.

    ``ok``: it matched. ``refused``: it was not even checked, because the wait after the
    last wrong tries is not over. ``wait_s``: seconds before the next try is accepted.
    ``failures``: wrong tries in a row so far.
    """

    ok: bool
    refused: bool
    wait_s: float
    failures: int


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
    """The teacher PIN and recovery code, kept as settings; ``clock`` measures the delays
    (seconds since the epoch, so a wait survives closing the app)."""

    def __init__(self, db: ProfileDatabase, settings: Settings, clock: Callable[[], float]):
        self._db = db
        self._settings = settings
        self._clock = clock

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
            conn.execute("DELETE FROM settings WHERE key IN ('teacher_pin_attempts', 'teacher_recovery_attempts')")
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

    def _attempts(self, key: str) -> tuple[int, float, float]:
        """(failures in a row, wait-until time, the wait's length) stored under ``key``."""
        raw = self._settings.get(key)
        if raw is None:
            return 0, 0.0, 0.0
        try:
            data = json.loads(raw)
            failures, until, delay = int(data["failures"]), float(data["until"]), float(data["delay"])
        except (ValueError, TypeError, KeyError):  # damaged: never fewer delays than one failure more
            failures = PIN_FREE_ATTEMPTS + 1
            delay = pin_delay_after(failures)
            return failures, self._clock() + delay, delay
        return max(failures, 0), until, delay

    def _wait(self, key: str) -> float:
        _failures, until, delay = self._attempts(key)
        # never longer than the wait that was set: a clock put back cannot lock a teacher out
        return max(0.0, min(until - self._clock(), delay))

    def _throttled_try(self, key: str, matches: bool | None) -> PinCheck:
        """Record one try of the secret whose attempts are under ``key``; ``matches`` is
        None when the try was refused before checking."""
        failures, _until, _delay = self._attempts(key)
        if matches is None:
            return PinCheck(False, True, self._wait(key), failures)
        if matches:
            with self._db.transaction() as conn:
                conn.execute("DELETE FROM settings WHERE key = ?", (key,))
            return PinCheck(True, False, 0.0, 0)
        failures += 1
        delay = pin_delay_after(failures)
        self._settings.set(key, json.dumps({"failures": failures, "until": self._clock() + delay, "delay": delay}))
        return PinCheck(False, False, delay, failures)

    def pin_wait(self) -> float:
        """Seconds before the next teacher PIN try is accepted (0: now)."""
        return self._wait("teacher_pin_attempts")

    def recovery_wait(self) -> float:
        """Seconds before the next recovery-code try is accepted (0: now)."""
        return self._wait("teacher_recovery_attempts")

    def try_pin(self, pin: str) -> PinCheck:
        """One PIN try from the number pad: refused unchecked while a wait runs; a wrong
        PIN adds a failure and sets the next wait (:func:`pin_delay_after`), persisted."""
        key = "teacher_pin_attempts"
        if self._wait(key) > 0:
            return self._throttled_try(key, None)
        return self._throttled_try(key, valid_pin(pin) and self._secret_matches("teacher_pin", pin, "teacher PIN"))

    def try_recovery_code(self, code: str) -> PinCheck:
        """One recovery-code try (spaces and dashes ignored), slowed down like the PIN but
        counted apart, so a child's wrong PINs never block the teacher's recovery."""
        key = "teacher_recovery_attempts"
        if self._wait(key) > 0:
            return self._throttled_try(key, None)
        code = code.replace(" ", "").replace("-", "") if isinstance(code, str) else ""
        if self._settings.get("teacher_recovery") is None:
            raise StorageError(f"{self._db.db_path}: no recovery code was set with this PIN")
        ok = RECOVERY_PATTERN.match(code) is not None and self._secret_matches("teacher_recovery", code,
                                                                               "recovery code")
        return self._throttled_try(key, ok)

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
