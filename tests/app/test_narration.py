"""Voice narration per scene (issue 14 part 1): audio checks and limits, trimming,
crash-safe storage, packages, the MP4 sound track and ``storybeam export-video``.

Audio files are generated here (numpy + the standard library's :mod:`wave`; OGG through
soundfile), never recorded from a microphone."""
from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import time
import wave
import zipfile
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.paths import REPO_ROOT
from app.story import (ACCEPTED_RATES, MAX_IMPORT_SECONDS, MAX_NARRATION_SECONDS, MAX_STORY_NARRATION_SECONDS, Audio, Narration,
                       NarrationError, ProfileStore, StorageError, Story, StoryEditor, StoryError, decode_audio,
                       demo_story, encode_wav, import_narration, load_narration, read_audio, read_package,
                       store_narration, trim)
from app.story.narration import asset_name

def tone(seconds: float, rate: int, freq: float = 440.0, amp: float = 0.3, channels: int = 1) -> np.ndarray:
    """(n, channels) int16 samples of a sine (channel c at freq * (c + 1))."""
    t = np.arange(int(round(seconds * rate))) / rate
    cols = [amp * np.sin(2 * np.pi * freq * (c + 1) * t) for c in range(channels)]
    return np.round(np.stack(cols, axis=1) * 32767).astype(np.int16)


def write_wav(path: Path, samples: np.ndarray, rate: int, width: int = 2) -> Path:
    """A PCM WAV of (n, channels) int16 samples, stored at ``width`` bytes per sample."""
    s = samples.astype(np.int32)
    if width == 1:
        raw = ((s >> 8) + 128).astype(np.uint8).tobytes()
    elif width == 2:
        raw = s.astype("<i2").tobytes()
    elif width == 3:
        v = (s << 8).astype("<i4").view(np.uint8).reshape(-1, 4)[:, :3]
        raw = v.tobytes()
    else:
        raw = (s << 16).astype("<i4").tobytes()
    with wave.open(str(path), "wb") as wf:
        wf.setnchannels(samples.shape[1])
        wf.setsampwidth(width)
        wf.setframerate(rate)
        wf.writeframes(raw)
    return path


def _story() -> Story:
    story = Story.new("short", title="Voices")
    story.id = "voices1"
    return story


# -- decoding and checks ------------------------------------------------------------------
@pytest.mark.parametrize("width", [1, 2, 3, 4])
@pytest.mark.parametrize("rate", [8000, 22050, 48000])
def test_wav_decodes_to_the_reference_samples(tmp_path, width, rate):
    ref = tone(0.5, rate)
    audio = read_audio(write_wav(tmp_path / "a.wav", ref, rate, width))
    assert audio.rate == rate and len(audio.samples) == len(ref)
    # 8-bit keeps the top byte only: the reference is the int16 samples with the low byte cut
    expected = (ref[:, 0].astype(np.int32) >> 8) << 8 if width == 1 else ref[:, 0]
    np.testing.assert_array_equal(audio.samples, expected)


def test_stereo_is_averaged_to_mono(tmp_path):
    ref = tone(0.4, 16000, channels=2)
    audio = read_audio(write_wav(tmp_path / "s.wav", ref, 16000))
    expected = np.round(ref.astype(np.float64).mean(axis=1)).astype(np.int16)
    np.testing.assert_array_equal(audio.samples, expected)


def test_ogg_decodes_close_to_its_source(tmp_path):
    sf = pytest.importorskip("soundfile")
    ref = tone(1.0, 44100)
    path = tmp_path / "v.ogg"
    sf.write(str(path), ref, 44100, format="OGG", subtype="VORBIS")
    audio = read_audio(path)
    assert audio.rate == 44100 and abs(len(audio.samples) - len(ref)) <= 64
    n = min(len(ref), len(audio.samples))
    corr = np.corrcoef(ref[:n, 0].astype(float), audio.samples[:n].astype(float))[0, 1]
    assert corr > 0.95  # lossy, but the same tone


