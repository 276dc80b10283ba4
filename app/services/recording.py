"""Recording a scene's narration from a microphone, crash-safely, without Kivy.

Backends, chosen by :func:`find_recorder` (each an established binding, imported only
when it is used):

* **Android** -- the platform's ``android.media.AudioRecord`` (16-bit mono PCM) through
  `pyjnius <https://pyjnius.readthedocs.io>`_, which python-for-android ships with every
  Kivy app; the ``RECORD_AUDIO`` permission is asked for at run time with p4a's
  ``android.permissions``. (AudioRecord rather than MediaRecorder: MediaRecorder writes
  AMR/AAC, which StoryBeam could not check or play back without a decoder on the tablet;
  AudioRecord gives the PCM that is stored as WAV directly.)
* **Desktop** -- `sounddevice <https://python-sounddevice.readthedocs.io>`_ (PortAudio),
  when it is installed *and* an input device exists; otherwise no backend, and
  :func:`find_recorder` says why (the UI hides the record button and shows the reason).

Method. Every backend is a *chunk source* (``read() -> int16 array``, blocking for at
most a fraction of a second); :class:`ChunkRecorder` pulls chunks on a worker thread and
appends them to a ``.wav.part`` file in the profile's recording folder (outside every
story's assets). Nothing points at that file: a SIGKILL while recording leaves a
half-written ``.part`` file that :func:`discard_stale` removes on the next start, and the
story is untouched. Only :meth:`ChunkRecorder.stop` closes the file into a complete WAV,
which the caller then checks and stores with :func:`app.story.narration.store_narration`
(atomic asset write, then one SQLite transaction). Recording stops by itself at
:data:`app.story.MAX_NARRATION_SECONDS`.
"""
from __future__ import annotations

import os
import threading
import time
import uuid
import wave
from pathlib import Path
from typing import Callable, Protocol

import numpy as np

from app.story import MAX_NARRATION_SECONDS
from retrieval.errors import StoryBeamError

#: Rate the microphone is recorded at (Hz): plenty for a voice, and accepted everywhere.
RECORD_RATE = 22050
CHUNK_SECONDS = 0.1
PART_SUFFIX = ".wav.part"


class RecordingError(StoryBeamError):
    """The microphone could not be used; the message says why."""


class ChunkSource(Protocol):
    """A microphone: ``open()``, then ``read()`` mono int16 chunks, then ``close()``."""

    rate: int

    def open(self) -> None: ...

    def read(self) -> np.ndarray: ...

    def close(self) -> None: ...


def discard_stale(folder: str | Path) -> int:
    """Remove recordings a crash left unfinished (``*.wav.part``); returns how many."""
    n = 0
    folder = Path(folder)
    if folder.is_dir():
        for part in folder.glob("*" + PART_SUFFIX):
            try:
                part.unlink()
                n += 1
            except OSError:
                pass
    return n


