"""Android entry point (python-for-android runs ``main.py``); on a desktop use
``storybeam app``. The profile lives in the app's private storage."""
import os
from pathlib import Path

from app.ui.env import prepare_kivy_env

prepare_kivy_env()

from app.scene import app_renderer_factory  # noqa: E402
from app.ui.app import StoryBeamApp  # noqa: E402


def make_app() -> StoryBeamApp:
    """The app on its profile, with the 3-D Play preview and projector stage drawn by Kivy
    GL (OpenGL ES 2: no pyrender on the tablet)."""
    private = Path(os.environ.get("ANDROID_PRIVATE") or os.path.join(os.path.expanduser("~"), ".storybeam"))
    return StoryBeamApp(db_path=private / "profile.db",
                        renderer_factory=app_renderer_factory(private, renderer="kivy-gl"))


if __name__ == "__main__":
    make_app().run()
