"""Crash-safe storage of one device profile: stories, teacher data and the activity log.

One SQLite database per device profile, with the story assets (custom backgrounds,
thumbnails, narrations) in a folder beside it (``<name>.assets/``). The app uses it through
one façade, :class:`ProfileStore` (:mod:`.profile`); behind it, one module per concern:

* :mod:`.database` -- opening, checking and migrating the SQLite file (WAL,
  ``synchronous=FULL``, explicit transactions, ``user_version`` migrations), the durable
  file write, :class:`StorageError`;
* :mod:`.stories` -- the saved stories; :mod:`.assets` -- their files;
* :mod:`.teacher` -- settings and the teacher PIN (recovery code, delays after wrong tries);
* :mod:`.backup` -- the last good copy of the profile, and putting it back when the
  profile is damaged (stories and teacher PIN);
* :mod:`.classroom` -- class sessions, groups and the opt-in activity log;
* :mod:`.packages` -- story packages (export, validation, import).

The constants are re-exported here to be read; a test that changes one (``PIN_ITERATIONS``,
``MIGRATIONS``, ``MAX_ENTRY_BYTES``, ``durable_write``) patches the module that uses it.

Every problem a user can cause (a damaged file, a foreign file, a bad package) raises
:class:`StorageError` with the file name and the problem; the store stays usable for
everything that is not affected.
"""
from __future__ import annotations

from app.story.storage.backup import BackupInfo, backup_path, backup_settings, read_backup, restore_backup
from app.story.storage.classroom import MAX_NAME_CHARS, Group
from app.story.storage.database import APPLICATION_ID, MIGRATIONS, SCHEMA_VERSION, SQLITE_HEADER, StorageError
from app.story.storage.packages import (
    MAX_ENTRY_BYTES,
    MAX_PACKAGE_BYTES,
    MAX_PACKAGE_ENTRIES,
    MAX_UNCOMPRESSED_BYTES,
    PACKAGE_FORMAT_NAME,
    PACKAGE_FORMAT_VERSION,
    read_package,
)
from app.story.storage.profile import ProfileStore, default_profile_path
from app.story.storage.stories import StorySummary
from app.story.storage.teacher import (
    GROWNUP_LOCKS_S,
    GROWNUP_MAX,
    GROWNUP_MIN,
    PIN_DELAY_DOUBLES_EVERY,
    PIN_FIRST_DELAY_S,
    PIN_FREE_ATTEMPTS,
    PIN_ITERATIONS,
    PIN_MAX_DELAY_S,
    RECOVERY_CODE_DIGITS,
    GrownUpQuestion,
    PinCheck,
    grownup_lock_after,
    pin_delay_after,
    valid_pin,
)

__all__ = ["ProfileStore", "StorageError", "StorySummary", "Group", "read_package", "default_profile_path",
           "SCHEMA_VERSION", "MIGRATIONS", "APPLICATION_ID", "PinCheck", "pin_delay_after", "valid_pin",
           "RECOVERY_CODE_DIGITS", "MAX_ENTRY_BYTES", "MAX_PACKAGE_BYTES", "MAX_PACKAGE_ENTRIES",
           "MAX_UNCOMPRESSED_BYTES", "PACKAGE_FORMAT_NAME", "PACKAGE_FORMAT_VERSION", "SQLITE_HEADER", "MAX_NAME_CHARS",
           "PIN_ITERATIONS", "PIN_FREE_ATTEMPTS", "PIN_FIRST_DELAY_S", "PIN_DELAY_DOUBLES_EVERY", "PIN_MAX_DELAY_S",
           "GrownUpQuestion", "grownup_lock_after", "GROWNUP_LOCKS_S", "GROWNUP_MIN", "GROWNUP_MAX",
           "BackupInfo", "backup_path", "backup_settings", "read_backup", "restore_backup"]
