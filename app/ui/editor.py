"""Scene editor: scene strip (drag to reorder), table view for sketching, and big choice
buttons for place, characters and motion. Every change goes through the StoryEditor, so
it is undoable and autosaved."""
from __future__ import annotations

from kivy.app import App
from kivy.graphics import Color, Line, Rectangle
from kivy.metrics import dp
from kivy.uix.behaviors import ButtonBehavior
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.gridlayout import GridLayout
from kivy.uix.label import Label
from kivy.uix.modalview import ModalView
from kivy.uix.screenmanager import Screen
from kivy.uix.scrollview import ScrollView
from kivy.uix.widget import Widget

from app.services.act_it_out import act_it_out_allowed
from app.story import BACKGROUNDS, CHARACTER_KINDS, MOTION_CLASSES, find_spins, hop_time
from app.ui.art import MOTION_COLOURS, draw_background, draw_character_badge
from app.ui.clip_tiles import ClipTile, clip_tile_name
from app.ui.pose_picker import GroupBrowser, PosePicker
from app.ui.narration import voice_button
from app.ui.table_view import TableView, normalise_times
from app.ui.widgets import BUTTON_DP, MIN_TOUCH_DP, IconButton, big_label, compact_screen, filled, window_dp
from retrieval.errors import StoryBeamError

THUMB_DP = 96
CLIP_TILE_DP = 150  # "more like this" tiles: big enough to see the stick figure move


class SceneThumb(Widget):
    """A small picture of one scene in the strip (its background and characters)."""

    def __init__(self, scene, number: int, label: str, selected: bool, **kwargs):
        super().__init__(size_hint_y=None, height=dp(THUMB_DP), **kwargs)
        self.scene, self.number, self.selected = scene, number, selected
        self.label = Label(text=label, font_size=dp(14), color=(1, 1, 1, 1), outline_width=2,
                           outline_color=(0, 0, 0, 1))
        self.add_widget(self.label)
        self.bind(pos=self.redraw, size=self.redraw)

    def redraw(self, *_: object) -> None:
        self.canvas.before.clear()
        x, y, w, h = self.x + dp(4), self.y + dp(4), self.width - dp(8), self.height - dp(8)
        with self.canvas.before:
            draw_background(self.scene.background, x, y, w, h)
            for i, c in enumerate(self.scene.characters):
                draw_character_badge(c.kind, x + dp(16) + i * dp(22), y + dp(18), dp(9))
            if self.selected:
                Color(1.0, 0.55, 0.1, 1)
                Line(rectangle=(x - dp(2), y - dp(2), w + dp(4), h + dp(4)), width=dp(3))
        self.label.pos = (x, y + h - dp(26))
        self.label.size = (w, dp(24))


class SceneStrip(BoxLayout):
    """Vertical list of scene thumbnails. Tap selects; drag a thumbnail up or down to
    move the scene (the drop position is shown as an orange bar)."""

    DRAG_THRESHOLD_DP = 12

    def __init__(self, on_select, on_move, **kwargs):
        super().__init__(orientation="vertical", spacing=dp(6), size_hint_y=None, padding=dp(4), **kwargs)
        self.bind(minimum_height=self.setter("height"))
        self.on_select, self.on_move = on_select, on_move

    def thumb_at(self, x: float, y: float) -> SceneThumb | None:
        return next((c for c in self.children if isinstance(c, SceneThumb) and c.collide_point(x, y)), None)

    def drop_index(self, y: float) -> int:
        """Position in the scene list for a drop at height ``y`` (top of the strip = 0)."""
        thumbs = list(reversed([c for c in self.children if isinstance(c, SceneThumb)]))
        for i, thumb in enumerate(thumbs):
            if y > thumb.center_y:
                return i
        return len(thumbs)

    def on_touch_down(self, touch):
        thumb = self.thumb_at(*touch.pos)
        if thumb is None:
            return super().on_touch_down(touch)
        touch.grab(self)
        touch.ud["strip_thumb"] = thumb
        touch.ud["strip_start"] = touch.pos
        return True

    def on_touch_move(self, touch):
        if touch.grab_current is not self:
            return super().on_touch_move(touch)
        sx, sy = touch.ud["strip_start"]
        if abs(touch.y - sy) > dp(self.DRAG_THRESHOLD_DP):
            touch.ud["strip_dragging"] = True
            self._show_drop(touch)
        return True

    def on_touch_up(self, touch):
        if touch.grab_current is not self:
            return super().on_touch_up(touch)
        touch.ungrab(self)
        self.canvas.after.clear()
        thumb = touch.ud["strip_thumb"]
        if touch.ud.get("strip_dragging"):
            target = self.drop_index(touch.y)
            current = thumb.number - 1
            if target > current:
                target -= 1  # the dragged scene leaves its old slot first
            if target != current:
                self.on_move(thumb.scene.id, target)
        else:
            self.on_select(thumb.scene.id)
        return True

    def _show_drop(self, touch) -> None:
        thumbs = list(reversed([c for c in self.children if isinstance(c, SceneThumb)]))
        i = self.drop_index(touch.y)
        y = thumbs[i].top + dp(3) if i < len(thumbs) else (thumbs[-1].y - dp(3) if thumbs else self.top)
        self.canvas.after.clear()
        with self.canvas.after:
            Color(1.0, 0.55, 0.1, 1)
            Rectangle(pos=(self.x, y - dp(3)), size=(self.width, dp(6)))
            Color(1, 1, 1, 0.6)
            Rectangle(pos=(self.x, touch.y - dp(THUMB_DP) / 2), size=(self.width, dp(THUMB_DP)))


