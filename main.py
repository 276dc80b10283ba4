"""Android entry point (python-for-android runs ``main.py``); on a desktop use
``storybeam app``. The profile lives in the app's private storage."""
import os
from pathlib import Path

from app.ui.env import prepare_kivy_env

prepare_kivy_env()

from app.ui.app import StoryBeamApp  # noqa: E402

if __name__ == "__main__":
    private = os.environ.get("ANDROID_PRIVATE") or os.path.join(os.path.expanduser("~"), ".storybeam")
    StoryBeamApp(db_path=Path(private) / "profile.db").run()
