"""The Kivy touch interface: screens (home, editor, play, teacher, import), widgets and
drawn art. Only this layer (and the commands that start it) imports Kivy; what the
screens decide lives in :mod:`app.story`, :mod:`app.services` and :mod:`app.player`, so it
is tested without a window. Start it with ``storybeam app``.

The modules are imported one by one (``from app.ui.app import StoryBeamApp``) because
Kivy must be configured by :func:`app.ui.env.prepare_kivy_env` before any of them loads.
"""