def _refusals(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    """name -> (file, a fragment its message must contain)."""
    cases: dict[str, tuple[Path, str]] = {}

    def case(name: str, path: Path, fragment: str) -> None:
        cases[name] = (path, fragment)

    (tmp_path / "empty.wav").write_bytes(b"")
    case("empty file", tmp_path / "empty.wav", "empty")
    case("no samples", write_wav(tmp_path / "zero.wav", np.zeros((0, 1), np.int16), 16000), "empty")
    case("silence", write_wav(tmp_path / "silent.wav", np.zeros((16000, 1), np.int16), 16000), "silence")
    case("too short", write_wav(tmp_path / "blip.wav", tone(0.05, 16000), 16000), "at least")
    case("wrong rate", write_wav(tmp_path / "rate.wav", tone(0.5, 12345), 12345), "12345 Hz")
    case("three channels", write_wav(tmp_path / "ch3.wav", tone(0.5, 16000, channels=3), 16000), "3 channels")
    case("too long", write_wav(tmp_path / "long.wav", tone(MAX_IMPORT_SECONDS + 1, 8000), 8000), "at most")
    good = write_wav(tmp_path / "good.wav", tone(1.0, 16000), 16000).read_bytes()
    (tmp_path / "cut.wav").write_bytes(good[: len(good) // 2])
    case("cut short", tmp_path / "cut.wav", "damaged or cut short")
    (tmp_path / "noise.wav").write_bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    case("random bytes", tmp_path / "noise.wav", "not a WAV or OGG")
    (tmp_path / "text.ogg").write_text("OggS? no, just text pretending " * 10)
    case("text as ogg", tmp_path / "text.ogg", "not a readable OGG")
    big = tmp_path / "huge.wav"
    with open(big, "wb") as fh:  # sparse: 65 MB on paper, refused from its size alone
        fh.write(good[:44])
        fh.truncate(65 * 1024 * 1024)
    case("enormous", big, "at most 64 MB")
    # a header that claims an hour of audio: refused before any sample is read
    liar = bytearray(good)
    liar[40:44] = (3600 * 16000 * 2).to_bytes(4, "little")
    (tmp_path / "liar.wav").write_bytes(bytes(liar))
    case("lying header", tmp_path / "liar.wav", "at most")
    return cases


def test_corrupt_empty_wrong_rate_and_enormous_audio_is_refused_naming_the_file(tmp_path):
    cases = _refusals(tmp_path)
    for name, (path, fragment) in cases.items():
        with pytest.raises(NarrationError) as info:
            read_audio(path)
        message = str(info.value)
        assert str(path) in message, name
        assert fragment in message, (name, message)


@pytest.mark.parametrize("subtype,channels", [("FLOAT", 1), ("FLOAT", 2), ("DOUBLE", 1)])
def test_a_float_wav_reads_like_its_integer_twin(tmp_path, subtype, channels):
    """Audacity exports 32-bit float WAVs by default; Python's wave module refuses them
    ("unknown format: 3"), so they are read through scipy."""
    sf = pytest.importorskip("soundfile")
    ref = tone(0.5, 16000, channels=channels)
    path = tmp_path / "float.wav"
    sf.write(str(path), ref.astype(np.float64) / 32767.0, 16000, subtype=subtype)
    audio = read_audio(path)
    assert audio.rate == 16000 and len(audio.samples) == len(ref)
    expected = np.round(ref.astype(np.float64).mean(axis=1))
    assert np.max(np.abs(audio.samples - expected)) <= 1


def test_a_float_wav_in_the_extensible_header_reads(tmp_path):
    """WAVE_FORMAT_EXTENSIBLE with the float sub-format (what many tools write for
    more than two channels or high bit depths) is a float WAV too."""
    ref = tone(0.3, 22050)[:, 0].astype(np.float32) / 32767.0
    samples = ref.astype("<f4").tobytes()
    guid = (3).to_bytes(2, "little") + bytes.fromhex("000000001000800000aa00389b71")
    fmt = ((0xFFFE).to_bytes(2, "little") + (1).to_bytes(2, "little") + (22050).to_bytes(4, "little")
           + (22050 * 4).to_bytes(4, "little") + (4).to_bytes(2, "little") + (32).to_bytes(2, "little")
           + (22).to_bytes(2, "little") + (32).to_bytes(2, "little") + (4).to_bytes(4, "little") + guid)
    assert len(fmt) == 40
    body = (b"WAVE" + b"fmt " + len(fmt).to_bytes(4, "little") + fmt
            + b"data" + len(samples).to_bytes(4, "little") + samples)
    (tmp_path / "ext.wav").write_bytes(b"RIFF" + len(body).to_bytes(4, "little") + body)
    audio = read_audio(tmp_path / "ext.wav")
    assert len(audio.samples) == len(ref) and np.max(np.abs(audio.samples - np.round(ref * 32767))) <= 1


def test_a_damaged_ogg_or_float_wav_is_refused_naming_the_file(tmp_path):
    sf = pytest.importorskip("soundfile")
    ogg = tmp_path / "v.ogg"
    sf.write(str(ogg), tone(1.0, 16000), 16000, format="OGG", subtype="VORBIS")
    data = ogg.read_bytes()
    (tmp_path / "bad.ogg").write_bytes(data[:200] + bytes(len(data) - 200))
    with pytest.raises(NarrationError, match="bad.ogg"):
        read_audio(tmp_path / "bad.ogg")
    sf.write(str(tmp_path / "f.wav"), tone(0.5, 16000).astype(np.float32) / 32768, 16000, subtype="FLOAT")
    good = (tmp_path / "f.wav").read_bytes()
    (tmp_path / "fcut.wav").write_bytes(good[:60])
    with pytest.raises(NarrationError, match="fcut.wav") as info:
        read_audio(tmp_path / "fcut.wav")
    assert info.value.kind == "unreadable"


def test_a_long_sound_is_imported_then_trimmed_before_it_is_kept(tmp_path):
    """A sound longer than a scene's narration may be reads whole (up to
    MAX_IMPORT_SECONDS), is refused as it is with the kind "too_long" (the picture says:
    trim it), and is kept once trimmed."""
    path = write_wav(tmp_path / "long.wav", tone(MAX_NARRATION_SECONDS + 30, 8000), 8000)
    audio = read_audio(path)
    assert audio.seconds == pytest.approx(MAX_NARRATION_SECONDS + 30)
    store = ProfileStore(tmp_path / "p.db")
    story = _story()
    store.save_story(story)
    with pytest.raises(NarrationError) as info:
        import_narration(store, story, story.scenes[0].id, path)
    assert info.value.kind == "too_long" and "trim" in str(info.value)
    assert store.asset_names(story.id) == []
    narration = import_narration(store, story, story.scenes[0].id, path, 10.0, 10.0 + MAX_NARRATION_SECONDS)
    assert narration.seconds == pytest.approx(MAX_NARRATION_SECONDS)


def test_refused_imports_store_nothing(tmp_path):
    store = ProfileStore(tmp_path / "p.db")
    story = _story()
    store.save_story(story)
    before = json.dumps(store.load_story(story.id).to_dict())
    for name, (path, _) in _refusals(tmp_path).items():
        with pytest.raises(NarrationError):
            import_narration(store, story, story.scenes[0].id, path)
        assert store.asset_names(story.id) == [], name
        assert story.scenes[0].narration is None
        assert json.dumps(store.load_story(story.id).to_dict()) == before


def test_accepted_rates_are_all_readable(tmp_path):
    for rate in ACCEPTED_RATES:
        assert read_audio(write_wav(tmp_path / f"{rate}.wav", tone(0.2, rate), rate)).rate == rate


# -- trimming -------------------------------------------------------------------------------
def test_trim_is_the_sample_slice_and_refuses_bad_ranges():
    rate = 16000
    audio = Audio(tone(2.0, rate)[:, 0], rate)
    part = trim(audio, 0.25, 1.5)
    np.testing.assert_array_equal(part.samples, audio.samples[4000:24000])
    np.testing.assert_array_equal(trim(audio, 0.5).samples, audio.samples[8000:])
    for start, end in [(1.0, 0.5), (-0.1, 1.0), (0.0, 2.5), (1.0, 1.05), (float("nan"), 1.0)]:
        with pytest.raises(NarrationError):
            trim(audio, start, end)


def test_wav_encoding_round_trips():
    audio = Audio(tone(0.3, 24000)[:, 0], 24000)
    back = decode_audio(encode_wav(audio), "x")
    assert back.rate == 24000
    np.testing.assert_array_equal(back.samples, audio.samples)


# -- the model ------------------------------------------------------------------------------
def test_stories_without_narration_keep_their_stored_form():
    old = demo_story().to_dict()
    assert all("narration" not in s for s in old["scenes"])
    assert Story.from_dict(json.loads(json.dumps(old))).to_dict() == old


def test_narration_round_trips_and_lengthens_its_scene():
    story = demo_story()
    scene = story.scenes[0]
    motion_only = scene.duration
    scene.narration = Narration("narration-0123456789abcdef.wav", motion_only + 1.5)
    assert scene.duration == pytest.approx(motion_only + 1.5)
    assert Story.from_dict(story.to_dict()).scenes[0].narration == scene.narration


@pytest.mark.parametrize("bad, fragment", [
    ({"asset": "../x.wav", "seconds": 1.0}, "unsafe"),
    ({"asset": "a/b.wav", "seconds": 1.0}, "unsafe"),
    ({"asset": "n.wav", "seconds": 0}, "out of range"),
    ({"asset": "n.wav", "seconds": MAX_NARRATION_SECONDS + 1}, "out of range"),
    ({"asset": "n.wav"}, "missing field 'seconds'"),
    ("n.wav", "expected an object"),
])
def test_bad_narration_references_are_refused_naming_the_field(bad, fragment):
    data = demo_story().to_dict()
    data["scenes"][1]["narration"] = bad
    with pytest.raises(StoryError, match=fragment) as info:
        Story.from_dict(data)
    assert "story.scenes[1].narration" in str(info.value)


# -- storage ----------------------------------------------------------------------------------
def test_store_load_replace_and_undo(tmp_path):
    store = ProfileStore(tmp_path / "p.db")
    story = _story()
    store.save_story(story)
    editor = StoryEditor(story)
    editor.add_listener(lambda s, label: store.save_story(s))
    sid = story.scenes[1].id
    first = Audio(tone(1.0, 16000)[:, 0], 16000)
    second = Audio(tone(2.0, 22050, freq=300)[:, 0], 22050)
    n1 = store_narration(store, story, sid, first, editor)
    assert n1.asset == asset_name(encode_wav(first)) and n1.seconds == pytest.approx(1.0)
    reopened = ProfileStore(tmp_path / "p.db").load_story(story.id)
    np.testing.assert_array_equal(load_narration(store, reopened, sid).samples, first.samples)
    n2 = store_narration(store, story, sid, second, editor)
    assert n2.asset != n1.asset
    assert set(store.asset_names(story.id)) == {n1.asset, n2.asset}  # the old file is never overwritten
    editor.undo()
    saved = store.load_story(story.id)
    assert saved.scene(sid).narration == n1
    np.testing.assert_array_equal(load_narration(store, saved, sid).samples, first.samples)
    editor.set_narration(sid, None)
    assert store.load_story(story.id).scene(sid).narration is None


def test_the_story_total_is_limited(tmp_path):
    store = ProfileStore(tmp_path / "p.db")
    story = Story.new("classic")
    store.save_story(story)
    per = Audio(np.ones(int(8000 * 100), np.int16), 8000)  # 100 s each
    for scene in story.scenes:
        store_narration(store, story, scene.id, per)
    story.scenes.append(Story.new("free").scenes[0])
    store.save_story(story)
    with pytest.raises(NarrationError, match=f"at most {MAX_STORY_NARRATION_SECONDS:.0f} s"):
        store_narration(store, story, story.scenes[-1].id, Audio(np.ones(8000 * 101, np.int16), 8000))
    assert story.scenes[-1].narration is None


def test_package_round_trip_keeps_the_voice_and_drops_replaced_ones(tmp_path):
    store = ProfileStore(tmp_path / "a.db")
    story = _story()
    store.save_story(story)
    sid = story.scenes[0].id
    store_narration(store, story, sid, Audio(tone(0.5, 8000)[:, 0], 8000))
    kept = Audio(tone(1.2, 48000, freq=220)[:, 0], 48000)
    n = store_narration(store, story, sid, kept)
    pkg = store.export_package(story.id, tmp_path / "s.zip")
    with zipfile.ZipFile(pkg) as zf:
        assert sorted(zf.namelist()) == ["assets/" + n.asset, "manifest.json", "story.json"]
    other = ProfileStore(tmp_path / "b.db")
    imported = other.import_package(pkg)
    assert imported.scene(sid).narration == n
    np.testing.assert_array_equal(load_narration(other, imported, sid).samples, kept.samples)


def _repack(src: Path, dst: Path, change) -> Path:
    """A copy of package ``src`` with ``change(files)`` applied and a consistent manifest."""
    import hashlib
    with zipfile.ZipFile(src) as zf:
        files = {n: zf.read(n) for n in zf.namelist() if n != "manifest.json"}
        manifest = json.loads(zf.read("manifest.json"))
    change(files)
    manifest["files"] = [{"name": k, "size": len(v), "sha256": hashlib.sha256(v).hexdigest()} for k, v in files.items()]
    with zipfile.ZipFile(dst, "w") as zf:
        zf.writestr("manifest.json", json.dumps(manifest))
        for k, v in files.items():
            zf.writestr(k, v)
    return dst


def test_packages_with_a_missing_or_bad_narration_are_refused_and_nothing_imported(tmp_path):
    store = ProfileStore(tmp_path / "a.db")
    story = _story()
    store.save_story(story)
    n = store_narration(store, story, story.scenes[2].id, Audio(tone(1.0, 16000)[:, 0], 16000))
    pkg = store.export_package(story.id, tmp_path / "s.zip")
    name = "assets/" + n.asset

    def drop(files):
        del files[name]

    def corrupt(files):
        files[name] = files[name][:100]

    def silence(files):
        files[name] = encode_wav(Audio(np.zeros(16000, np.int16), 16000))

    def stretch(files):
        files[name] = encode_wav(Audio(tone(3.0, 16000)[:, 0], 16000))

    target = ProfileStore(tmp_path / "b.db")
    for change, fragment in [(drop, "missing from the package"), (corrupt, "cut short"), (silence, "silence"),
                             (stretch, "the story says")]:
        bad = _repack(pkg, tmp_path / f"{change.__name__}.zip", change)
        with pytest.raises(StorageError, match=fragment) as info:
            target.import_package(bad)
        assert str(bad) in str(info.value)
        assert target.list_stories() == []
    assert read_package(pkg)[0].scenes[2].narration == n  # the untouched package is fine


_KILL_CHILD = r"""
import sys, numpy as np
from app.story import ProfileStore, Audio, store_narration, Story
store = ProfileStore(sys.argv[1])
story = store.load_story("voices1")
rng = np.random.default_rng(int(sys.argv[2]))
print("ready", flush=True)
i = 0
while True:
    i += 1
    n = int(rng.integers(8000, 48000))
    samples = (rng.standard_normal(n) * 3000).astype(np.int16)
    store_narration(store, story, story.scenes[i % len(story.scenes)].id, Audio(samples, 16000))
"""


@pytest.mark.slow  # SIGKILLs child savers
def test_sigkill_while_saving_narrations_never_loses_the_story(tmp_path):
    """A child stores narrations as fast as it can; it is SIGKILLed at random moments.
    After every kill the story loads and every narration it points at loads."""
    db = tmp_path / "p.db"
    with ProfileStore(db) as store:
        store.save_story(_story())
    rng = np.random.default_rng(7)
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    voiced = 0
    for k in range(6):
        proc = subprocess.Popen([sys.executable, "-c", _KILL_CHILD, str(db), str(k)], stdout=subprocess.PIPE,
                                cwd=REPO_ROOT, env=env, text=True)
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(float(rng.uniform(0.05, 0.6)))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        with ProfileStore(db) as store:
            story = store.load_story("voices1")
            for scene in story.scenes:
                if scene.narration is not None:
                    voiced += 1
                    assert load_narration(store, story, scene.id).seconds == pytest.approx(scene.narration.seconds)
    assert voiced > 0  # the children did save narrations before being killed


# -- the MP4 sound track and the command ---------------------------------------------------------
def _ffmpeg() -> str:
    from app.player import available
    why = available()
    if why:
        pytest.skip(why)
    import imageio_ffmpeg
    return imageio_ffmpeg.get_ffmpeg_exe()


def decoded_audio(mp4: Path, rate: int = 48000) -> np.ndarray:
    """The MP4's audio stream decoded by ffmpeg (honouring the container's edit list), as
    int16 mono at ``rate``; an empty array when there is no audio stream."""
    done = subprocess.run([_ffmpeg(), "-v", "error", "-i", str(mp4), "-map", "0:a:0?", "-f", "s16le", "-ac", "1",
                           "-ar", str(rate), "-"], capture_output=True)
    if done.returncode != 0 and b"does not contain any stream" in done.stderr:
        return np.zeros(0, np.int16)
    assert done.returncode == 0, done.stderr.decode(errors="replace")
    return np.frombuffer(done.stdout, "<i2")


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x.astype(np.float64) ** 2))) if len(x) else 0.0


