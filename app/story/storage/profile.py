"""The façade: :class:`ProfileStore`, one device profile, with every operation the app,
the lab and the tests use, each delegated to the module of its concern."""
from __future__ import annotations

import functools
import logging
import os
import sqlite3
import time
from pathlib import Path
from typing import Any, Callable

from app.story.storage.assets import AssetFolder
from app.story.storage.backup import write_backup
from app.story.storage.classroom import Classroom
from app.story.storage.database import ProfileDatabase, StorageError
from app.story.storage.packages import PackageShelf
from app.story.storage.stories import StoryShelf
from app.story.storage.teacher import Settings, TeacherGate, current_boot_id

log = logging.getLogger(__name__)


def forward(part: str, member: Callable[..., Any] | property) -> Any:
    """A façade member that calls ``member`` (a method or property of one concern's class)
    on the store's attribute ``part``: a plain function (with the member's name, docstring
    and signature, so it can be looked up and patched on the class) or a read-only property."""
    if isinstance(member, property):
        getter = member.fget
        assert getter is not None
        return property(lambda store: getter(getattr(store, part)), doc=member.__doc__)

    @functools.wraps(member)
    def call(store: "ProfileStore", *args: Any, **kwargs: Any) -> Any:
        return member(getattr(store, part), *args, **kwargs)
    return call


