"""The story film (issue 29): the video a child takes home shows the story -- its places,
its characters large on their paths, title and ending cards, the voice and the chime."""
from __future__ import annotations

import os
import subprocess
import wave
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from app.player.cards import CURTAIN, HEART, PLACES, card_frames, ending_card, title_card  # noqa: E402
from app.player.celebration import chime, confetti  # noqa: E402
from app.player.story_film import FILM_CHARACTER_HEIGHT_M, FRAME_MARGIN, frame_camera  # noqa: E402
from app.player.video_export import AUDIO_RATE, frame_count, story_audio  # noqa: E402
from app.story import Cover, Narration, demo_story, encode_wav, read_audio  # noqa: E402


def near(img: np.ndarray, colour, tol: int = 30) -> np.ndarray:
    return np.all(np.abs(img.astype(int) - np.asarray(colour, int)) <= tol, axis=-1)


def test_the_camera_keeps_every_character_in_the_picture_and_large():
    """Two characters walking apart, one standing: every frame, every corner of every
    character's box projects inside the frame margin, and a lone character is big."""
    fps, size = 30.0, (640, 360)
    n = 90
    u = np.linspace(0, 1, n)[:, None]
    hips = np.stack([np.hstack([-0.1 - 0.4 * u, 0.15 + 0 * u, 0 * u]),
                     np.hstack([0.1 + 0.3 * u, 0.15 + 0 * u, 0.2 * u])], axis=1)
    shot = frame_camera(hips, FILM_CHARACTER_HEIGHT_M, fps, size)
    h = FILM_CHARACTER_HEIGHT_M
    for i in range(n):
        view = shot.view(i, *size)
        for c in range(2):
            ground = hips[i, c] * [1, 0, 1]
            box = np.array([ground + [dx, dy, dz] for dx in (-0.3 * h, 0.3 * h) for dy in (0, h)
                            for dz in (-0.3 * h, 0.3 * h)])
            uv = view.project(box)
            assert np.all(uv[:, 0] >= 0) and np.all(uv[:, 0] < size[0]), i
            assert np.all(uv[:, 1] >= 0) and np.all(uv[:, 1] < size[1]), i
    # one character: it fills a large part of the picture's height
    lone = frame_camera(hips[:, :1], h, fps, size)
    view = lone.view(45, *size)
    ground = hips[45, 0] * [1, 0, 1]
    top, foot = view.project(np.array([ground + [0, h, 0], ground]))
    assert (foot[1] - top[1]) / size[1] > 0.45
    assert FRAME_MARGIN[1] < 1


