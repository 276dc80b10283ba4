"""The story player: the story as moving pictures -- the table laid in the 3-D scene, the
Play preview, the projector stage, the MP4 export, and the thread they render on. (What
is drawn, for any renderer, is :mod:`ar.scene`; this package decides what a story shows
and when.)

Light modules (numpy and the story only; imported here, safe on Android and at start-up):

* :mod:`app.player.placement` -- the one table -> scene mapping (``table_to_scene``) and
  its two placements: the full-size preview table and the miniature on the board;
* :mod:`app.player.render_thread` -- ``RenderThread``: one long-lived thread owns the
  renderer and its GL context; the newest request wins;
* :mod:`app.player.app_renderer` -- ``AppRenderer``: the render thread's one renderer,
  serving the Play preview (a ``Scene``) and the stage (a ``StageJob``);
* :mod:`app.player.video_export` -- the MP4 export: the story film by default (3-D in a
  child process, or the top-down 2-D fallback between the same cards);
* :mod:`app.player.cards` -- the film's drawn pictures: the places' skies, title and
  ending cards (Pillow, imported on use);
* :mod:`app.player.celebration` -- the ending's chime and confetti (Play and the film).

3-D modules (retargeting, OpenCV and :mod:`ar.scene` at load -- no pyrender: the preview
and the stage describe frames as :class:`ar.scene.SceneDescription` s, which Kivy GL draws
in the app and pyrender, imported on first use, draws for the export and tests; the demo
pipeline imports :mod:`ar.render`. *Not* imported here -- import them by module path
where 3-D is wanted):

* :mod:`app.player.animator` -- ``SceneAnimator``: a story character's clip retargeted and
  laid on its path (shared by the preview, the stage and the export);
* :mod:`app.player.preview` -- ``ScenePreviewRenderer``: the Play preview from above the table;
* :mod:`app.player.stage` -- ``StageRenderer``: the story through the tracked projector rig;
* :mod:`app.player.story_film` -- ``StoryFilm``: the story film's frames, its camera framing the cast;
* :mod:`app.player.demo_pipeline` -- ``storybeam demo`` / ``render --demo``: retrieve,
  animate and render through the synthetic hand-held rig.
"""
from __future__ import annotations

from app.player.app_renderer import AppRenderer, StageJob, app_renderer_factory
from app.player.placement import (
    PREVIEW_PLACEMENT,
    STAGE_PLACEMENT,
    STAGE_SCALE,
    TABLE_CENTRE_M,
    TablePlacement,
    scene_to_table,
    table_to_scene,
)
from app.player.render_thread import RenderThread
from app.player.video_export import (
    VIEWS as EXPORT_VIEWS,
)
from app.player.video_export import (
    AUDIO_RATE,
    FILM_FPS,
    FILM_SIZE,
    RIG_FPS,
    ExportResult,
    VideoExportError,
    app_exporter,
    available,
    default_fps,
    has_narration,
    mux_audio,
    story_audio,
    export_in_subprocess,
    export_story_mp4,
    frame_count,
    read_story,
    story_frames,
    story_frames_3d,
)

__all__ = [
    # placement
    "TablePlacement", "PREVIEW_PLACEMENT", "STAGE_PLACEMENT", "STAGE_SCALE", "TABLE_CENTRE_M", "table_to_scene",
    "scene_to_table",
    # render thread and the app's renderer
    "RenderThread", "AppRenderer", "StageJob", "app_renderer_factory",
    # video export
    "EXPORT_VIEWS", "VideoExportError", "ExportResult", "available", "frame_count", "story_frames",
    "story_frames_3d", "export_story_mp4", "export_in_subprocess", "app_exporter", "read_story",
    "AUDIO_RATE", "has_narration", "story_audio", "mux_audio", "FILM_SIZE", "FILM_FPS", "RIG_FPS", "default_fps",
]