def test_export_muxes_each_narration_at_its_scene_start(tmp_path):
    from app.player import export_story_mp4, frame_count, story_audio

    _ffmpeg()
    story = demo_story()
    voices = tmp_path / "assets"
    voices.mkdir()
    for scene, (secs, rate) in zip(story.scenes[1:], [(1.5, 22050), (scene_long := 5.0, 16000)]):
        wav = encode_wav(Audio(tone(secs, rate)[:, 0], rate))
        (voices / asset_name(wav)).write_bytes(wav)
        scene.narration = Narration(asset_name(wav), secs)
    fps = 15.0
    out = export_story_mp4(story, tmp_path / "v.mp4", fps, view="2d", narration_dir=voices).path
    audio = decoded_audio(out)
    video_seconds = frame_count(story, fps) / fps
    assert abs(len(audio) / 48000 - video_seconds) <= 1 / 48000 * 2
    assert abs(len(audio) / 48000 - story.duration) <= len(story.scenes) / (2 * fps)
    # voice where a narration is, silence elsewhere
    starts = np.cumsum([0] + [s.duration for s in story.scenes])
    sec = lambda a, b: audio[int(a * 48000):int(b * 48000)]  # noqa: E731
    assert _rms(sec(0.0, starts[1] - 0.05)) < 30
    assert _rms(sec(starts[1] + 0.1, starts[1] + 1.4)) > 3000
    assert _rms(sec(starts[1] + 1.6, starts[2] - 0.05)) < 30
    assert _rms(sec(starts[2] + 0.1, starts[2] + scene_long - 0.1)) > 3000
    # the track the muxer was given is exactly the video's length, sample for sample
    track, problems = story_audio(story, fps, voices)
    assert problems == [] and len(track) == round(frame_count(story, fps) * 48000 / fps)


