"""Spoken prompts: the sentence of a notice said aloud, for a child who cannot read it.

Method. One :class:`Speaker` per app, chosen once by :func:`find_speaker`:

* **Android** -- the platform's ``android.speech.tts.TextToSpeech`` through pyjnius,
  created on first use; each prompt is ``speak(text, QUEUE_FLUSH, None, id)`` after
  ``setLanguage(Locale(lang))``. Untested here (no tablet): see docs/guide/app.md.
* **Desktop** -- `espeak-ng <https://github.com/espeak-ng/espeak-ng>`_ (or the older
  ``espeak``) when it is on ``PATH``: started as a child process with the language's
  voice, never waited for, the previous prompt stopped first so prompts never pile up.
* **Neither** -- :class:`SilentSpeaker`: nothing is said, nothing fails.

A prompt never blocks the UI and never raises: speech is a help, not a dependency.
"""
from __future__ import annotations

import logging
import shutil
import subprocess
from typing import Callable, Protocol

log = logging.getLogger(__name__)

#: espeak-ng voice per app language
ESPEAK_VOICES = {"en": "en-us", "ja": "ja"}


class Speaker(Protocol):
    """Says a short sentence in a language (``en``, ``ja``); returns at once."""

    name: str

    def say(self, text: str, lang: str) -> None: ...


class SilentSpeaker:
    """No speech on this device: prompts are only shown."""

    name = "none"

    def say(self, text: str, lang: str) -> None:
        return None


class EspeakSpeaker:
    """espeak-ng (or espeak) as a child process; a new prompt stops the one before."""

    def __init__(self, program: str, popen: Callable[..., subprocess.Popen] = subprocess.Popen):
        self.program, self.name, self._popen = program, program.rsplit("/", 1)[-1], popen
        self._proc: subprocess.Popen | None = None

    def command(self, text: str, lang: str) -> list[str]:
        return [self.program, "-v", ESPEAK_VOICES.get(lang, lang), "-s", "150", "--", text]

    def say(self, text: str, lang: str) -> None:
        if self._proc is not None and self._proc.poll() is None:
            self._proc.terminate()
        try:
            self._proc = self._popen(self.command(text, lang), stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
        except OSError as exc:
            log.warning("speech: %s cannot start (%s)", self.program, exc)
            self._proc = None


class AndroidSpeaker:  # pragma: no cover - needs an Android device
    """Android's TextToSpeech through pyjnius (created on first use)."""

    name = "android"

    def __init__(self):
        self._tts = None

    def say(self, text: str, lang: str) -> None:
        try:
            from jnius import autoclass  # optional: pyjnius (Android only)
            if self._tts is None:
                activity = autoclass("org.kivy.android.PythonActivity").mActivity
                self._tts = autoclass("android.speech.tts.TextToSpeech")(activity, None)
            self._tts.setLanguage(autoclass("java.util.Locale")(lang))
            self._tts.speak(text, 0, None, "storybeam")  # 0: QUEUE_FLUSH
        except Exception as exc:  # noqa: BLE001 - speech must never break the app
            log.warning("speech: TextToSpeech failed (%s)", exc)


def find_speaker(platform: str, which: Callable[[str], str | None] = shutil.which) -> Speaker:
    """The speaker this device has: Android's TextToSpeech, espeak-ng/espeak on a
    desktop, else silence."""
    if platform == "android":
        return AndroidSpeaker()
    for program in ("espeak-ng", "espeak"):
        path = which(program)
        if path:
            return EspeakSpeaker(path)
    return SilentSpeaker()