class ChunkRecorder:
    """Record from a :class:`ChunkSource` into a WAV file in ``folder`` on a worker thread.

    ``start()``, then ``stop() -> Path`` (the finished WAV) or ``cancel()``. ``seconds``
    is the length so far; ``on_limit`` is called (from the worker) when the length limit
    stopped the recording."""

    def __init__(self, source: ChunkSource, folder: str | Path, limit_seconds: float = MAX_NARRATION_SECONDS,
                 on_limit: Callable[[], None] | None = None):
        self.source, self.folder = source, Path(folder)
        self.limit_frames = int(limit_seconds * source.rate)
        self.on_limit = on_limit
        self.frames = 0
        self.error: str | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._wav: wave.Wave_write | None = None
        self.part: Path | None = None

    @property
    def seconds(self) -> float:
        return self.frames / self.source.rate

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        self.part = self.folder / f"rec-{uuid.uuid4().hex[:12]}{PART_SUFFIX}"
        self.source.open()
        wav = wave.open(str(self.part), "wb")
        wav.setnchannels(1)
        wav.setsampwidth(2)
        wav.setframerate(self.source.rate)
        self._wav = wav
        self._thread = threading.Thread(target=self._run, name="storybeam-recorder", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                chunk = np.asarray(self.source.read(), dtype=np.int16).reshape(-1)
                room = self.limit_frames - self.frames
                chunk = chunk[:room]
                if len(chunk):
                    self._wav.writeframesraw(chunk.astype("<i2").tobytes())
                    self.frames += len(chunk)
                if self.frames >= self.limit_frames:
                    if self.on_limit:
                        self.on_limit()
                    break
        except Exception as exc:  # noqa: BLE001 - a device error ends the recording with a message
            self.error = f"the microphone stopped ({type(exc).__name__}: {exc})"

    def _finish(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        try:
            self.source.close()
        finally:
            if self._wav is not None:
                self._wav.close()  # writes the final header
                self._wav = None

    def stop(self) -> Path:
        """Finish the recording; the complete WAV's path (``rec-*.wav`` in ``folder``)."""
        self._finish()
        if self.error:
            self.cancel()
            raise RecordingError(self.error)
        assert self.part is not None
        done = self.part.with_name(self.part.name[: -len(".part")])
        with open(self.part, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(self.part, done)
        return done

    def cancel(self) -> None:
        """Stop and throw the recording away."""
        self._finish()
        if self.part is not None:
            self.part.unlink(missing_ok=True)


# -- desktop: sounddevice -------------------------------------------------------------------
class SoundDeviceSource:
    """The default input device through sounddevice (PortAudio), mono int16."""

    def __init__(self, rate: int = RECORD_RATE):
        import sounddevice  # optional: sounddevice (desktop only; checked by find_recorder)

        self._sd, self.rate, self._stream = sounddevice, rate, None

    def open(self) -> None:
        self._stream = self._sd.InputStream(samplerate=self.rate, channels=1, dtype="int16",
                                            blocksize=int(self.rate * CHUNK_SECONDS))
        self._stream.start()

    def read(self) -> np.ndarray:
        data, _overflowed = self._stream.read(int(self.rate * CHUNK_SECONDS))
        return np.asarray(data).reshape(-1)

    def close(self) -> None:
        if self._stream is not None:
            self._stream.stop()
            self._stream.close()
            self._stream = None


# -- Android: AudioRecord through pyjnius -------------------------------------------------------
class AndroidSource:
    """``android.media.AudioRecord`` (MIC, mono, 16-bit PCM) through pyjnius.

    Written against the Android API (AudioRecord, API level 3+); it needs a device to run
    and is not exercised by the desktop tests."""

    def __init__(self, rate: int = RECORD_RATE):
        from jnius import autoclass  # optional: pyjnius (Android only; checked by find_recorder)

        self._AudioRecord = autoclass("android.media.AudioRecord")
        self._AudioFormat = autoclass("android.media.AudioFormat")
        self._Source = autoclass("android.media.MediaRecorder$AudioSource")
        self.rate, self._rec = rate, None
        self._n = int(rate * CHUNK_SECONDS)

    def open(self) -> None:
        fmt = self._AudioFormat
        minimum = self._AudioRecord.getMinBufferSize(self.rate, fmt.CHANNEL_IN_MONO, fmt.ENCODING_PCM_16BIT)
        if minimum <= 0:
            raise RecordingError(f"this tablet cannot record at {self.rate} Hz")
        self._rec = self._AudioRecord(self._Source.MIC, self.rate, fmt.CHANNEL_IN_MONO, fmt.ENCODING_PCM_16BIT,
                                      max(minimum, 4 * self._n))
        if self._rec.getState() != self._AudioRecord.STATE_INITIALIZED:
            self._rec.release()
            self._rec = None
            raise RecordingError("the microphone is busy or not allowed")
        self._rec.startRecording()

    def read(self) -> np.ndarray:
        buf = [0] * self._n  # pyjnius passes a Python list as short[] and copies it back
        got = self._rec.read(buf, 0, self._n)
        if got < 0:
            raise RecordingError(f"AudioRecord.read failed ({got})")
        return np.asarray(buf[:got], dtype=np.int16)

    def close(self) -> None:
        if self._rec is not None:
            self._rec.stop()
            self._rec.release()
            self._rec = None


def on_android() -> bool:
    return "ANDROID_ARGUMENT" in os.environ or "ANDROID_PRIVATE" in os.environ


def _android_permission() -> str | None:
    """None when RECORD_AUDIO is granted; else ask for it and say so."""
    try:
        from android.permissions import Permission, check_permission, request_permissions  # optional: p4a (Android only)
    except ImportError:
        return None  # an old p4a without runtime permissions: the manifest grant applies
    if check_permission(Permission.RECORD_AUDIO):
        return None
    request_permissions([Permission.RECORD_AUDIO])
    return "allow the microphone, then tap record again"


def find_recorder() -> tuple[Callable[[], ChunkSource] | None, str]:
    """``(make_source, "")`` when this device can record, else ``(None, reason)``."""
    if on_android():
        try:
            import jnius  # noqa: F401  # optional: pyjnius (Android only)
        except ImportError as exc:
            return None, f"pyjnius is missing ({exc})"
        why = _android_permission()
        if why:
            return None, why
        return AndroidSource, ""
    try:
        import sounddevice  # optional: sounddevice (desktop recording; absent -> no record button)
    except (ImportError, OSError) as exc:  # OSError: the package is there but PortAudio is not
        return None, f"no audio library for recording (sounddevice: {exc})"
    try:
        sounddevice.query_devices(kind="input")
    except Exception as exc:  # noqa: BLE001 - PortAudio reports "no device" in several ways
        return None, f"no microphone found ({exc})"
    return SoundDeviceSource, ""


class ArraySource:
    """A :class:`ChunkSource` that plays back samples at real time (tests, demos): the
    recorder path without a microphone."""

    def __init__(self, samples: np.ndarray, rate: int, realtime: bool = True):
        self.samples, self.rate, self.realtime = np.asarray(samples, np.int16), rate, realtime
        self._at = 0

    def open(self) -> None:
        self._at = 0

    def read(self) -> np.ndarray:
        n = int(self.rate * CHUNK_SECONDS)
        if self.realtime:
            time.sleep(CHUNK_SECONDS)
        chunk = self.samples[self._at:self._at + n]
        self._at += n
        if not len(chunk):
            time.sleep(CHUNK_SECONDS / 4)  # past the end: a quiet room
            return np.zeros(n, np.int16)
        return chunk

    def close(self) -> None:
        pass


__all__ = ["RECORD_RATE", "RecordingError", "ChunkSource", "ChunkRecorder", "SoundDeviceSource", "AndroidSource",
           "ArraySource", "find_recorder", "discard_stale", "on_android", "PART_SUFFIX"]