def test_a_missing_narration_leaves_its_scene_silent_and_says_so(tmp_path):
    from app.player import export_story_mp4

    _ffmpeg()
    story = demo_story()
    story.scenes[0].narration = Narration("narration-ffffffffffffffff.wav", 1.0)
    result = export_story_mp4(story, tmp_path / "v.mp4", 10.0, view="2d", narration_dir=tmp_path)
    assert "scene 1 is silent" in result.note and "narration-ffffffffffffffff.wav" in result.note
    assert _rms(decoded_audio(result.path)) == 0.0


def test_export_video_command_attaches_the_narration(tmp_path, capsys):
    _ffmpeg()
    voice = write_wav(tmp_path / "voice.wav", tone(3.0, 22050), 22050)
    out = tmp_path / "out.mp4"
    assert main(["export-video", "--demo-story", "--narration", str(voice), "--out", str(out), "--view", "2d",
                 "--fps", "10"]) == 0
    assert "narration" in capsys.readouterr().out
    audio = decoded_audio(out)
    story = demo_story()
    assert abs(len(audio) / 48000 - story.duration) <= len(story.scenes) / 20
    assert _rms(audio[int(0.1 * 48000):int(2.9 * 48000)]) > 3000
    assert _rms(audio[int(3.1 * 48000):]) < 30


