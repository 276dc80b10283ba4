"""Stories a child can manage (issue 29): the bin (delete with a way back), renaming by
picture, voice or typing, and saving the finished video where the family finds it."""
from __future__ import annotations

import pytest

from app.services.gallery import (DesktopGallery, safe_name, set_video_saving_allowed, video_saving_allowed,
                                  videos_folder)
from app.story import Cover, Narration, ProfileStore, StorageError, Story
from app.story.narration import referenced_assets


@pytest.fixture
def store(tmp_path):
    with ProfileStore(tmp_path / "profile.db") as s:
        yield s


def test_a_binned_story_leaves_home_and_comes_back(store):
    a, b = Story.new("short", title="A"), Story.new("short", title="B")
    store.save_story(a)
    store.save_story(b)
    store.put_asset(a.id, "narration-x.wav", b"RIFF")
    store.bin_story(a.id)
    assert [s.id for s in store.list_stories()] == [b.id]
    assert [s.id for s in store.binned_stories()] == [a.id]
    assert store.load_story(a.id).title == "A" and store.asset_names(a.id) == ["narration-x.wav"]
    store.restore_story(a.id)
    assert {s.id for s in store.list_stories()} == {a.id, b.id} and store.binned_stories() == []
    store.bin_story(a.id)
    assert store.empty_bin() == 1
    assert not store.has_story(a.id) and store.asset_names(a.id) == []
    assert [s.id for s in store.list_stories()] == [b.id]
    with pytest.raises(StorageError):
        store.bin_story("nope")


def test_the_bin_survives_reopening(tmp_path):
    path = tmp_path / "p.db"
    with ProfileStore(path) as s:
        story = Story.new("short", title="kept")
        s.save_story(story)
        s.bin_story(story.id)
    with ProfileStore(path) as s:
        assert [x.id for x in s.binned_stories()] == [story.id] and s.list_stories() == []


def test_rename_by_picture_voice_or_typing(store):
    story = Story.new("short", title="Story 1")
    store.save_story(story)
    voice = Narration("narration-0123456789abcdef.wav", 1.2)
    renamed = store.rename_story(story.id, cover=Cover("animal", 2, voice))
    assert renamed.cover == Cover("animal", 2, voice)
    again = store.load_story(story.id)
    assert again.cover.picture == "animal" and again.cover.voice.asset == voice.asset
    assert voice.asset in referenced_assets(again)  # the voice label is kept with the story (packages, pruning)
    store.rename_story(story.id, title="The big race")
    assert store.load_story(story.id).title == "The big race"
    assert store.load_story(story.id).cover.picture == "animal"
    with pytest.raises(StorageError):
        store.rename_story(story.id, title="x" * 500)
    with pytest.raises(StorageError):
        store.rename_story(story.id, cover=Cover("dragon", 0))
    assert store.load_story(story.id).title == "The big race"  # a refused rename changes nothing


def test_desktop_gallery_saves_into_the_videos_folder(tmp_path):
    home = tmp_path / "home"
    (home / "Videos").mkdir(parents=True)
    video = tmp_path / "film.mp4"
    video.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(1000))
    gallery = DesktopGallery(tmp_path / "exports", home=home, env={})
    first = gallery.save(video, "Robot & Cat")
    second = gallery.save(video, "Robot & Cat")
    assert first.location == str(home / "Videos" / "StoryBeam" / "Robot  Cat.mp4")
    assert second.location.endswith("Robot  Cat (2).mp4")
    assert (home / "Videos" / "StoryBeam" / "Robot  Cat.mp4").read_bytes() == video.read_bytes()
    # no videos folder: the app's export folder
    bare = DesktopGallery(tmp_path / "exports", home=tmp_path / "nohome", env={})
    assert bare.save(video, "x").location == str(tmp_path / "exports" / "x.mp4")
    # XDG's own answer wins
    (tmp_path / "vids").mkdir()
    assert videos_folder(home, {"XDG_VIDEOS_DIR": str(tmp_path / "vids")}) == tmp_path / "vids"
    assert safe_name("../../etc/passwd") == "etcpasswd" and safe_name("うみの おはなし") == "うみの おはなし"


def test_the_teachers_switch(store):
    assert video_saving_allowed(store)
    set_video_saving_allowed(store, False)
    assert not video_saving_allowed(store)
