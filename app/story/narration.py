"""A scene's voice: checking, decoding, trimming and storing narration audio.

Method. Whatever comes in (an imported WAV or OGG file, a finished recording, a
package's asset) is decoded to 16-bit mono PCM and checked *before* anything is stored:

1. **Size first.** A file larger than :data:`MAX_NARRATION_FILE_BYTES` is refused from its
   ``stat`` alone, so an enormous file is never read into memory.
2. **Format by content, not by name.** ``RIFF....WAVE`` is read with the standard
   library's :mod:`wave` (integer PCM, 8/16/24/32 bit, mono or stereo) -- IEEE float
   (32/64 bit, Audacity's default), which :mod:`wave` refuses, from its chunks; ``OggS`` with
   `soundfile <https://python-soundfile.readthedocs.io>`_ (libsndfile: Vorbis, Opus,
   FLAC-in-Ogg), an optional dependency -- without it an OGG file is refused with a
   message saying so. Anything else is "not a WAV or OGG file".
3. **Header limits before decoding.** The declared rate must be one of
   :data:`ACCEPTED_RATES` (telephone 8 kHz to studio 48 kHz: anything else is a wrong or
   damaged header), and the declared length at most :data:`MAX_NARRATION_SECONDS` (an
   import: :data:`MAX_IMPORT_SECONDS`, trimmed before it is kept), so a header announcing
   hours of audio is refused before its samples are read.
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
#: Largest audio file decoded (bytes), checked before reading: stored narrations and a
#: package's are far smaller (16-bit mono, at most 11.5 MB).
MAX_NARRATION_FILE_BYTES = 16 * 1024 * 1024
#: Largest file accepted for *import* (bytes): a long or float WAV (Audacity's default,
#: 32-bit float stereo at 44.1 kHz: 353 kB/s) is imported whole and trimmed before it is
#: kept, so the limit covers about 3 minutes of that format.
MAX_IMPORT_FILE_BYTES = 64 * 1024 * 1024
#: Longest audio accepted for import (seconds): the child trims it to at most
#: :data:`MAX_NARRATION_SECONDS` before it is kept.
MAX_IMPORT_SECONDS = 600.0
#: All narrations of one story together (seconds): keeps every narrated story packable.
MAX_STORY_NARRATION_SECONDS = 600.0
MAX_CHANNELS = 2
ASSET_PREFIX = "narration-"


class NarrationError(StoryBeamError):
    """Audio that cannot be a scene's narration; the message names the file and why.

    ``kind`` says what went wrong in one word, for the picture a child is shown instead of
    the message (:mod:`app.ui.notices`): ``unreadable`` (not audio we can decode, damaged),
    ``too_long`` (longer than a scene's narration may be: trim it), ``too_big`` (the file
    itself), ``silent`` (nothing recorded), ``too_short``, ``story_full`` (the story's
    narrations together), ``missing`` (a stored voice that is gone)."""

    def __init__(self, message: str, kind: str = "unreadable"):
        super().__init__(message)
        self.kind = kind


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


def _check_header(where: str, rate: int, channels: int, frames: int,
                  max_seconds: float = MAX_NARRATION_SECONDS) -> None:
    if rate not in ACCEPTED_RATES:
        raise NarrationError(f"{where}: sample rate {rate} Hz is not supported "
                             f"(use one of {', '.join(str(r) for r in ACCEPTED_RATES)} Hz)")
    if not 1 <= channels <= MAX_CHANNELS:
        raise NarrationError(f"{where}: {channels} channels; narration must be mono or stereo")
    if frames <= 0:
        raise NarrationError(f"{where}: the audio is empty (no samples)", "silent")
    if frames / rate > max_seconds:
        raise NarrationError(f"{where}: {_seconds_text(frames / rate)} long; at most {max_seconds:.0f} s "
                             f"can be {'imported' if max_seconds > MAX_NARRATION_SECONDS else 'a narration'}",
                             "too_long")


def _finish(where: str, mono: np.ndarray, rate: int) -> Audio:
    """Checks on the decoded samples (length, silence) and the :class:`Audio`."""
    samples = np.ascontiguousarray(mono, dtype=np.int16)
    if len(samples) / rate < MIN_NARRATION_SECONDS:
        raise NarrationError(f"{where}: only {len(samples) / rate * 1000:.0f} ms of audio; "
                             f"a narration needs at least {MIN_NARRATION_SECONDS * 1000:.0f} ms", "too_short")
    if not np.any(samples):
        raise NarrationError(f"{where}: the audio is empty (silence only; is the microphone on?)", "silent")
    return Audio(samples, rate)


#: WAVE format tags (the ``fmt `` chunk's first field): integer PCM, IEEE float, and
#: WAVE_FORMAT_EXTENSIBLE, whose sub-format GUID starts with one of the other two.
_WAVE_PCM, _WAVE_FLOAT, _WAVE_EXTENSIBLE = 1, 3, 0xFFFE


def _wav_chunks(data: bytes) -> dict[bytes, tuple[int, int]]:
    """The RIFF/WAVE chunks of ``data``: id -> (offset of its body, declared size); the
    first of each id. Stops at a chunk that runs past the end (kept: a cut data chunk)."""
    chunks: dict[bytes, tuple[int, int]] = {}
    pos = 12
    while pos + 8 <= len(data):
        cid, size = data[pos:pos + 4], int.from_bytes(data[pos + 4:pos + 8], "little")
        chunks.setdefault(cid, (pos + 8, size))
        pos += 8 + size + (size & 1)
    return chunks


def _wav_format_tag(data: bytes) -> int | None:
    """The format tag of a RIFF/WAVE byte string (the extensible tag resolved to its
    sub-format), or None when no complete ``fmt `` chunk is found. Read here because
    :mod:`wave` (Python 3.11) rejects IEEE float outright ("unknown format: 3")."""
    body, size = _wav_chunks(data).get(b"fmt ", (0, 0))
    if size < 16 or body + size > len(data):
        return None
    tag = int.from_bytes(data[body:body + 2], "little")
    if tag == _WAVE_EXTENSIBLE and size >= 26:
        tag = int.from_bytes(data[body + 24:body + 26], "little")  # the sub-format GUID's first two bytes
    return tag


def _decode_float_wav(data: bytes, where: str, max_seconds: float) -> Audio:
    """An IEEE-float WAV (32 or 64 bit; plain or extensible header -- Audacity's default
    export): the ``fmt `` and ``data`` chunks read directly, samples in [-1, 1] scaled to
    16 bit (NaN as silence, out-of-range values clipped), channels averaged."""
    chunks = _wav_chunks(data)
    body, _ = chunks[b"fmt "]
    channels = int.from_bytes(data[body + 2:body + 4], "little")
    rate = int.from_bytes(data[body + 4:body + 8], "little")
    bits = int.from_bytes(data[body + 14:body + 16], "little")
    if bits not in (32, 64):
        raise NarrationError(f"{where}: {bits}-bit float samples are not supported")
    if b"data" not in chunks:
        raise NarrationError(f"{where}: not a readable WAV file (no data chunk)")
    start, size = chunks[b"data"]
    width = bits // 8
    frames = size // (width * max(channels, 1))
    _check_header(where, rate, channels, frames, max_seconds)
    raw = data[start:start + frames * channels * width]
    if len(raw) != frames * channels * width:
        raise NarrationError(f"{where}: the WAV file is damaged or cut short "
                             f"({len(raw) // (channels * width)} of {frames} frames present)")
    block = np.frombuffer(raw, "<f4" if bits == 32 else "<f8").reshape(frames, channels)
    mono = np.nan_to_num(block.astype(np.float64).mean(axis=1), nan=0.0, posinf=1.0, neginf=-1.0)
    return _finish(where, np.clip(np.round(mono * 32767.0), -32768, 32767), rate)


def _decode_wav(data: bytes, where: str, max_seconds: float = MAX_NARRATION_SECONDS) -> Audio:
    if _wav_format_tag(data) == _WAVE_FLOAT:
        return _decode_float_wav(data, where, max_seconds)
    try:
        with wave.open(io.BytesIO(data), "rb") as wf:
            rate, channels, width, frames = wf.getframerate(), wf.getnchannels(), wf.getsampwidth(), wf.getnframes()
            _check_header(where, rate, channels, frames, max_seconds)
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


def _decode_ogg(data: bytes, where: str, max_seconds: float = MAX_NARRATION_SECONDS) -> Audio:
    try:
        import soundfile  # optional: soundfile/libsndfile (desktop; absent on Android)
    except (ImportError, OSError):
        raise NarrationError(f"{where}: OGG files cannot be read on this device (soundfile is not installed); "
                             "use a WAV file") from None
    try:
        with soundfile.SoundFile(io.BytesIO(data)) as sf:
            _check_header(where, int(sf.samplerate), int(sf.channels), int(sf.frames), max_seconds)
            frames, channels, rate = int(sf.frames), int(sf.channels), int(sf.samplerate)
            block = sf.read(frames, dtype="int16", always_2d=True)
    except (RuntimeError, soundfile.LibsndfileError, ValueError, TypeError) as exc:
        reason = str(exc).rsplit(": ", 1)[-1]  # libsndfile's reason, without the repr of our buffer
        raise NarrationError(f"{where}: not a readable OGG file ({reason})") from None
    if block.shape[0] != frames or block.shape[1] != channels:
        raise NarrationError(f"{where}: the OGG file is damaged or cut short "
                             f"({block.shape[0]} of {frames} frames decoded)")
    return _finish(where, np.round(block.astype(np.float64).mean(axis=1)), rate)


def decode_audio(data: bytes, where: str, max_seconds: float = MAX_NARRATION_SECONDS,
                 max_bytes: int = MAX_NARRATION_FILE_BYTES) -> Audio:
    """Decode and check narration bytes (WAV -- integer PCM or IEEE float -- or OGG, told
    apart by content); ``where`` names the source in messages. ``max_seconds`` and
    ``max_bytes`` default to a stored narration's limits (an import passes its larger
    ones). Raises :class:`NarrationError`."""
    if len(data) > max_bytes:
        raise NarrationError(f"{where}: {len(data) / 2**20:.1f} MB; an audio file may be at most "
                             f"{max_bytes // 2**20} MB", "too_big")
    if not data:
        raise NarrationError(f"{where}: the file is empty", "silent")
    if data[:4] == b"RIFF" and data[8:12] == b"WAVE":
        return _decode_wav(data, where, max_seconds)
    if data[:4] == b"OggS":
        return _decode_ogg(data, where, max_seconds)
    raise NarrationError(f"{where}: not a WAV or OGG audio file")


def read_audio(path: str | Path) -> Audio:
    """Read and check an audio file to import (size checked before reading). It may be
    up to :data:`MAX_IMPORT_SECONDS` long: :func:`trim` cuts the part to keep, and
    :func:`store_narration` refuses anything still over :data:`MAX_NARRATION_SECONDS`."""
    path = Path(path)
    try:
        size = os.stat(path).st_size
        if size > MAX_IMPORT_FILE_BYTES:
            raise NarrationError(f"{path}: {size / 2**20:.1f} MB; an audio file may be at most "
                                 f"{MAX_IMPORT_FILE_BYTES // 2**20} MB", "too_big")
        data = path.read_bytes()
    except OSError as exc:
        raise NarrationError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    return decode_audio(data, str(path), MAX_IMPORT_SECONDS, MAX_IMPORT_FILE_BYTES)


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
                             f"all scenes together may have at most {MAX_STORY_NARRATION_SECONDS:.0f} s", "story_full")


def store_narration(store: AssetStore, story: Story, scene_id: str, audio: Audio,
                    editor: NarrationEditor | None = None, where: str = "narration") -> Narration:
    """Give scene ``scene_id`` the narration ``audio``: write the WAV as a story asset
    (atomic), then point the scene at it and save the story -- through ``editor`` when
    given (an undoable step; the app's autosave saves it), else directly. See the module
    docstring for why a SIGKILL at any moment loses at most this narration."""
    story.scene(scene_id)  # StoryError for an unknown scene, before anything is written
    if audio.seconds > MAX_NARRATION_SECONDS + 1e-9:
        raise NarrationError(f"{where}: {_seconds_text(audio.seconds)} long; a scene's narration may be at most "
                             f"{MAX_NARRATION_SECONDS:.0f} s: trim it", "too_long")
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
        raise NarrationError(f"{where}: missing ({exc})", "missing") from None
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


__all__ = ["AssetStore", "NarrationEditor", "ACCEPTED_RATES", "MIN_NARRATION_SECONDS", "MAX_NARRATION_FILE_BYTES",
           "MAX_IMPORT_FILE_BYTES", "MAX_IMPORT_SECONDS", "MAX_STORY_NARRATION_SECONDS",
           "MAX_CHANNELS", "ASSET_PREFIX", "NarrationError", "Audio", "decode_audio", "read_audio", "trim",
           "encode_wav", "asset_name", "check_story_total", "store_narration", "import_narration", "load_narration",
           "referenced_assets", "prune_narrations", "check_package_narrations"]