def test_export_video_command_refuses_bad_audio_naming_it_and_writes_nothing(tmp_path, capsys):
    bad = write_wav(tmp_path / "rate.wav", tone(0.5, 12345), 12345)
    out = tmp_path / "out.mp4"
    assert main(["export-video", "--demo-story", "--narration", str(bad), "--out", str(out), "--view", "2d"]) == 1
    err = capsys.readouterr().err
    assert str(bad) in err and "12345 Hz" in err and "Traceback" not in err
    assert not out.exists()


def test_export_command_takes_the_narration_folder(tmp_path, capsys):
    _ffmpeg()
    story = demo_story()
    wav = encode_wav(Audio(tone(1.0, 16000)[:, 0], 16000))
    (tmp_path / asset_name(wav)).write_bytes(wav)
    story.scenes[0].narration = Narration(asset_name(wav), 1.0)
    src = tmp_path / "story.json"
    src.write_text(json.dumps(story.to_dict()))
    out = tmp_path / "o.mp4"
    assert main(["export", str(src), str(out), "--view", "2d", "--fps", "5", "--narration-dir", str(tmp_path)]) == 0
    assert _rms(decoded_audio(out)[: 48000 // 2]) > 3000
    capsys.readouterr()


def test_decoded_audio_helper_sees_no_audio_in_a_silent_export(tmp_path):
    """The check above could pass vacuously if the helper always found sound: a story
    without narration has no audio stream at all."""
    from app.player import export_story_mp4

    _ffmpeg()
    out = export_story_mp4(demo_story(), tmp_path / "v.mp4", 5.0, view="2d", narration_dir=tmp_path).path
    assert len(decoded_audio(out)) == 0


# -- recording (the recorder path, with an array for a microphone) -------------------------------------
def test_the_recorder_writes_what_the_microphone_gave(tmp_path):
    from app.services.recording import ArraySource, ChunkRecorder

    ref = tone(0.75, 22050)[:, 0]
    rec = ChunkRecorder(ArraySource(ref, 22050, realtime=False), tmp_path / "rec")
    rec.start()
    deadline = time.monotonic() + 20
    while rec.frames < len(ref) and time.monotonic() < deadline:
        time.sleep(0.01)
    path = rec.stop()
    assert path.suffix == ".wav" and not list((tmp_path / "rec").glob("*.part"))
    audio = read_audio(path)
    assert audio.rate == 22050
    np.testing.assert_array_equal(audio.samples[: len(ref)], ref)  # then the quiet room's zeros


def test_the_recorder_stops_at_the_length_limit_and_cancel_leaves_nothing(tmp_path):
    from app.services.recording import ArraySource, ChunkRecorder

    hit = []
    rec = ChunkRecorder(ArraySource(tone(2.0, 8000)[:, 0], 8000, realtime=False), tmp_path, limit_seconds=0.5,
                        on_limit=lambda: hit.append(True))
    rec.start()
    rec._thread.join(timeout=20)
    assert hit == [True] and rec.frames == 4000
    assert read_audio(rec.stop()).seconds == pytest.approx(0.5)
    again = ChunkRecorder(ArraySource(tone(2.0, 8000)[:, 0], 8000, realtime=False), tmp_path / "c")
    again.start()
    again.cancel()
    assert list((tmp_path / "c").iterdir()) == []


_RECORD_CHILD = r"""
import sys, numpy as np
from app.services.recording import ArraySource, ChunkRecorder
t = np.arange(22050 * 60) / 22050
rec = ChunkRecorder(ArraySource((np.sin(2 * np.pi * 300 * t) * 8000).astype(np.int16), 22050), sys.argv[1])
rec.start()
print("recording", flush=True)
rec._thread.join()
"""


@pytest.mark.slow  # SIGKILLs a child recorder
def test_sigkill_while_recording_loses_only_the_recording(tmp_path):
    """Killed mid-recording: the story (with its earlier narration) is intact, the
    unfinished ``.part`` file is not a WAV anyone uses, and the next start removes it."""
    from app.services.recording import PART_SUFFIX, discard_stale

    db = tmp_path / "p.db"
    with ProfileStore(db) as store:
        story = _story()
        store.save_story(story)
        kept = store_narration(store, story, story.scenes[0].id, Audio(tone(1.0, 16000)[:, 0], 16000))
        before = json.dumps(store.load_story(story.id).to_dict())
    folder = tmp_path / "p.db.recording"
    proc = subprocess.Popen([sys.executable, "-c", _RECORD_CHILD, str(folder)], stdout=subprocess.PIPE,
                            cwd=REPO_ROOT, env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)), text=True)
    assert proc.stdout.readline().strip() == "recording"
    time.sleep(0.6)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    parts = list(folder.glob("*" + PART_SUFFIX))
    assert len(parts) == 1 and parts[0].stat().st_size > 44  # samples were being written
    with ProfileStore(db) as store:
        story = store.load_story("voices1")
        assert json.dumps(story.to_dict()) == before
        assert load_narration(store, story, story.scenes[0].id).seconds == pytest.approx(kept.seconds)
    assert discard_stale(folder) == 1 and not list(folder.iterdir())


