"""Android entry point (python-for-android runs ``main.py``); on a desktop use
``storybeam app``. The profile lives in the app's private storage."""
import os
from pathlib import Path

from app.ui.env import prepare_kivy_env

prepare_kivy_env()

from app.player import app_renderer_factory  # noqa: E402
from app.player.app_renderer import default_camera_choice, saved_camera_choice  # noqa: E402
from app.ui.app import StoryBeamApp  # noqa: E402


def make_app() -> StoryBeamApp:
    """The app on its profile, with the 3-D Play preview and projector stage drawn by Kivy
    GL (OpenGL ES 2: no pyrender on the tablet). The rig's camera: the teacher's setting,
    else on Android the tablet's own camera through Kivy once the rig is calibrated
    (:func:`app.player.app_renderer.default_camera_choice`)."""
    private = Path(os.environ.get("ANDROID_PRIVATE") or os.path.join(os.path.expanduser("~"), ".storybeam"))
    android = "ANDROID_PRIVATE" in os.environ or "ANDROID_ARGUMENT" in os.environ  # set by python-for-android
    camera = saved_camera_choice(private / "profile.db", default_camera_choice(private, android))
    return StoryBeamApp(db_path=private / "profile.db",
                        renderer_factory=app_renderer_factory(private, camera=camera, renderer="kivy-gl"))


if __name__ == "__main__":
    make_app().run()
