"""Every screen at every tablet size (issue 29): ``storybeam app --screenshot`` lists the
widgets the window cuts off or another widget covers (``clipped_widgets``), and it is
empty for home, editor, play and teacher at the sizes a tablet has, in both languages.
The checker itself is tested on widget trees with known faults."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _shot(tmp_path: Path, screen: str, size: str, density: float, lang: str) -> dict:
    out = tmp_path / f"{screen}_{size}_{density}_{lang}.png"
    env = dict(os.environ, KIVY_HOME=str(tmp_path / "kivy"), PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "-m", "app.cli", "app", "--db", str(tmp_path / f"{screen}{size}{lang}.db"),
                           "--screenshot", str(out), "--screen", screen, "--size", size, "--density", str(density),
                           "--lang", lang, "--preview", "2d"], cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=240)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(Path(f"{out}.json").read_text())


# the two tightest tablets for every screen, and the largest for the busiest one
CASES = [(screen, "1024x600", 1.0, "en") for screen in ("home", "editor", "play", "teacher")] + \
        [(screen, "1280x800", 1.33, "ja") for screen in ("home", "editor", "play", "teacher")] + \
        [("editor", "2560x1600", 2.0, "ja"), ("pin", "2560x1600", 3.0, "en")]


@pytest.mark.slow  # one app per screenshot, in a child process
@pytest.mark.parametrize("screen,size,density,lang", CASES)
def test_no_widget_is_cut_off_or_covered(tmp_path, screen, size, density, lang):
    info = _shot(tmp_path, screen, size, density, lang)
    assert info["screen"] == screen and info["size"] == [int(v) for v in size.split("x")]  # not the PIN pad
    assert info["density"] == pytest.approx(density)
    assert info["clipped_widgets"] == [], json.dumps(info["clipped_widgets"], indent=1)


# -- the checker on trees with known faults ------------------------------------------------------
@pytest.fixture(scope="module")
def kivy_ui():
    from app.ui.env import prepare_kivy_env  # deferred: Kivy after its environment
    prepare_kivy_env(headless=True)
    from kivy.uix.boxlayout import BoxLayout
    from kivy.uix.button import Button
    from kivy.uix.label import Label
    from kivy.uix.scrollview import ScrollView
    from kivy.uix.widget import Widget

    from app.ui.layout_check import clipped_widgets
    return BoxLayout, Button, Label, ScrollView, Widget, clipped_widgets


def test_the_checker_finds_cut_covered_and_overflowing_widgets(kivy_ui):
    BoxLayout, Button, Label, ScrollView, Widget, clipped_widgets = kivy_ui
    root = Widget(size=(400, 300), pos=(0, 0))
    inside = Button(text="fine", pos=(10, 10), size=(100, 50))
    past_edge = Button(text="past the edge", pos=(350, 10), size=(100, 50))
    under = Button(text="under", pos=(10, 100), size=(100, 50))
    over = Button(text="over", pos=(30, 110), size=(100, 50))
    root.add_widget(inside)
    root.add_widget(past_edge)
    root.add_widget(under)
    root.add_widget(over)  # added last: drawn on top of "under"
    long = Label(text="a sentence far too long for its little box " * 3, pos=(150, 200), size=(80, 30))
    long.texture_size = [410, 24]  # what its text measures when drawn: set, so no GL context is needed here
    root.add_widget(long)
    row = BoxLayout(pos=(150, 100), size=(120, 50))
    root.add_widget(row)
    row_child = Button(text="wider than its row", size_hint_x=None, width=200)
    row.add_widget(row_child)
    row.do_layout()
    found = {p["widget"]: p["problem"] for p in clipped_widgets([root], (400, 300))}
    assert found["Button 'past the edge'"] == "cut by the window"
    assert found["Button 'under'"] == "covered by Button 'over'"
    assert found["Label 'a sentence far too long for its little box a sentence far too long for its little box "
                 "a sentence far too long for its little box '"] == "text cut"
    assert found["Button 'wider than its row'"] == "outside its row"
    assert "Button 'fine'" not in found and "Button 'over'" not in found


def test_scrolled_content_is_not_cut_and_invisible_widgets_are_skipped(kivy_ui):
    BoxLayout, Button, Label, ScrollView, Widget, clipped_widgets = kivy_ui
    root = Widget(size=(400, 300), pos=(0, 0))
    scroll = ScrollView(pos=(0, 0), size=(200, 300))
    column = BoxLayout(orientation="vertical", size_hint_y=None, height=900)
    for i in range(9):
        column.add_widget(Button(text=f"item {i}"))
    scroll.add_widget(column)
    root.add_widget(scroll)
    hidden = Button(text="hidden", pos=(500, 10), size=(50, 50), opacity=0)
    root.add_widget(hidden)
    column.do_layout()
    assert clipped_widgets([root], (400, 300)) == []
