"""Story model: dictionary round trip, validation, undo/redo over edits."""
from __future__ import annotations

import copy

import pytest

from app.story.editing import MAX_UNDO, StoryEditor
from app.story.model import ARCS, STORY_FORMAT_VERSION, Story, StoryError
from retrieval.errors import StoryBeamError


def _story_with_content() -> Story:
    story = Story.new("classic", title="Robo and the cat")
    ed = StoryEditor(story)
    scene = story.scenes[0]
    robot = ed.add_character(scene.id, "robot")
    ed.set_path(scene.id, robot.id, [(0.1, 0.1, 0.0), (0.5, 0.3, 1.0), (0.9, 0.4, 2.5)])
    ed.set_motion(scene.id, robot.id, "jump", "cmu_13_11")
    ed.add_mark(scene.id, robot.id, "hop", 1.2)
    return story


@pytest.mark.parametrize("arc", list(ARCS))
def test_new_story_has_one_scene_per_arc_part(arc):
    story = Story.new(arc)
    assert len(story.scenes) == max(1, len(ARCS[arc]))
    assert [s.part for s in story.scenes] == (list(ARCS[arc]) or [None])


def test_dict_round_trip_is_identical():
    story = _story_with_content()
    data = story.to_dict()
    assert data["version"] == STORY_FORMAT_VERSION
    again = Story.from_dict(copy.deepcopy(data))
    assert again == story
    assert again.to_dict() == data


def test_position_along_path_interpolates_in_time():
    story = _story_with_content()
    robot = story.scenes[0].characters[0]
    assert robot.position_at(0.5) == pytest.approx((0.3, 0.2))
    assert robot.position_at(99) == pytest.approx((0.9, 0.4))
    assert story.scenes[0].duration == pytest.approx(2.5)


@pytest.mark.parametrize("mutate, fragment", [
    (lambda d: d.update(version=STORY_FORMAT_VERSION + 1), "newer StoryBeam"),
    (lambda d: d.update(format="something else"), "not a StoryBeam story"),
    (lambda d: d.update(arc="epic"), "unknown arc"),
    (lambda d: d["scenes"][0].update(background="lava"), "unknown background"),
    (lambda d: d["scenes"][0]["characters"][0].update(kind="dragon"), "unknown character"),
    (lambda d: d["scenes"][0]["characters"][0]["path"].append([5.0, 0.1, 9.0]), "off the"),
    (lambda d: d["scenes"][0]["characters"][0]["path"].append([0.2, 0.1, 0.5]), "time goes backwards"),
    (lambda d: d["scenes"][0]["characters"][0]["path"][0].__setitem__(0, "x"), "expected numbers"),
    (lambda d: d["scenes"][0]["characters"][0]["marks"][0].update(kind="fly"), "unknown mark"),
    (lambda d: d.update(id="../evil"), "letters, digits"),
    (lambda d: d.update(title="a\x00b"), "control characters"),
    (lambda d: d["scenes"].append(copy.deepcopy(d["scenes"][0])), "duplicate scene id"),
    (lambda d: d.pop("scenes"), "missing field 'scenes'"),
])
def test_invalid_stories_are_refused_with_the_field_named(mutate, fragment):
    data = _story_with_content().to_dict()
    mutate(data)
    with pytest.raises(StoryError, match=fragment) as info:
        Story.from_dict(data)
    assert isinstance(info.value, StoryBeamError)


def test_undo_redo_walks_back_and_forth_through_edits():
    story = Story.new("short")
    ed = StoryEditor(story)
    states = [story.to_dict()]
    first = story.scenes[0].id
    ed.set_background(first, "night"); states.append(story.to_dict())
    c = ed.add_character(first, "animal"); states.append(story.to_dict())
    ed.set_path(first, c.id, [(0.2, 0.2, 0.0), (0.4, 0.2, 1.0)]); states.append(story.to_dict())
    dup = ed.duplicate_scene(first); states.append(story.to_dict())
    ed.move_scene(dup.id, 0); states.append(story.to_dict())
    ed.delete_scene(first); states.append(story.to_dict())
    assert story.scenes[0].id == dup.id and len(story.scenes) == 3
    for expected in reversed(states[:-1]):
        assert ed.undo()
        assert story.to_dict() == expected
    assert not ed.undo()
    for expected in states[1:]:
        assert ed.redo()
        assert story.to_dict() == expected
    assert not ed.redo()


def test_new_edit_clears_redo_and_listeners_hear_every_change():
    story = Story.new("free")
    ed = StoryEditor(story)
    heard = []
    ed.add_listener(lambda s, label: heard.append(label))
    ed.add_scene()
    ed.undo()
    assert ed.can_redo
    ed.set_title("Hello")
    assert not ed.can_redo
    assert heard == ["add scene", "undo add scene", "title"]


def test_rejected_edit_leaves_story_and_history_unchanged():
    story = Story.new("short")
    ed = StoryEditor(story)
    c = ed.add_character(story.scenes[0].id, "child")
    before = story.to_dict()
    with pytest.raises(StoryError, match="off the"):
        ed.set_path(story.scenes[0].id, c.id, [(0.1, 0.1, 0.0), (3.0, 0.1, 1.0)])
    with pytest.raises(StoryError, match="no scene"):
        ed.delete_scene("nope")
    with pytest.raises(StoryError, match="at most"):
        for _ in range(10):
            ed.add_character(story.scenes[0].id, "robot")
    assert len(story.scenes[0].characters) == 6
    ed.undo()
    assert len(story.scenes[0].characters) == 5
    assert ed.undo_label == "add character"
    assert before["scenes"][0]["characters"][0]["id"] == c.id


def test_undo_history_is_bounded():
    story = Story.new("free")
    ed = StoryEditor(story)
    for i in range(MAX_UNDO + 20):
        ed.set_title(f"t{i}")
    undone = 0
    while ed.undo():
        undone += 1
    assert undone == MAX_UNDO
    assert story.title == "t19"
