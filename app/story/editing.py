"""Edits on a story, with undo and redo.

Every change the UI makes goes through a :class:`StoryEditor` method. Each method is a
named command; the stack records the story's dictionary form before and after it.
Snapshots (rather than hand-written inverse operations) are chosen on purpose: a story is
a few kilobytes, and a snapshot undo cannot drift out of step with the model when a new
kind of edit is added. Listeners are told after every change (and every undo/redo), which
is how the app autosaves.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any, Callable

from app.story.model import (BACKGROUNDS, CHARACTER_KINDS, MARK_KINDS, MAX_CHARACTERS_PER_SCENE, MAX_SCENES,
                       Character, Mark, MotionChoice, Narration, Scene, Story, StoryError, path_point, new_id)

#: How many steps back a child can go; older steps are dropped.
MAX_UNDO = 200

Listener = Callable[[Story, str], None]


@dataclass
class _Step:
    label: str
    before: dict[str, Any]
    after: dict[str, Any]


class StoryEditor:
    """Applies named edits to one story and keeps the undo/redo stacks."""

    def __init__(self, story: Story):
        self.story = story
        self._undo: list[_Step] = []
        self._redo: list[_Step] = []
        self._listeners: list[Listener] = []

    # -- listeners and history -------------------------------------------------------
    def add_listener(self, listener: Listener) -> None:
        """Call ``listener(story, label)`` after every change, undo and redo."""
        self._listeners.append(listener)

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    @property
    def undo_label(self) -> str | None:
        return self._undo[-1].label if self._undo else None

    def undo(self) -> bool:
        """Go back one edit; returns False when there is nothing to undo."""
        if not self._undo:
            return False
        step = self._undo.pop()
        self._restore(step.before)
        self._redo.append(step)
        self._notify(f"undo {step.label}")
        return True

    def redo(self) -> bool:
        """Repeat the last undone edit; returns False when there is nothing to redo."""
        if not self._redo:
            return False
        step = self._redo.pop()
        self._restore(step.after)
        self._undo.append(step)
        self._notify(f"redo {step.label}")
        return True

    def _restore(self, snapshot: dict[str, Any]) -> None:
        restored = Story.from_dict(copy.deepcopy(snapshot))
        # keep the same Story object so views holding it stay valid
        self.story.title, self.story.arc, self.story.scenes = restored.title, restored.arc, restored.scenes

    def _notify(self, label: str) -> None:
        for listener in list(self._listeners):
            listener(self.story, label)

    def _execute(self, label: str, change: Callable[[Story], Any]) -> Any:
        """Run ``change`` on the story as one undoable step.

        If ``change`` raises, the story is put back as it was and the error propagates, so
        a rejected edit never leaves a half-changed story behind.
        """
        before = self.story.to_dict()
        try:
            result = change(self.story)
        except Exception:
            self._restore(before)
            raise
        after = self.story.to_dict()
        if after != before:
            self._undo.append(_Step(label, before, after))
            del self._undo[:-MAX_UNDO]
            self._redo.clear()
            self._notify(label)
        return result

    # -- story-level edits -----------------------------------------------------------
    def set_title(self, title: str) -> None:
        def change(s: Story) -> None:
            s.title = title
            Story.from_dict(s.to_dict())  # validates length and characters
        self._execute("title", change)

    def add_scene(self, after_index: int | None = None, background: str = "sky") -> Scene:
        """Add an empty scene after ``after_index`` (at the end by default)."""
        _check_background(background)

        def change(s: Story) -> Scene:
            if len(s.scenes) >= MAX_SCENES:
                raise StoryError(f"a story has at most {MAX_SCENES} scenes")
            scene = Scene(background=background)
            at = len(s.scenes) if after_index is None else after_index + 1
            s.scenes.insert(at, scene)
            return scene
        return self._execute("add scene", change)

    def duplicate_scene(self, scene_id: str) -> Scene:
        """Copy a scene (with fresh ids) right after the original."""
        def change(s: Story) -> Scene:
            if len(s.scenes) >= MAX_SCENES:
                raise StoryError(f"a story has at most {MAX_SCENES} scenes")
            index = s.scene_index(scene_id)
            data = copy.deepcopy(s.scenes[index].to_dict())
            data["id"] = new_id()
            for c in data["characters"]:
                c["id"] = new_id()
            clone = Scene.from_dict(data)
            s.scenes.insert(index + 1, clone)
            return clone
        return self._execute("duplicate scene", change)

    def delete_scene(self, scene_id: str) -> None:
        def change(s: Story) -> None:
            s.scenes.pop(s.scene_index(scene_id))
        self._execute("delete scene", change)

    def move_scene(self, scene_id: str, new_index: int) -> None:
        """Move a scene to position ``new_index`` (clamped to the list)."""
        def change(s: Story) -> None:
            scene = s.scenes.pop(s.scene_index(scene_id))
            s.scenes.insert(max(0, min(new_index, len(s.scenes))), scene)
        self._execute("move scene", change)

    def set_background(self, scene_id: str, background: str) -> None:
        _check_background(background)

        def change(s: Story) -> None:
            s.scene(scene_id).background = background
        self._execute("background", change)

    # -- character edits -------------------------------------------------------------
    def add_character(self, scene_id: str, kind: str) -> Character:
        if kind not in CHARACTER_KINDS:
            raise StoryError(f"unknown character '{kind}' (expected one of {', '.join(CHARACTER_KINDS)})")

        def change(s: Story) -> Character:
            scene = s.scene(scene_id)
            if len(scene.characters) >= MAX_CHARACTERS_PER_SCENE:
                raise StoryError(f"a scene has at most {MAX_CHARACTERS_PER_SCENE} characters")
            character = Character(kind=kind)
            scene.characters.append(character)
            return character
        return self._execute("add character", change)

    def remove_character(self, scene_id: str, character_id: str) -> None:
        def change(s: Story) -> None:
            scene = s.scene(scene_id)
            scene.characters.remove(scene.character(character_id))
        self._execute("remove character", change)

    def set_path(self, scene_id: str, character_id: str, path: list[tuple[float, float, float]],
                 spins: list[float] | None = None) -> None:
        """Replace a character's path (table metres, seconds) as one step.

        ``spins`` (times found as loops in the same stroke) replace the old spin marks;
        hops that still fall on the new path are kept.
        """
        points = [path_point(p, f"path[{i}]") for i, p in enumerate(path)]
        for i in range(1, len(points)):
            if points[i][2] < points[i - 1][2]:
                raise StoryError(f"path[{i}]: time goes backwards")

        def change(s: Story) -> None:
            character = s.scene(scene_id).character(character_id)
            character.path = points
            end = points[-1][2] if points else 0.0
            kept = [m for m in character.marks if m.at <= end and (spins is None or m.kind != "spin")]
            character.marks = sorted(kept + [Mark("spin", float(t)) for t in (spins or [])], key=lambda m: m.at)
        self._execute("draw path", change)

    def set_motion(self, scene_id: str, character_id: str, motion_class: str, clip_id: str | None = None) -> None:
        choice = MotionChoice.from_dict({"class": motion_class, "clip": clip_id})

        def change(s: Story) -> None:
            s.scene(scene_id).character(character_id).motion = choice
        self._execute("motion", change)

    def set_narration(self, scene_id: str, narration: Narration | None) -> None:
        """Point a scene at a stored narration (:func:`app.story.narration.store_narration`
        writes the audio first), or remove it with None. Undo keeps the asset's name, and
        stored narration assets are never overwritten, so undo brings the voice back."""
        checked = None if narration is None else Narration.from_dict(narration.to_dict())

        def change(s: Story) -> None:
            s.scene(scene_id).narration = checked
        self._execute("narration", change)

    def add_mark(self, scene_id: str, character_id: str, kind: str, at: float) -> None:
        """Add a hop or spin at time ``at`` along the character's path."""
        if kind not in MARK_KINDS:
            raise StoryError(f"unknown mark '{kind}'")
        mark = Mark.from_dict({"kind": kind, "at": at})

        def change(s: Story) -> None:
            character = s.scene(scene_id).character(character_id)
            character.marks.append(mark)
            character.marks.sort(key=lambda m: m.at)
        self._execute(kind, change)


def _check_background(background: str) -> None:
    if background not in BACKGROUNDS:
        raise StoryError(f"unknown background '{background}' (expected one of {', '.join(BACKGROUNDS)})")


__all__ = ["StoryEditor", "MAX_UNDO"]
