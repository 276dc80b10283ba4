"""A bundled demo story (three scenes), used by ``storybeam app --demo-story``, the docs
screenshots and the UI tests. Built in code so it always matches the current model."""
from __future__ import annotations

import math

from app.story.model import Character, Mark, MotionChoice, Scene, Story

DEMO_STORY_ID = "demo-robot-cat"


def wavy_path(x0: float, y0: float, x1: float, y1: float, wiggle: float, seconds: float,
              n: int = 40) -> list[tuple[float, float, float]]:
    """A sketched path ``(x, y, t)`` (table metres, seconds) of ``n`` points from ``(x0, y0)``
    to ``(x1, y1)`` in ``seconds``, bowed sideways by one sine period of amplitude ``wiggle``
    (y only), rounded as the tablet stores touches (0.1 mm, 1 ms)."""
    pts = []
    for i in range(n):
        u = i / (n - 1)
        x = x0 + (x1 - x0) * u
        y = y0 + (y1 - y0) * u + wiggle * math.sin(u * math.pi * 2)
        pts.append((round(x, 4), round(y, 4), round(u * seconds, 3)))
    return pts


def demo_story() -> Story:
    """"The robot and the cat": meet in the meadow, a race at night, a dance in space."""
    return Story(
        id=DEMO_STORY_ID,
        title="Robot & Cat",
        arc="short",
        scenes=[
            Scene(id="demo-s1", background="grass", part="beginning", characters=[
                Character(id="demo-c1", kind="robot", path=wavy_path(0.15, 0.2, 0.95, 0.55, 0.08, 4.0),
                          motion=MotionChoice("walk"), marks=[Mark("hop", 2.0)]),
                Character(id="demo-c2", kind="animal", path=wavy_path(1.05, 0.15, 0.75, 0.45, 0.05, 3.0),
                          motion=MotionChoice("run")),
            ]),
            Scene(id="demo-s2", background="night", part="middle", characters=[
                Character(id="demo-c3", kind="robot", path=wavy_path(0.1, 0.6, 1.1, 0.6, 0.1, 3.0),
                          motion=MotionChoice("run")),
                Character(id="demo-c4", kind="animal", path=wavy_path(0.1, 0.3, 1.1, 0.3, -0.1, 2.5),
                          motion=MotionChoice("jump"), marks=[Mark("spin", 1.2)]),
            ]),
            Scene(id="demo-s3", background="space", part="end", characters=[
                Character(id="demo-c5", kind="child", path=wavy_path(0.3, 0.4, 0.9, 0.4, 0.15, 3.0),
                          motion=MotionChoice("dance")),
            ]),
        ],
    )
