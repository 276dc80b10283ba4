"""A scene's voice: checking, decoding, trimming and storing narration audio.

Method. Whatever comes in (an imported WAV or OGG file, a finished recording, a
package's asset) is decoded to 16-bit mono PCM and checked *before* anything is stored:

1. **Size first.** A file larger than :data:`MAX_NARRATION_FILE_BYTES` is refused from its
   ``stat`` alone, so an enormous file is never read into memory.
2. **Format by content, not by name.** ``RIFF....WAVE`` is read with the standard
   library's :mod:`wave` (integer PCM, 8/16/24/32 bit, mono or stereo); ``OggS`` with
   `soundfile <https://python-soundfile.readthedocs.io>`_ (libsndfile: Vorbis, Opus,
   FLAC-in-Ogg), an optional dependency -- without it an OGG file is refused with a
   message saying so. Anything else is "not a WAV or OGG file".
3. **Header limits before decoding.** The declared rate must be one of
   :data:`ACCEPTED_RATES` (telephone 8 kHz to studio 48 kHz: anything else is a wrong or
   damaged header), and the declared length at most :data:`MAX_NARRATION_SECONDS`, so a
   header announcing hours of audio is refused before its samples are read.
4. **Decoded checks.** The frames actually read must match the header (a truncated file
   is corrupt), be at least :data:`MIN_NARRATION_SECONDS` long and not all zero (an
   empty recording -- a muted or missing microphone).
5. **Stored form.** The checked audio is written as a mono 16-bit PCM WAV at its own
   rate (the form Kivy's ``SoundLoader`` plays on every platform and ffmpeg muxes), named
   by its content hash (``narration-<sha256 prefix>.wav``). Stereo is averaged to mono.

Bounds. A stored narration is at most ``120 s x 48 000 Hz x 2 B = 11.5 MB``, under the
package's 16 MB per-file limit (:data:`app.story.storage.MAX_ENTRY_BYTES`), and a story's
narrations together at most :data:`MAX_STORY_NARRATION_SECONDS` (``600 s x 96 kB/s =
57.6 MB``), under the package's 96 MB unpacked limit -- so every story that can be
narrated can also be packaged.

Crash safety (:func:`store_narration`): the WAV is written as a story asset with the
store's atomic write (temporary file, fsync, rename) under a name no saved story uses
yet, and only then does the scene point at it and the story get saved (one SQLite
transaction). A SIGKILL before the save leaves the old story with its old narration
(the new file is an unreferenced asset); after it, the new story with a complete file.

Every refusal raises :class:`NarrationError` naming the file; nothing is stored.
"""
from __future__ import annotations

import hashlib
import io
import os
import wave
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from app.story.model import MAX_NARRATION_SECONDS, Narration, Story
from retrieval.errors import StoryBeamError


class AssetStore(Protocol):
    """What narration needs of :class:`app.story.storage.ProfileStore` (which imports this
    module for its package checks, so this module does not import it back)."""

    def put_asset(self, story_id: str, name: str, data: bytes) -> Path: ...

    def read_asset(self, story_id: str, name: str) -> bytes: ...

    def save_story(self, story: Story) -> None: ...

    def asset_names(self, story_id: str) -> list[str]: ...

    def asset_path(self, story_id: str, name: str) -> Path: ...


class NarrationEditor(Protocol):
    """The one edit narration makes (:meth:`app.story.editing.StoryEditor.set_narration`)."""

    def set_narration(self, scene_id: str, narration: Narration | None) -> None: ...

#: Sample rates a narration may have (Hz); anything else is refused as a wrong rate.
ACCEPTED_RATES = (8000, 11025, 16000, 22050, 24000, 32000, 44100, 48000)
MIN_NARRATION_SECONDS = 0.1
#: Largest file accepted for import (bytes), checked before reading.
MAX_NARRATION_FILE_BYTES = 16 * 1024 * 1024
#: All narrations of one story together (seconds): keeps every narrated story packable.
MAX_STORY_NARRATION_SECONDS = 600.0
MAX_CHANNELS = 2
ASSET_PREFIX = "narration-"


class NarrationError(StoryBeamError):
    """Audio that cannot be a scene's narration; the message names the file and why."""


