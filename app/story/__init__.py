"""The story a child makes, and where it is kept -- no Kivy, no OpenGL, no renderer.

* :mod:`app.story.model` -- ``Story`` > ``Scene`` > ``Character`` (sketched path in table
  metres, ``MotionChoice``, ``Mark``), validated dictionary form, the table's size;
* :mod:`app.story.editing` -- ``StoryEditor``: every edit the UI makes, with undo/redo;
* :mod:`app.story.gestures` -- reading a finger's strokes: thinning, spins, hops;
* :mod:`app.story.narration` -- a scene's voice: WAV/OGG checks and limits, trimming,
  storing it as a story asset crash-safely;
* :mod:`app.story.storage` -- ``ProfileStore``: the crash-safe SQLite profile, story
  packages, the teacher's PIN and groups;
* :mod:`app.story.demo_story` -- the bundled three-scene demo story.

Everything here runs anywhere Python and numpy do (the tablet, tests, a batch job).
"""
from __future__ import annotations

from app.story.demo_story import DEMO_STORY_ID, demo_story, wavy_path
from app.story.editing import MAX_UNDO, StoryEditor
from app.story.gestures import find_spins, hop_time, thin
from app.story.model import (
    ARCS,
    BACKGROUNDS,
    CHARACTER_KINDS,
    COVER_COLOURS,
    COVER_PICTURES,
    MARK_KINDS,
    MAX_CHARACTERS_PER_SCENE,
    MAX_NARRATION_SECONDS,
    MAX_PATH_POINTS,
    MAX_SCENE_SECONDS,
    MAX_SCENES,
    MAX_TITLE_CHARS,
    MOTION_CLASSES,
    STORY_FORMAT_NAME,
    STORY_FORMAT_VERSION,
    TABLE_DEPTH_M,
    TABLE_WIDTH_M,
    Character,
    Cover,
    Mark,
    MotionChoice,
    Narration,
    Scene,
    Story,
    StoryError,
    new_id,
)
from app.story.narration import (
    ACCEPTED_RATES,
    MAX_IMPORT_FILE_BYTES,
    MAX_IMPORT_SECONDS,
    MAX_NARRATION_FILE_BYTES,
    MAX_STORY_NARRATION_SECONDS,
    MIN_NARRATION_SECONDS,
    Audio,
    NarrationError,
    decode_audio,
    encode_wav,
    import_narration,
    load_narration,
    prune_narrations,
    read_audio,
    store_narration,
    trim,
)
from app.story.storage import (
    APPLICATION_ID,
    BackupInfo,
    MIGRATIONS,
    RECOVERY_CODE_DIGITS,
    SCHEMA_VERSION,
    Group,
    GrownUpQuestion,
    PinCheck,
    ProfileStore,
    StorageError,
    StorySummary,
    backup_settings,
    default_profile_path,
    grownup_lock_after,
    pin_delay_after,
    read_backup,
    read_package,
    restore_backup,
    valid_pin,
)

__all__ = [
    # model
    "STORY_FORMAT_VERSION", "STORY_FORMAT_NAME", "ARCS", "CHARACTER_KINDS", "MOTION_CLASSES", "MARK_KINDS",
    "BACKGROUNDS", "COVER_PICTURES", "COVER_COLOURS", "Cover",
    "TABLE_WIDTH_M", "TABLE_DEPTH_M", "MAX_PATH_POINTS", "MAX_SCENES", "MAX_CHARACTERS_PER_SCENE",
    "MAX_TITLE_CHARS", "MAX_SCENE_SECONDS", "StoryError", "new_id", "Mark", "MotionChoice", "Character", "Scene",
    "Story", "Narration", "MAX_NARRATION_SECONDS",
    # narration
    "NarrationError", "Audio", "ACCEPTED_RATES", "MIN_NARRATION_SECONDS", "MAX_NARRATION_FILE_BYTES",
    "MAX_IMPORT_FILE_BYTES", "MAX_IMPORT_SECONDS", "MAX_STORY_NARRATION_SECONDS", "decode_audio", "read_audio", "trim", "encode_wav", "store_narration",
    "import_narration", "load_narration", "prune_narrations",
    # editing
    "StoryEditor", "MAX_UNDO",
    # gestures
    "thin", "find_spins", "hop_time",
    # storage
    "ProfileStore", "StorageError", "StorySummary", "Group", "read_package", "default_profile_path",
    "SCHEMA_VERSION", "MIGRATIONS", "APPLICATION_ID", "PinCheck", "pin_delay_after", "valid_pin",
    "RECOVERY_CODE_DIGITS", "GrownUpQuestion", "grownup_lock_after",
    "BackupInfo", "read_backup", "restore_backup", "backup_settings",
    # demo story
    "DEMO_STORY_ID", "demo_story", "wavy_path",
]