def test_find_recorder_says_why_it_cannot_record(monkeypatch):
    from app.services import recording

    monkeypatch.delenv("ANDROID_ARGUMENT", raising=False)
    monkeypatch.delenv("ANDROID_PRIVATE", raising=False)
    monkeypatch.setitem(sys.modules, "sounddevice", None)  # "not installed"
    source, why = recording.find_recorder()
    assert source is None and "sounddevice" in why
    monkeypatch.setenv("ANDROID_ARGUMENT", "/data/app")
    monkeypatch.setitem(sys.modules, "jnius", None)
    source, why = recording.find_recorder()
    assert source is None and "pyjnius" in why


def test_mutated_audio_files_are_refused_with_a_message_never_an_exception():
    """Seeded mutation fuzzing of a valid WAV and OGG (bytes flipped, files cut): every
    outcome is a decoded narration or a NarrationError -- the first run of this found a
    RuntimeError escaping from the wave module."""
    sf = pytest.importorskip("soundfile")
    rng = np.random.default_rng(5)
    x = tone(1.0, 8000)
    buf = io.BytesIO()
    sf.write(buf, x, 8000, format="OGG", subtype="VORBIS")
    outcomes = {"ok": 0, "refused": 0}
    for base in (encode_wav(Audio(x[:, 0], 8000)), buf.getvalue()):
        for _ in range(1500):
            data = bytearray(base)
            for _ in range(int(rng.integers(1, 8))):
                data[int(rng.integers(0, len(data)))] = int(rng.integers(0, 256))
            if rng.random() < 0.2:
                data = data[: int(rng.integers(0, len(data)))]
            try:
                decode_audio(bytes(data), "fuzz")
                outcomes["ok"] += 1
            except NarrationError as exc:
                assert str(exc).startswith("fuzz: ")
                outcomes["refused"] += 1
    assert outcomes["ok"] > 0 and outcomes["refused"] > 0