@dataclass(frozen=True)
class Audio:
    """Decoded narration: mono 16-bit samples at ``rate`` Hz."""

    samples: np.ndarray  # (n,) int16
    rate: int

    @property
    def seconds(self) -> float:
        return len(self.samples) / self.rate


def _seconds_text(seconds: float) -> str:
    return f"{seconds:.1f} s"


def _check_header(where: str, rate: int, channels: int, frames: int) -> None:
    if rate not in ACCEPTED_RATES:
        raise NarrationError(f"{where}: sample rate {rate} Hz is not supported "
                             f"(use one of {', '.join(str(r) for r in ACCEPTED_RATES)} Hz)")
    if not 1 <= channels <= MAX_CHANNELS:
        raise NarrationError(f"{where}: {channels} channels; narration must be mono or stereo")
    if frames <= 0:
        raise NarrationError(f"{where}: the audio is empty (no samples)")
    if frames / rate > MAX_NARRATION_SECONDS:
        raise NarrationError(f"{where}: {_seconds_text(frames / rate)} long; a scene's narration may be at most "
                             f"{MAX_NARRATION_SECONDS:.0f} s (trim it first)")


def _finish(where: str, mono: np.ndarray, rate: int) -> Audio:
    """Checks on the decoded samples (length, silence) and the :class:`Audio`."""
    samples = np.ascontiguousarray(mono, dtype=np.int16)
    if len(samples) / rate < MIN_NARRATION_SECONDS:
        raise NarrationError(f"{where}: only {len(samples) / rate * 1000:.0f} ms of audio; "
                             f"a narration needs at least {MIN_NARRATION_SECONDS * 1000:.0f} ms")
    if not np.any(samples):
        raise NarrationError(f"{where}: the audio is empty (silence only; is the microphone on?)")
    return Audio(samples, rate)


def _decode_wav(data: bytes, where: str) -> Audio:
    try:
        with wave.open(io.BytesIO(data), "rb") as wf:
            rate, channels, width, frames = wf.getframerate(), wf.getnchannels(), wf.getsampwidth(), wf.getnframes()
            _check_header(where, rate, channels, frames)
            if width not in (1, 2, 3, 4):
                raise NarrationError(f"{where}: {8 * width}-bit samples are not supported")
            raw = wf.readframes(frames)
    except (wave.Error, EOFError, ValueError, RuntimeError, OverflowError) as exc:
        # wave.Error: not PCM, a bad chunk; EOFError: cut short; RuntimeError: a chunk size
        # that seeks past the end (found by fuzzing mutated WAVs)
        raise NarrationError(f"{where}: not a readable WAV file ({exc or type(exc).__name__})") from None
    if len(raw) != frames * channels * width:
        raise NarrationError(f"{where}: the WAV file is damaged or cut short "
                             f"({len(raw) // (channels * width)} of {frames} frames present)")
    if width == 2 and channels == 1:  # the common case (and the stored form): the samples as they are
        return _finish(where, np.frombuffer(raw, "<i2"), rate)
    if width == 1:  # unsigned 8-bit
        ints = (np.frombuffer(raw, np.uint8).astype(np.int32) - 128) << 8
    elif width == 2:
        ints = np.frombuffer(raw, "<i2").astype(np.int32)
    elif width == 3:  # little-endian 24-bit: keep the top two bytes
        b = np.frombuffer(raw, np.uint8).reshape(-1, 3)
        ints = b[:, 1].astype(np.int32) | (b[:, 2].astype(np.int8).astype(np.int32) << 8)
    else:
        ints = np.frombuffer(raw, "<i4").astype(np.int64) >> 16
    mono = ints.reshape(-1, channels).mean(axis=1)
    return _finish(where, np.clip(np.round(mono), -32768, 32767), rate)


