"""StoryBeam's application: everything a child, a teacher or a developer touches.

Layers, each importing only those listed before it (``tests/test_layering.py`` enforces
it; ``docs/design/architecture.md`` draws it):

* :mod:`app.story` -- the story model, editing with undo, gestures, crash-safe storage
  and packages (no Kivy, no GL);
* :mod:`app.services` -- the motion catalogue, thumbnails and calibration wizard the
  screens call (no Kivy);
* :mod:`app.player` -- the one table-to-scene mapping, the animator, the stage, the render
  thread and video export;
* :mod:`app.ui` -- the Kivy screens and widgets only;
* :mod:`app.commands` -- one module per ``storybeam`` command (found by :mod:`app.cli`),
  the only modules that import the lab (:mod:`lab`: benchmarks, stress harnesses, the
  research experiment).
"""