def test_the_apps_exporter_finds_each_storys_voices(tmp_path):
    """What the teacher screen calls (app_exporter with the profile's asset folders)."""
    from app.player import app_exporter

    _ffmpeg()
    store = ProfileStore(tmp_path / "p.db")
    story = demo_story()
    store.save_story(story)
    store_narration(store, story, story.scenes[2].id, Audio(tone(1.0, 16000)[:, 0], 16000))
    export = app_exporter("2d", fps=10.0, narration_dirs=lambda s: store.story_assets_dir(s.id))
    result = export(story, tmp_path / "v.mp4")
    audio = decoded_audio(result.path)
    start = sum(s.duration for s in story.scenes[:2])
    assert len(audio) == round(story.duration * 48000)
    assert _rms(audio[: int((start - 0.05) * 48000)]) < 30
    assert _rms(audio[int((start + 0.1) * 48000):int((start + 0.9) * 48000)]) > 3000


def test_opening_a_story_prunes_only_voices_it_does_not_use(tmp_path):
    from app.story import prune_narrations

    store = ProfileStore(tmp_path / "p.db")
    story = _story()
    store.save_story(story)
    old = store_narration(store, story, story.scenes[0].id, Audio(tone(0.5, 8000)[:, 0], 8000))
    kept = store_narration(store, story, story.scenes[0].id, Audio(tone(0.7, 8000)[:, 0], 8000))
    other = store_narration(store, story, story.scenes[1].id, Audio(tone(0.9, 8000)[:, 0], 8000))
    store.put_asset(story.id, "background.png", b"not a voice")
    assert prune_narrations(store, store.load_story(story.id)) == 1
    assert sorted(store.asset_names(story.id)) == sorted(["background.png", kept.asset, other.asset])
    assert old.asset not in store.asset_names(story.id)
    assert prune_narrations(store, store.load_story(story.id)) == 0