def _decode_ogg(data: bytes, where: str) -> Audio:
    try:
        import soundfile  # optional: soundfile/libsndfile (desktop; absent on Android)
    except (ImportError, OSError):
        raise NarrationError(f"{where}: OGG files cannot be read on this device (soundfile is not installed); "
                             "use a WAV file") from None
    try:
        with soundfile.SoundFile(io.BytesIO(data)) as sf:
            _check_header(where, int(sf.samplerate), int(sf.channels), int(sf.frames))
            frames, channels, rate = int(sf.frames), int(sf.channels), int(sf.samplerate)
            block = sf.read(frames, dtype="int16", always_2d=True)
    except (RuntimeError, soundfile.LibsndfileError, ValueError, TypeError) as exc:
        reason = str(exc).rsplit(": ", 1)[-1]  # libsndfile's reason, without the repr of our buffer
        raise NarrationError(f"{where}: not a readable OGG file ({reason})") from None
    if block.shape[0] != frames or block.shape[1] != channels:
        raise NarrationError(f"{where}: the OGG file is damaged or cut short "
                             f"({block.shape[0]} of {frames} frames decoded)")
    return _finish(where, np.round(block.astype(np.float64).mean(axis=1)), rate)


def decode_audio(data: bytes, where: str) -> Audio:
    """Decode and check narration bytes (WAV or OGG, told apart by content); ``where``
    names the source in messages. Raises :class:`NarrationError`."""
    if len(data) > MAX_NARRATION_FILE_BYTES:
        raise NarrationError(f"{where}: {len(data) / 2**20:.1f} MB; an audio file may be at most "
                             f"{MAX_NARRATION_FILE_BYTES // 2**20} MB")
    if not data:
        raise NarrationError(f"{where}: the file is empty")
    if data[:4] == b"RIFF" and data[8:12] == b"WAVE":
        return _decode_wav(data, where)
    if data[:4] == b"OggS":
        return _decode_ogg(data, where)
    raise NarrationError(f"{where}: not a WAV or OGG audio file")


def read_audio(path: str | Path) -> Audio:
    """Read and check an audio file to import (size checked before reading)."""
    path = Path(path)
    try:
        size = os.stat(path).st_size
        if size > MAX_NARRATION_FILE_BYTES:
            raise NarrationError(f"{path}: {size / 2**20:.1f} MB; an audio file may be at most "
                                 f"{MAX_NARRATION_FILE_BYTES // 2**20} MB")
        data = path.read_bytes()
    except OSError as exc:
        raise NarrationError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    return decode_audio(data, str(path))


def trim(audio: Audio, start: float = 0.0, end: float | None = None, where: str = "narration") -> Audio:
    """The part of ``audio`` from ``start`` to ``end`` seconds (``end`` None: to the end),
    cut on sample boundaries; refused when the part is shorter than
    :data:`MIN_NARRATION_SECONDS` or silent."""
    end = audio.seconds if end is None else end
    if not (np.isfinite(start) and np.isfinite(end)) or start < 0 or end > audio.seconds + 1e-9 or end <= start:
        raise NarrationError(f"{where}: cannot trim {start:.2f}-{end:.2f} s of a "
                             f"{_seconds_text(audio.seconds)} recording")
    a, b = int(round(start * audio.rate)), int(round(end * audio.rate))
    return _finish(where, audio.samples[a:b], audio.rate)


def encode_wav(audio: Audio) -> bytes:
    """The stored form: a mono 16-bit PCM WAV."""
    buf = io.BytesIO()
    with wave.open(buf, "wb") as wf:
        wf.setnchannels(1)
        wf.setsampwidth(2)
        wf.setframerate(audio.rate)
        wf.writeframes(audio.samples.astype("<i2").tobytes())
    return buf.getvalue()


def asset_name(wav: bytes) -> str:
    """The asset name of a stored narration: ``narration-<first 16 hex of SHA-256>.wav``."""
    return f"{ASSET_PREFIX}{hashlib.sha256(wav).hexdigest()[:16]}.wav"


def check_story_total(story: Story, scene_id: str, seconds: float, where: str = "narration") -> None:
    """Refuse a narration that would take the story's narrations past
    :data:`MAX_STORY_NARRATION_SECONDS`."""
    others = sum(s.narration.seconds for s in story.scenes if s.narration is not None and s.id != scene_id)
    if others + seconds > MAX_STORY_NARRATION_SECONDS:
        raise NarrationError(f"{where}: this story already has {_seconds_text(others)} of narration; "
                             f"all scenes together may have at most {MAX_STORY_NARRATION_SECONDS:.0f} s")


