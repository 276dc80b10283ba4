"""The story's ending, as numbers: the celebration's sound and its confetti.

Shared by Play (the Kivy celebration when a story finishes, :mod:`app.ui.play`) and the
story film's ending card (:mod:`app.player.cards`), so the two look and sound alike.

* :func:`chime` -- a short rising arpeggio (C5 E5 G5 C6, then the chord), each note a sine
  with two quiet overtones under a bell envelope (5 ms attack, exponential decay), int16 mono;
  synthesised, so no sound file is shipped or licensed.
* :func:`confetti` -- ``n`` pieces bursting from a point and falling under gravity with a
  little flutter: positions (unit square, y up), colours and spins at time ``t``; a fixed
  seed makes it the same on every run (tests, screenshots).

numpy only: safe on Android and at start-up.
"""
from __future__ import annotations

import io
import wave

import numpy as np

#: the celebration's length (seconds): the Play animation and the film's ending card
CELEBRATION_SECONDS = 2.5
#: bright, child-friendly confetti colours (RGB 0..255)
CONFETTI_COLOURS = ((255, 89, 94), (255, 202, 58), (138, 201, 38), (25, 130, 196), (106, 76, 147),
                    (255, 146, 76), (255, 112, 166))
_NOTES_HZ = (523.25, 659.25, 783.99, 1046.5)


def chime(rate: int = 48000, volume: float = 0.5) -> np.ndarray:
    """The celebration sound: int16 mono samples at ``rate`` (about 1.6 s)."""
    step = 0.14
    total = int(rate * (step * len(_NOTES_HZ) + 1.0))
    out = np.zeros(total, np.float64)

    def bell(freq: float, start: float, seconds: float, gain: float) -> None:
        n = int(rate * seconds)
        t = np.arange(n) / rate
        env = np.minimum(t / 0.005, 1.0) * np.exp(-t * 4.0)
        tone = np.sin(2 * np.pi * freq * t) + 0.3 * np.sin(4 * np.pi * freq * t) + 0.1 * np.sin(6 * np.pi * freq * t)
        a = int(rate * start)
        out[a:a + n] += gain * env * tone[: total - a]

    for i, f in enumerate(_NOTES_HZ):
        bell(f, i * step, 0.6, 0.35)
    for f in _NOTES_HZ:  # the final chord
        bell(f, len(_NOTES_HZ) * step, 1.0, 0.25)
    out *= volume / max(float(np.abs(out).max()), 1e-9)
    return np.round(out * 32767).astype(np.int16)


def chime_wav(rate: int = 48000) -> bytes:
    """:func:`chime` as a WAV file's bytes (16-bit mono)."""
    buf = io.BytesIO()
    with wave.open(buf, "wb") as wf:
        wf.setnchannels(1)
        wf.setsampwidth(2)
        wf.setframerate(rate)
        wf.writeframes(chime(rate).astype("<i2").tobytes())
    return buf.getvalue()


def confetti(t: float, n: int = 90, seed: int = 7, origin: tuple[float, float] = (0.5, 0.35)) -> dict[str, np.ndarray]:
    """The confetti at ``t`` seconds after the burst: ``xy`` (n, 2) in the unit square (y
    up; pieces may leave it), ``colour`` (n, 3) uint8, ``angle`` (n,) radians, ``size`` (n,)
    as a fraction of the picture's height. Each piece leaves ``origin`` with a random
    upward velocity and falls under gravity with air drag and a sideways flutter."""
    rng = np.random.default_rng(seed)
    heading = rng.uniform(np.radians(20), np.radians(160), n)
    speed = rng.uniform(0.6, 1.5, n)
    v0 = np.stack([np.cos(heading) * speed * 0.8, np.sin(heading) * speed], 1)
    drag, g = 2.2, 1.1
    t = max(float(t), 0.0)
    k = (1 - np.exp(-drag * t)) / drag  # the integral of exp(-drag t): velocity decays
    fall = g / drag * (t - k)  # terminal fall reached gradually
    phase = rng.uniform(0, 2 * np.pi, n)
    flutter = 0.03 * np.sin(6.0 * t + phase) * min(t, 1.0)
    xy = np.asarray(origin, np.float64) + v0 * k + np.stack([flutter, -fall * np.ones(n)], 1)
    colour = np.asarray(CONFETTI_COLOURS, np.uint8)[rng.integers(0, len(CONFETTI_COLOURS), n)]
    angle = phase + rng.uniform(-8, 8, n) * t
    size = rng.uniform(0.012, 0.026, n)
    return {"xy": xy, "colour": colour, "angle": angle, "size": size}


__all__ = ["CELEBRATION_SECONDS", "CONFETTI_COLOURS", "chime", "chime_wav", "confetti"]