class EditorScreen(Screen):
    """Edit one scene of the open story."""

    def on_pre_enter(self, *args):
        self.refresh()

    @property
    def scene(self):
        app = App.get_running_app()
        story = app.editor.story
        if not story.scenes:
            return None
        ids = [s.id for s in story.scenes]
        if app.current_scene_id not in ids:
            app.current_scene_id = ids[0]
        return story.scene(app.current_scene_id)

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        scene = self.scene
        if scene is not None and scene.characters and app.selected_character_id not in [c.id for c in scene.characters]:
            app.selected_character_id = scene.characters[0].id
        root = filled(BoxLayout(spacing=dp(8), padding=dp(8)), (0.96, 0.93, 0.85, 1))
        # Sizes for this screen (dp): narrower columns and shorter rows on a small tablet; the
        # right column's rows share its height (never under the 48 dp touch minimum).
        win_w, win_h = window_dp()
        compact = compact_screen()
        left_w, right_w, label_size = (140, 280, 13) if compact else (170, 300, 16)
        label_h = label_size * 1.9
        fixed = 3 * label_h + 52 + 7 * 4 + 16
        unit = max(MIN_TOUCH_DP, min(BUTTON_DP, (win_h - fixed) / 6.9))
        centre_w = win_w - left_w - right_w - 32
        bar_w = max(MIN_TOUCH_DP, min(90, (centre_w - 6 * 6 - 2) / 6))  # six buttons, a spacer: six gaps
        bar_font = dp(15) if bar_w >= 86 else dp(12)

        # -- left: scene strip -------------------------------------------------------
        left = BoxLayout(orientation="vertical", size_hint_x=None, width=dp(left_w), spacing=dp(6))
        self.strip = SceneStrip(on_select=self.select_scene, on_move=self.move_scene)
        story = app.editor.story
        for i, s in enumerate(story.scenes):
            label = t(f"part_{s.part}") if s.part else t("scene_n", n=i + 1)
            self.strip.add_widget(SceneThumb(s, i + 1, f"{i + 1}. {label}", s.id == app.current_scene_id))
        scroll = ScrollView(do_scroll_x=False, scroll_type=["bars"], bar_width=dp(14))
        scroll.add_widget(self.strip)
        left.add_widget(scroll)
        actions = GridLayout(cols=3, size_hint_y=None, height=dp(BUTTON_DP), spacing=dp(4))
        actions.add_widget(IconButton("add", t("add_scene"), on_press=self.add_scene, font_size=dp(12)))
        actions.add_widget(IconButton("duplicate", t("duplicate"), on_press=self.duplicate_scene, font_size=dp(12)))
        actions.add_widget(IconButton("delete", t("delete"), on_press=self.delete_scene, font_size=dp(12)))
        left.add_widget(actions)
        root.add_widget(left)

        # -- centre: top bar + table -------------------------------------------------
        centre = BoxLayout(orientation="vertical", spacing=dp(6))
        bar = BoxLayout(size_hint_y=None, height=dp(unit if compact else BUTTON_DP), spacing=dp(6))
        small = {"size_hint_x": None, "width": dp(bar_w), "font_size": bar_font}
        bar.add_widget(IconButton("home", t("home"), on_press=app.go_home, **small))
        self.undo_button = IconButton("undo", t("undo"), on_press=self.undo, **small)
        self.redo_button = IconButton("redo", t("redo"), on_press=self.redo, **small)
        self.undo_button.opacity = 1.0 if app.editor.can_undo else 0.45
        self.redo_button.opacity = 1.0 if app.editor.can_redo else 0.45
        bar.add_widget(self.undo_button)
        bar.add_widget(self.redo_button)
        bar.add_widget(Widget())
        self.voice_button = voice_button(self, **small)  # the scene's narration (app.ui.narration)
        bar.add_widget(self.voice_button)
        self.play_button = IconButton("play", t("play"), on_press=lambda: app.go("play"),
                                      background=[0.75, 0.95, 0.75, 1], **small)
        bar.add_widget(self.play_button)
        self.projector_button = IconButton("projector", t("projector"), on_press=lambda: app.go("projector"),
                                           **small)
        bar.add_widget(self.projector_button)
        centre.add_widget(bar)
        stroke = self.pending_stroke()
        self.table = TableView(scene=scene, selected_id=app.selected_character_id or "",
                               pending=[p[:2] for p in stroke] if stroke else [])
        self.table.bind(on_sketch=self.on_sketch)
        centre.add_widget(self.table)
        hint = t("draw_hint") if scene is not None and scene.characters else t("pick_character_hint")
        self.hint = big_label(hint, 18)
        centre.add_widget(self.hint)
        root.add_widget(centre)

        # -- right: choices ------------------------------------------------------------
        right = BoxLayout(orientation="vertical", size_hint_x=None, width=dp(right_w), spacing=dp(4))
        right.add_widget(big_label(t("background"), label_size))
        bg_grid = GridLayout(cols=4, spacing=dp(4), size_hint_y=None, height=dp(2 * 0.92 * unit + 4))
        self.background_buttons = {}
        for name in BACKGROUNDS:
            b = IconButton(name, t(f"bg_{name}"), on_press=lambda n=name: self.set_background(n),
                           font_size=dp(11), selected=scene is not None and scene.background == name)
            self.background_buttons[name] = b
            bg_grid.add_widget(b)
        right.add_widget(bg_grid)
        right.add_widget(big_label(t("characters"), label_size))
        add_row = GridLayout(cols=3, spacing=dp(4), size_hint_y=None, height=dp(unit))
        self.character_buttons = {}
        for kind in CHARACTER_KINDS:
            b = IconButton(kind, "+ " + t(f"char_{kind}"), on_press=lambda k=kind: self.add_character(k),
                           font_size=dp(12))
            self.character_buttons[kind] = b
            add_row.add_widget(b)
        right.add_widget(add_row)
        self.cast_row = GridLayout(cols=6, spacing=dp(4), size_hint_y=None, height=dp(52))
        for c in (scene.characters if scene else []):
            self.cast_row.add_widget(_CastBadge(c, c.id == app.selected_character_id, self.select_character))
        cast_line = BoxLayout(size_hint_y=None, height=dp(52), spacing=dp(4))
        cast_line.add_widget(self.cast_row)
        self.remove_button = IconButton("delete", t("delete"), on_press=self.remove_character, size_hint_x=None,
                                        width=dp(56), font_size=dp(11))
        self.remove_button.opacity = 1.0 if self.selected_character() is not None else 0.0
        self.remove_button.disabled = self.selected_character() is None
        cast_line.add_widget(self.remove_button)
        right.add_widget(cast_line)
        right.add_widget(big_label(t("motion"), label_size))
        motion_grid = GridLayout(cols=3, spacing=dp(4), size_hint_y=None, height=dp(2 * unit + 4))
        selected = self.selected_character()
        self.motion_buttons = {}
        for name in (*MOTION_CLASSES, "more"):
            b = IconButton(name, t(f"motion_{name}"), on_press=lambda n=name: self.choose_motion(n),
                           font_size=dp(13), icon_colour=list(MOTION_COLOURS[name]),
                           selected=selected is not None and selected.motion.motion_class == name)
            self.motion_buttons[name] = b
            motion_grid.add_widget(b)
        right.add_widget(motion_grid)
        likes = BoxLayout(spacing=dp(4), size_hint_y=None, height=dp(0.84 * unit))
        likes.add_widget(IconButton("similar", t("more_like_this"), on_press=self.more_like_this, font_size=dp(14)))
        self.act_button = None  # "Act it out" (app.ui.act_view), unless the teacher switched the camera off
        if act_it_out_allowed(app.store):
            self.act_button = IconButton("act", t("act_it_out"), on_press=self.act_it_out, font_size=dp(14))
            likes.add_widget(self.act_button)
        right.add_widget(likes)
        finders = BoxLayout(spacing=dp(4), size_hint_y=None, height=dp(0.84 * unit))
        self.pose_button = IconButton("pose", t("pose_button"), on_press=self.search_by_pose, font_size=dp(14))
        self.groups_button = IconButton("groups", t("groups_button"), on_press=self.browse_groups,
                                        font_size=dp(14))
        finders.add_widget(self.pose_button)
        finders.add_widget(self.groups_button)
        right.add_widget(finders)
        right.add_widget(Widget())
        root.add_widget(right)
        self.add_widget(root)

    # -- helpers ----------------------------------------------------------------------
    def pending_stroke(self) -> list | None:
        """The stroke drawn in this scene before it had a character, if any."""
        pending = getattr(App.get_running_app(), "pending_stroke", None)
        if pending is None or self.scene is None or pending[0] != self.scene.id:
            return None
        return pending[1]

    def selected_character(self):
        app = App.get_running_app()
        scene = self.scene
        if scene is None:
            return None
        return next((c for c in scene.characters if c.id == app.selected_character_id), None)

    def _edit(self, action) -> None:
        """Run an edit; a refused edit shows its message instead of crashing."""
        app = App.get_running_app()
        try:
            action(app.editor)
        except StoryBeamError as exc:
            app.show_error(exc)
            return
        self.refresh()

    # -- actions --------------------------------------------------------------------
    def select_scene(self, scene_id: str) -> None:
        App.get_running_app().current_scene_id = scene_id
        self.refresh()

    def move_scene(self, scene_id: str, index: int) -> None:
        self._edit(lambda ed: ed.move_scene(scene_id, index))

    def add_scene(self) -> None:
        app = App.get_running_app()
        scene = self.scene
        after = app.editor.story.scene_index(scene.id) if scene else None
        bg = BACKGROUNDS[len(app.editor.story.scenes) % len(BACKGROUNDS)]

        def action(ed):
            new = ed.add_scene(after, bg)
            app.current_scene_id = new.id
        self._edit(action)

    def duplicate_scene(self) -> None:
        app = App.get_running_app()
        if self.scene is None:
            return

        def action(ed):
            app.current_scene_id = ed.duplicate_scene(self.scene.id).id
        self._edit(action)

    def delete_scene(self) -> None:
        if self.scene is not None:
            self._edit(lambda ed: ed.delete_scene(self.scene.id))

    def set_background(self, name: str) -> None:
        if self.scene is not None:
            self._edit(lambda ed: ed.set_background(self.scene.id, name))

    def add_character(self, kind: str) -> None:
        app = App.get_running_app()
        if self.scene is None:
            return

        scene_id, stroke = self.scene.id, self.pending_stroke()

        def action(ed):
            character = ed.add_character(scene_id, kind)
            app.selected_character_id = character.id
            if stroke:  # the line drawn before anyone was there: the new character's path
                cleaned, spins = find_spins(normalise_times(stroke))
                ed.set_path(scene_id, character.id, cleaned, spins)
        self._edit(action)
        app.pending_stroke = None
        self.table.pending = []

    def remove_character(self) -> None:
        character = self.selected_character()
        if character is not None:
            self._edit(lambda ed: ed.remove_character(self.scene.id, character.id))

    def select_character(self, character_id: str) -> None:
        App.get_running_app().selected_character_id = character_id
        self.refresh()

    def choose_motion(self, name: str, clip_id: str | None = None) -> None:
        character = self.selected_character()
        if character is None:
            App.get_running_app().show_notice("add_someone")
            return
        if name == "more":
            self.more_like_this(show_all=True)
            return
        self._edit(lambda ed: ed.set_motion(self.scene.id, character.id, name, clip_id))

    def more_like_this(self, show_all: bool = False) -> None:
        """List clips similar to the chosen one (or every clip of its class)."""
        app = App.get_running_app()
        t = app.t
        character = self.selected_character()
        catalog = app.catalog
        if character is None:
            app.show_notice("add_someone")
            return
        catalog.start_index()
        if show_all:
            clips = catalog.clips
        else:
            clips = catalog.similar(character.motion.clip_id or character.motion.motion_class)
        view = ModalView(size_hint=(0.8, 0.9))
        box = filled(BoxLayout(orientation="vertical", padding=dp(16), spacing=dp(10)), (1, 0.97, 0.9, 1))
        box.add_widget(big_label(t("motion_more") if show_all else t("more_like_this"), 24))
        grid = GridLayout(cols=3, spacing=dp(8), size_hint_y=None, row_default_height=dp(CLIP_TILE_DP),
                          row_force_default=True)
        grid.bind(minimum_height=grid.setter("height"))
        thumbs = app.motion_thumbnails()
        self.clip_tiles = []
        for clip in clips:
            icon = clip.label if clip.label in MOTION_COLOURS else "more"

            def pick(clip=clip):
                view.dismiss()
                self._edit(lambda ed: ed.set_motion(self.scene.id, character.id, clip.label, clip.trial))
            tile = ClipTile(clip.trial, clip_tile_name(t, clip.label, clip.trial, catalog.number_of), icon,
                            MOTION_COLOURS.get(clip.label, (0.4, 0.4, 0.4)), thumbs, pick,
                            selected=clip.trial == character.motion.clip_id)
            self.clip_tiles.append(tile)
            grid.add_widget(tile)
        if not clips:
            grid.add_widget(big_label(t("no_clips"), 20))
        scroll = ScrollView(do_scroll_x=False)
        scroll.add_widget(grid)
        box.add_widget(scroll)
        box.add_widget(IconButton("delete", t("back"), on_press=view.dismiss, size_hint_y=None, height=dp(64)))
        view.add_widget(box)
        self.clip_view = view
        view.open()

    def _pick_clip(self, label: str, trial: str) -> None:
        """A clip chosen in the pose search or the groups, for the selected character."""
        character = self.selected_character()
        if character is not None and self.scene is not None:
            self._edit(lambda ed: ed.set_motion(self.scene.id, character.id, label, trial))

    def search_by_pose(self) -> None:
        """Open the posable figure (:class:`app.ui.pose_picker.PosePicker`)."""
        app = App.get_running_app()
        if self.selected_character() is None:
            app.show_notice("add_someone")
            return
        self.pose_view = PosePicker(on_pick=self._pick_clip)
        self.pose_view.open()

    def act_it_out(self) -> None:
        """Open the camera view (:class:`app.ui.act_view.ActItOutView`): the child shows a
        movement; the motion picked from the nearest ones goes to the selected character."""
        app = App.get_running_app()
        if self.selected_character() is None:
            app.show_notice("add_someone")
            return
        if not act_it_out_allowed(app.store):  # switched off since the screen was drawn
            self.refresh()
            return
        from app.ui.act_view import ActItOutView  # deferred: the camera view loads when first opened

        self.act_view = ActItOutView(on_pick=self._pick_clip)
        self.act_view.open()

    def browse_groups(self) -> None:
        """Open the library's own groups (:class:`app.ui.pose_picker.GroupBrowser`)."""
        app = App.get_running_app()
        if self.selected_character() is None:
            app.show_notice("add_someone")
            return
        self.group_view = GroupBrowser(on_pick=self._pick_clip)
        self.group_view.open()

    def undo(self) -> None:
        App.get_running_app().editor.undo()
        self.refresh()

    def redo(self) -> None:
        App.get_running_app().editor.redo()
        self.refresh()

    def on_sketch(self, table: TableView, points) -> None:
        """A finished stroke: an arc onto the existing path is a hop; anything else is the
        character's new path (small loops in it become spins)."""
        app = App.get_running_app()
        scene = self.scene
        character = self.selected_character()
        if scene is None:
            return
        if character is None:  # kept: the next character added walks it (drawn dashed till then)
            app.pending_stroke = (scene.id, list(points))
            self.table.pending = [p[:2] for p in points]
            app.show_notice("add_someone")
            return
        if character.path:
            at = hop_time(points, character.path)
            if at is not None:
                self._edit(lambda ed: ed.add_mark(scene.id, character.id, "hop", at))
                return
        path = normalise_times(points)
        cleaned, spins = find_spins(path)
        self._edit(lambda ed: ed.set_path(scene.id, character.id, cleaned, spins))


class _CastBadge(ButtonBehavior, Widget):
    """A character already in the scene: tap to select it for sketching and motion."""

    def __init__(self, character, selected: bool, on_select, **kwargs):
        super().__init__(**kwargs)
        self.character, self.selected = character, selected
        self.bind(on_release=lambda *_: on_select(character.id), pos=self.redraw, size=self.redraw)

    def redraw(self, *_: object) -> None:
        self.canvas.clear()
        r = min(self.width, self.height) * 0.38
        with self.canvas:
            if self.selected:
                Color(1.0, 0.55, 0.1, 1)
                Line(circle=(self.center_x, self.center_y, r * 1.3), width=dp(3))
            draw_character_badge(self.character.kind, self.center_x, self.center_y, r)