def store_narration(store: AssetStore, story: Story, scene_id: str, audio: Audio,
                    editor: NarrationEditor | None = None, where: str = "narration") -> Narration:
    """Give scene ``scene_id`` the narration ``audio``: write the WAV as a story asset
    (atomic), then point the scene at it and save the story -- through ``editor`` when
    given (an undoable step; the app's autosave saves it), else directly. See the module
    docstring for why a SIGKILL at any moment loses at most this narration."""
    story.scene(scene_id)  # StoryError for an unknown scene, before anything is written
    check_story_total(story, scene_id, audio.seconds, where)
    wav = encode_wav(audio)
    name = asset_name(wav)
    store.put_asset(story.id, name, wav)
    narration = Narration(name, round(audio.seconds, 6))
    if editor is not None:
        editor.set_narration(scene_id, narration)
    else:
        story.scene(scene_id).narration = narration
        store.save_story(story)
    return narration


def import_narration(store: AssetStore, story: Story, scene_id: str, path: str | Path, start: float = 0.0,
                     end: float | None = None, editor: NarrationEditor | None = None) -> Narration:
    """Read, check and trim an audio file (``start``/``end`` in seconds of the file),
    then :func:`store_narration` it. Any refusal raises :class:`NarrationError` before
    anything is written."""
    audio = read_audio(path)
    if start > 0.0 or end is not None:
        audio = trim(audio, start, end, str(path))
    return store_narration(store, story, scene_id, audio, editor, str(path))


def load_narration(store: AssetStore, story: Story, scene_id: str) -> Audio | None:
    """The decoded narration of a scene (None without one); :class:`NarrationError` when
    its asset is missing or damaged."""
    narration = story.scene(scene_id).narration
    if narration is None:
        return None
    where = f"story {story.id}, narration {narration.asset}"
    try:
        data = store.read_asset(story.id, narration.asset)
    except StoryBeamError as exc:
        raise NarrationError(f"{where}: missing ({exc})") from None
    return decode_audio(data, where)


def referenced_assets(story: Story) -> set[str]:
    """Asset names of the story's narrations (and of its name said aloud, its cover's voice)."""
    names = {s.narration.asset for s in story.scenes if s.narration is not None}
    if story.cover is not None and story.cover.voice is not None:
        names.add(story.cover.voice.asset)
    return names


def prune_narrations(store: AssetStore, story: Story) -> int:
    """Delete the story's narration files that the *saved* ``story`` does not point at
    (replaced or removed voices, a save killed after its file was written); returns how
    many. Call it when a story is opened, before any edit: the undo history of an editing
    session may still point at older voices, so pruning mid-session would break undo."""
    keep = referenced_assets(story)
    removed = 0
    for name in store.asset_names(story.id):
        if name.startswith(ASSET_PREFIX) and name not in keep:
            try:
                store.asset_path(story.id, name).unlink()
                removed += 1
            except OSError:
                pass  # still there: tried again at the next opening
    return removed


def check_package_narrations(story: Story, assets: dict[str, bytes], where: str) -> None:
    """A package's narrations: every referenced asset present, decodable, of the stated
    length (within 1 ms), and the story's total within bounds. Raises
    :class:`NarrationError`."""
    total = 0.0
    for i, scene in enumerate(story.scenes):
        if scene.narration is None:
            continue
        name = scene.narration.asset
        here = f"{where}: scene {i + 1} narration {name}"
        if name not in assets:
            raise NarrationError(f"{here}: missing from the package")
        audio = decode_audio(assets[name], here)
        if abs(audio.seconds - scene.narration.seconds) > 1e-3:
            raise NarrationError(f"{here}: {audio.seconds:.3f} s of audio, the story says "
                                 f"{scene.narration.seconds:.3f} s")
        total += audio.seconds
    if total > MAX_STORY_NARRATION_SECONDS:
        raise NarrationError(f"{where}: {_seconds_text(total)} of narration; a story may have at most "
                             f"{MAX_STORY_NARRATION_SECONDS:.0f} s")


__all__ = ["AssetStore", "NarrationEditor", "ACCEPTED_RATES", "MIN_NARRATION_SECONDS", "MAX_NARRATION_FILE_BYTES", "MAX_STORY_NARRATION_SECONDS",
           "MAX_CHANNELS", "ASSET_PREFIX", "NarrationError", "Audio", "decode_audio", "read_audio", "trim",
           "encode_wav", "asset_name", "check_story_total", "store_narration", "import_narration", "load_narration",
           "referenced_assets", "prune_narrations", "check_package_narrations"]