class ProfileStore:
    """One device profile: a SQLite database plus an assets folder beside it.

    Opening checks and migrates the database (:class:`~app.story.storage.database.ProfileDatabase`)
    and removes what a crash left in the assets folder (``leftovers_removed``: how many).
    Stories (:mod:`~app.story.storage.stories`), assets (:mod:`~app.story.storage.assets`),
    settings and the teacher PIN (:mod:`~app.story.storage.teacher`), class sessions, groups
    and the activity log (:mod:`~app.story.storage.classroom`) and story packages
    (:mod:`~app.story.storage.packages`) each live in their own module; this class holds
    one of each, sharing the connection, and forwards to them.
    """

    #: The clock the gate's locks are measured with: monotonic (the device's clock setting
    #: cannot move it), counted per boot (``boot_id``; see :mod:`.teacher`). Tests, the UI
    #: monkey and ``storybeam stress gate`` assign their own (no real sleeps).
    pin_clock = staticmethod(time.monotonic)
    boot_id = staticmethod(current_boot_id)

    def __init__(self, db_path: str | Path):
        self.db_path = Path(db_path)
        self.assets_dir = self.db_path.with_name(self.db_path.name + ".assets")
        self._db = ProfileDatabase(self.db_path)
        self._assets = AssetFolder(self.assets_dir)
        self._stories = StoryShelf(self._db, self._assets)
        self._settings = Settings(self._db)
        self._gate = TeacherGate(self._db, self._settings, lambda: self.pin_clock(), lambda: self.boot_id())
        self._classroom = Classroom(self._db, self._settings)
        self._packages = PackageShelf(self._stories, self._assets)
        self.leftovers_removed = self._assets.clean_leftovers()
        self.back_up()

    # -- the database -----------------------------------------------------------------
    @property
    def _conn(self) -> sqlite3.Connection:
        """The open connection (the stress harnesses and tests query it, or wrap it to
        make a COMMIT fail)."""
        return self._db.conn

    @_conn.setter
    def _conn(self, conn: sqlite3.Connection) -> None:
        self._db.conn = conn

    schema_version = forward("_db", ProfileDatabase.schema_version)
    journal_mode = forward("_db", ProfileDatabase.journal_mode)

    def back_up(self) -> bool:
        """Rotate the last good copy (:func:`~app.story.storage.backup.write_backup`): done
        on opening, after every PIN change and on closing; True when a new copy was written.
        A copy that cannot be written (a full disk, a read-only folder) is logged and the
        previous one kept: the profile itself stays usable."""
        try:
            return write_backup(self._db)
        except StorageError as exc:
            log.warning("%s", exc)
            return False

    def close(self) -> None:
        """Close the database (checkpointing the WAL into the main file), after one last
        backup (a database that fails its check, or a full disk, keeps the copy it had)."""
        if self._db.conn is not None:
            self.back_up()
        self._db.close()

    def __enter__(self) -> "ProfileStore":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- each concern's operations, forwarded ---------------------------------------------
    save_story = forward("_stories", StoryShelf.save)
    load_story = forward("_stories", StoryShelf.load)
    has_story = forward("_stories", StoryShelf.has)
    list_stories = forward("_stories", StoryShelf.summaries)
    delete_story = forward("_stories", StoryShelf.delete)
    bin_story = forward("_stories", StoryShelf.to_bin)
    restore_story = forward("_stories", StoryShelf.restore)
    binned_stories = forward("_stories", StoryShelf.binned)
    empty_bin = forward("_stories", StoryShelf.empty_bin)
    rename_story = forward("_stories", StoryShelf.rename)

    put_asset = forward("_assets", AssetFolder.put)
    story_assets_dir = forward("_assets", AssetFolder.story_folder)
    asset_path = forward("_assets", AssetFolder.path)
    asset_names = forward("_assets", AssetFolder.names)
    read_asset = forward("_assets", AssetFolder.read)

    get_setting = forward("_settings", Settings.get)
    set_setting = forward("_settings", Settings.set)

    has_pin = forward("_gate", TeacherGate.has_pin)
    has_recovery_code = forward("_gate", TeacherGate.has_recovery_code)
    new_recovery_code = forward("_gate", TeacherGate.new_recovery_code)
    forget_recovery_code = forward("_gate", TeacherGate.forget_recovery_code)

    def set_pin(self, pin: str) -> str:
        """:meth:`TeacherGate.set_pin <app.story.storage.teacher.TeacherGate.set_pin>`, then a
        backup at once: the last good copy always carries the PIN in force."""
        code = self._gate.set_pin(pin)
        self.back_up()
        return code

    def reset_pin(self, recovery_code: str, new_pin: str) -> str:
        """:meth:`TeacherGate.reset_pin <app.story.storage.teacher.TeacherGate.reset_pin>`,
        then a backup at once (as :meth:`set_pin`)."""
        code = self._gate.reset_pin(recovery_code, new_pin)
        self.back_up()
        return code

    verify_pin = forward("_gate", TeacherGate.verify_pin)
    pin_wait = forward("_gate", TeacherGate.pin_wait)
    recovery_wait = forward("_gate", TeacherGate.recovery_wait)
    try_pin = forward("_gate", TeacherGate.try_pin)
    try_recovery_code = forward("_gate", TeacherGate.try_recovery_code)
    grownup_wait = forward("_gate", TeacherGate.grownup_wait)
    try_grownup = forward("_gate", TeacherGate.try_grownup)

    create_session = forward("_classroom", Classroom.create_session)
    list_sessions = forward("_classroom", Classroom.list_sessions)
    delete_session = forward("_classroom", Classroom.delete_session)
    add_group = forward("_classroom", Classroom.add_group)
    list_groups = forward("_classroom", Classroom.list_groups)
    activity_logging = forward("_classroom", Classroom.activity_logging)
    set_activity_logging = forward("_classroom", Classroom.set_activity_logging)
    log_activity = forward("_classroom", Classroom.log_activity)
    export_activity_csv = forward("_classroom", Classroom.export_activity_csv)

    export_package = forward("_packages", PackageShelf.export_package)
    import_package = forward("_packages", PackageShelf.import_package)


def default_profile_path() -> Path:
    """Where the app keeps the device profile unless ``--db`` says otherwise."""
    base = os.environ.get("STORYBEAM_HOME") or os.path.join(os.path.expanduser("~"), ".storybeam")
    return Path(base) / "profile.db"