def test_title_and_ending_cards_are_pictures_of_the_story():
    story = demo_story()
    size = (320, 180)
    lead, tail = card_frames(30.0)
    first = title_card(story, 0, lead, size)
    assert near(first, CURTAIN, 10).mean() > 0.7  # the curtain, closed
    opened = title_card(story, lead - 1, lead, size)
    assert near(opened, CURTAIN, 10).mean() < 0.1
    assert near(opened, PLACES["grass"].ground, 5).mean() > 0.1  # the first place
    story.cover = Cover("robot", 3)
    covered = title_card(story, lead - 1, lead, size)
    assert near(covered, (138, 201, 38), 5).sum() > 200  # the cover's colour ring
    last = ending_card(story, tail - 1, tail, size)
    assert near(last, HEART, 10).mean() > 0.03 and near(last, CURTAIN, 10).mean() > 0.5
    middle = ending_card(story, tail // 2, tail, size)
    assert near(middle, PLACES["space"].sky_top, 20).mean() > 0.05  # the last place, confetti over it


def test_confetti_falls_and_the_chime_rings():
    a, b = confetti(0.2), confetti(2.0)
    assert b["xy"][:, 1].mean() < a["xy"][:, 1].mean()
    sound = chime(48000)
    assert 1.0 < len(sound) / 48000 < 2.5 and np.abs(sound).max() > 10000


def test_the_film_sound_track_places_voice_and_chime(tmp_path):
    story = demo_story()
    audio = read_audio(_tone(tmp_path / "v.wav", 1.5))
    (tmp_path / "voice.wav").write_bytes(encode_wav(audio))
    story.scenes[1].narration = Narration("voice.wav", 1.5)
    fps = 30.0
    track, problems = story_audio(story, fps, tmp_path, film=True)
    assert not problems
    assert len(track) == round(frame_count(story, fps, "story") * AUDIO_RATE / fps)
    lead, tail = card_frames(fps)
    start = (lead + round(story.scenes[0].duration * fps)) / fps
    rms = lambda a, b: float(np.sqrt(np.mean(track[int(a * AUDIO_RATE):int(b * AUDIO_RATE)].astype(float) ** 2)))
    assert rms(start + 0.1, start + 1.4) > 3000  # the voice, from its scene's first frame
    assert rms(0, start - 0.05) == 0  # title card and scene 1: silent
    assert rms(start + 1.55, start + 2.9) == 0
    end = len(track) / AUDIO_RATE
    assert rms(end - tail / fps, end - tail / fps + 1.0) > 3000  # the chime on the ending card


def _tone(path: Path, seconds: float, rate: int = 16000) -> Path:
    t = np.arange(int(seconds * rate)) / rate
    with wave.open(str(path), "wb") as wf:
        wf.setnchannels(1)
        wf.setsampwidth(2)
        wf.setframerate(rate)
        wf.writeframes((0.4 * 32767 * np.sin(2 * np.pi * 330 * t)).astype("<i2").tobytes())
    return path


@pytest.mark.slow  # renders and encodes a whole (small) film: about a minute
def test_the_demo_story_film_shows_its_places_and_characters(tmp_path):
    """`storybeam export-video --demo-story --narration ...` at a small size: the title
    card opens the video, each scene's middle frame shows its place's sky and ground and
    a large share of character pixels, the ending card closes it, and the sound track
    holds the narration where the first scene starts."""
    import imageio.v2 as imageio
    import imageio_ffmpeg

    from app.cli import main

    voice = _tone(tmp_path / "voice.wav", 2.0)
    out = tmp_path / "film.mp4"
    fps, size = 10.0, (320, 180)
    assert main(["export-video", "--demo-story", "--narration", str(voice), "--out", str(out),
                 "--fps", str(fps), "--size", "320x180"]) == 0
    story = demo_story()
    frames = [f for f in imageio.get_reader(out)]
    assert frames[0].shape == (size[1], size[0], 3)
    assert len(frames) == frame_count(story, fps, "story")
    lead, tail = card_frames(fps)
    assert near(frames[0], CURTAIN, 25).mean() > 0.6
    assert near(frames[-1], HEART, 30).mean() > 0.02
    start = lead
    for scene in story.scenes:
        n = round(scene.duration * fps)
        frame = frames[start + n // 2]
        p = PLACES[scene.background]
        top = frame[: size[1] // 8]
        assert near(top, p.sky_top, 30).mean() > 0.3, scene.background  # the place's sky
        ground = np.median(frame[-size[1] // 10:].reshape(-1, 3), axis=0)
        sky = near(frame, p.sky_top, 40) | near(frame, p.sky_horizon, 40) | near(frame, (255, 255, 255), 30)
        figure = ~sky & ~near(frame, ground, 45)
        assert figure.mean() > 0.04, (scene.background, figure.mean())  # the characters, large
        start += n
    assert start + tail == len(frames)
    pcm = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(out), "-f", "s16le", "-ac", "1",
                          "-ar", str(AUDIO_RATE), "-"], capture_output=True, check=True).stdout
    sound = np.frombuffer(pcm, "<i2").astype(float)
    assert abs(len(sound) / AUDIO_RATE - len(frames) / fps) < 0.1
    t0 = lead / fps
    seg = lambda a, b: float(np.sqrt(np.mean(sound[int(a * AUDIO_RATE):int(b * AUDIO_RATE)] ** 2)))
    assert seg(t0 + 0.2, t0 + 1.8) > 2000 and seg(0.2, t0 - 0.2) < 200  # voice after the title card only
    assert seg(t0 + 2.3, t0 + 3.8) < 200  # 2 s of voice, then quiet
