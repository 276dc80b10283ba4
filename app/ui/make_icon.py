"""Write the Android launcher icon and presplash (``assets/ui/icon.png``,
``assets/ui/presplash.png``) from the same procedural art the app draws.

    python -m app.ui.make_icon
"""
from __future__ import annotations

from pathlib import Path

from app.paths import UI_ASSETS
from app.ui.env import prepare_kivy_env

#: where the icon and presplash go (assets/ui)
OUT = UI_ASSETS


def main() -> None:
    prepare_kivy_env(headless=True)
    # Kivy reads its environment at import, so every Kivy import comes after prepare_kivy_env();
    # deferred: after prepare_kivy_env(); importing the Window creates the GL context the Fbo needs
    from kivy.core.window import Window  # noqa: F401
    from kivy.graphics import ClearBuffers, ClearColor, Color, Ellipse, Fbo  # deferred: after prepare_kivy_env()

    from app.ui.art import draw_background, draw_character_badge  # deferred: imports Kivy, after prepare_kivy_env()

    def render(size: int, name: str, with_scene: bool) -> Path:
        fbo = Fbo(size=(size, size), with_stencilbuffer=False)
        with fbo:
            ClearColor(0, 0, 0, 0)
            ClearBuffers()
            if with_scene:
                draw_background("grass", 0, 0, size, size)
            Color(1.0, 0.82, 0.35, 1)
            Ellipse(pos=(size * 0.04, size * 0.04), size=(size * 0.92, size * 0.92))
            Color(1, 1, 1, 0.95)  # the drawn path: a row of dots under the robot
            for i in range(7):
                Ellipse(pos=(size * (0.16 + 0.11 * i), size * (0.22 + 0.05 * (i % 2))), size=(size * 0.05, size * 0.05))
            draw_character_badge("robot", size * 0.5, size * 0.56, size * 0.22)
        fbo.draw()
        path = OUT / name
        path.parent.mkdir(parents=True, exist_ok=True)
        fbo.texture.save(str(path), flipped=True)
        return path

    print(render(512, "icon.png", False))
    print(render(512, "presplash.png", True))


if __name__ == "__main__":
    main()
