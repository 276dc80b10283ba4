""""Act it out": the child shows a movement to the tablet's camera and picks the character's
motion from the nearest library motions.

The view (:class:`ActItOutView`, opened by the editor's *Act it out* tile beside *More like
this*) shows the camera preview with a body-outline guide ("stand here"); a tap on the big
start button counts down 3-2-1, then a take of :data:`app.services.act_it_out.TAKE_SECONDS`
is tracked, the detected skeleton drawn over the preview as it goes. The take's nearest
motions come back as the familiar big animated tiles (:class:`app.ui.clip_tiles.ClipTile`);
a tap on one gives the selected character that motion (it then performs it on its path).
A take that shows too little of the body (:class:`app.services.act_it_out.TakeVerdict`)
gets a picture instead of results -- step back, lift your head, stand in the outline --
and nothing changes in the story.

The camera and the pose estimator run on a worker thread (:meth:`ActItOutView._work`);
frames reach the preview through a one-frame mailbox (the newest wins) and are dropped
once shown. No frame is stored, exported or logged (see :mod:`app.services.act_it_out`);
the preview's texture is released when the view closes.

The camera is the app's ``act_camera`` choice (``storybeam app --act-camera``): the Kivy
camera (``kivy:N``, the tablet's front camera) or, on a desktop and in the tests, a device
number, a video file or a folder of images, played looped at its own frame rate.
"""
from __future__ import annotations

import logging
import threading
import time
from typing import TYPE_CHECKING, Callable

import numpy as np
from kivy.app import App
from kivy.clock import Clock
from kivy.graphics import Canvas, Color, Ellipse, Line, Rectangle, RoundedRectangle, Triangle
from kivy.graphics.texture import Texture
from kivy.metrics import dp
from kivy.properties import StringProperty
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.label import Label
from kivy.uix.modalview import ModalView
from kivy.uix.stencilview import StencilView
from kivy.uix.widget import Widget

from app.services.act_it_out import (
    FACE,
    LIFT_HEAD,
    NO_BODY,
    RESULTS,
    SKELETON_BONES,
    STEP_BACK,
    ActItOut,
    ActLibrary,
    frame_problem,
    pose_runtime_problem,
)
from app.ui.art import MOTION_COLOURS
from app.ui.clip_tiles import ClipTile, clip_tile_name
from app.ui.notices import NoticePicture, log_notice, notice_sentence
from app.ui.widgets import IconButton, big_label, filled, tile_grid
from retrieval.errors import StoryBeamError

if TYPE_CHECKING:
    from ar.camera_sources import CameraSource

log = logging.getLogger(__name__)

TILE_DP = 150
#: the height of the picture prompt (step back, lift your head)
PROMPT_DP = 200
#: seconds per number of the 3-2-1 countdown
COUNT_S = 1.0
#: the default camera for Act it out: the tablet's front camera on Android, device 0 elsewhere
ANDROID_ACT_CAMERA = "kivy:1"
DESKTOP_ACT_CAMERA = "0"
_GOOD, _BAD = (0.2, 0.75, 0.3), (0.9, 0.25, 0.2)


def act_library(app) -> ActLibrary:
    """The app's one :class:`ActLibrary` over its catalogue's folder (started on first use)."""
    library = getattr(app, "_act_library", None)
    if library is None or library.folder != app.catalog.motions_dir:
        library = ActLibrary(app.catalog.motions_dir)
        app._act_library = library
    library.start()
    return library


def open_act_camera(app) -> CameraSource:
    """On Kivy's main thread: the camera named by ``app.act_camera`` (see the module doc).
    Raises :class:`ar.camera_sources.CameraSourceError` naming the camera and the problem."""
    from app.player.app_renderer import kivy_camera_index  # deferred: the camera choice, only when filming
    from ar.camera_sources import open_camera_source  # deferred: OpenCV, only when filming

    choice = getattr(app, "act_camera", None) or DESKTOP_ACT_CAMERA
    index = kivy_camera_index(choice)
    if index is not None:
        from app.ui.kivy_camera import KivyCameraSource  # deferred: the Kivy camera provider, only for it

        factory = getattr(app, "kivy_camera_factory", None)
        return KivyCameraSource(index, camera=factory(index) if factory is not None else None)
    return open_camera_source(choice, paced=True, loop=True)


class CameraPreview(StencilView):
    """The camera picture (fitted, aspect kept), the body-outline guide and the skeleton
    (clipped to the widget: a limb outside the picture is drawn up to its edge).

    :meth:`show` takes a BGR frame and its pose (or None) on Kivy's thread; the frame is
    copied into the texture and not kept. ``guide_ok`` colours the outline green when the
    whole body is seen in the last frame."""

    countdown = StringProperty("")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.texture: Texture | None = None
        self.image_size: tuple[int, int] | None = None
        self.pose = None
        self.frames_shown = 0
        self.skeletons_drawn = 0
        self.guide_ok = False
        self._drawing = Canvas()  # in the stencilled canvas, under the countdown label
        self.canvas.add(self._drawing)
        self.count_label = Label(text="", font_size=dp(120), bold=True, color=(1, 1, 1, 1), outline_width=4,
                                 outline_color=(0.1, 0.1, 0.2, 1))
        self.add_widget(self.count_label)
        self.bind(pos=self.redraw, size=self.redraw, countdown=self._count)

    def _count(self, *_: object) -> None:
        self.count_label.text = self.countdown

    def show(self, frame: np.ndarray, pose) -> None:
        h, w = frame.shape[:2]
        if self.texture is None or self.image_size != (w, h):
            self.texture = Texture.create(size=(w, h), colorfmt="rgb")
            self.texture.flip_vertical()  # camera rows run top-down
            self.image_size = (w, h)
        self.texture.blit_buffer(np.ascontiguousarray(frame[:, :, ::-1]).tobytes(), colorfmt="rgb",
                                 bufferfmt="ubyte")
        self.pose = pose
        self.guide_ok = frame_problem(pose, (w, h)) is None
        self.frames_shown += 1
        self.redraw()

    def release(self) -> None:
        """Forget the picture (the view is closing)."""
        self.texture, self.pose = None, None
        self.redraw()

    def picture_rect(self) -> tuple[float, float, float]:
        """Where the picture is drawn: left, bottom and the scale (pixels per image pixel)."""
        w, h = self.image_size or (640, 480)
        s = min(self.width / w, self.height / h)
        return self.center_x - w * s / 2, self.center_y - h * s / 2, s

    def redraw(self, *_: object) -> None:
        self.count_label.pos, self.count_label.size = self.pos, self.size
        self._drawing.clear()
        x0, y0, s = self.picture_rect()
        w, h = self.image_size or (640, 480)
        with self._drawing:
            Color(0.12, 0.12, 0.16, 1)
            Rectangle(pos=self.pos, size=self.size)
            if self.texture is not None:
                Color(1, 1, 1, 1)
                Rectangle(texture=self.texture, pos=(x0, y0), size=(w * s, h * s))
            # the body-outline guide: where to stand, the whole body inside the picture
            Color(*(_GOOD if self.guide_ok else (1, 1, 1)), 0.85)
            gh = h * s * 0.86
            gx, gy = x0 + w * s / 2, y0 + h * s * 0.07
            r = gh * 0.075
            lw = dp(2.5)
            Line(circle=(gx, gy + gh - r, r), width=lw)
            Line(rounded_rectangle=(gx - gh * 0.13, gy + gh * 0.45, gh * 0.26, gh * 0.38, gh * 0.05), width=lw)
            Line(points=[gx - gh * 0.07, gy + gh * 0.45, gx - gh * 0.09, gy], width=lw)
            Line(points=[gx + gh * 0.07, gy + gh * 0.45, gx + gh * 0.09, gy], width=lw)
            Line(points=[gx - gh * 0.13, gy + gh * 0.8, gx - gh * 0.24, gy + gh * 0.5], width=lw)
            Line(points=[gx + gh * 0.13, gy + gh * 0.8, gx + gh * 0.24, gy + gh * 0.5], width=lw)
            if self.pose is not None and self.texture is not None:
                self._draw_skeleton(x0, y0, s, h)

    def _draw_skeleton(self, x0: float, y0: float, s: float, h: int) -> None:
        xy = np.asarray(self.pose.image_xy, float)
        px = x0 + xy[:, 0] * s
        py = y0 + (h - xy[:, 1]) * s  # image rows run down, Kivy's y up
        Color(1.0, 0.85, 0.1, 1)
        for a, b in SKELETON_BONES:
            Line(points=[px[a], py[a], px[b], py[b]], width=dp(3), cap="round")
        Color(1.0, 0.45, 0.1, 1)
        r = dp(5)
        for i in FACE:
            Ellipse(pos=(px[i] - r, py[i] - r), size=(2 * r, 2 * r))
        self.skeletons_drawn += 1


class PromptPicture(Widget):
    """A picture a child who cannot read understands: what went wrong (crossed out, red)
    and what to do (ticked, green). ``reason``: step_back, lift_head or no_body."""

    reason = StringProperty("")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.bind(pos=self.redraw, size=self.redraw, reason=self.redraw)

    def redraw(self, *_: object) -> None:
        self.canvas.clear()
        if not self.reason:
            return
        s = min(self.width / 2.4, self.height)
        left = (self.center_x - 1.15 * s, self.center_y - s / 2)
        right = (self.center_x + 0.15 * s, self.center_y - s / 2)
        with self.canvas:
            for (x, y), good in ((left, False), (right, True)):
                Color(1, 1, 1, 1)
                RoundedRectangle(pos=(x, y), size=(s, s), radius=[s * 0.06])
                self._scene(x, y, s, good)
                self._mark(x + s * 0.82, y + s * 0.82, s * 0.13, good)
            Color(0.3, 0.3, 0.35, 1)  # the arrow from wrong to right
            ax, ay = self.center_x, self.center_y
            Line(points=[ax - 0.1 * s, ay, ax + 0.06 * s, ay], width=max(2.0, s * 0.03))
            Triangle(points=[ax + 0.13 * s, ay, ax + 0.04 * s, ay + 0.06 * s, ax + 0.04 * s, ay - 0.06 * s])

    def _scene(self, x: float, y: float, s: float, good: bool) -> None:
        """The camera's picture (a frame) and the child in it."""
        fx, fy, fw, fh = x + 0.12 * s, y + 0.1 * s, 0.66 * s, 0.72 * s  # the camera's picture
        Color(0.55, 0.8, 0.95, 1)
        Rectangle(pos=(fx, fy), size=(fw, fh))
        Color(0.2, 0.2, 0.3, 1)
        Line(rectangle=(fx, fy, fw, fh), width=max(1.5, s * 0.02))
        if self.reason == NO_BODY and not good:
            return  # nobody in the picture
        if self.reason == STEP_BACK and not good:  # too close: the child is bigger than the picture
            _child(fx + fw / 2, fy - 0.55 * fh, fh * 1.9, head_down=False, clip=(fx, fy, fw, fh))
            return
        _child(fx + fw / 2, fy + 0.06 * fh, fh * 0.86 if self.reason != STEP_BACK else fh * 0.7,
               head_down=self.reason == LIFT_HEAD and not good)
        if self.reason == LIFT_HEAD and good:  # "up!": an arrow beside the raised face
            Color(*_GOOD, 1)
            ax, ay = fx + 0.8 * fw, fy + 0.62 * fh
            Line(points=[ax, ay, ax, ay + 0.2 * fh], width=max(2.0, s * 0.025), cap="round")
            Triangle(points=[ax - 0.07 * fw, ay + 0.18 * fh, ax + 0.07 * fw, ay + 0.18 * fh, ax, ay + 0.3 * fh])

    @staticmethod
    def _mark(cx: float, cy: float, r: float, good: bool) -> None:
        Color(*(_GOOD if good else _BAD), 1)
        Ellipse(pos=(cx - r, cy - r), size=(2 * r, 2 * r))
        Color(1, 1, 1, 1)
        if good:
            Line(points=[cx - 0.5 * r, cy, cx - 0.1 * r, cy - 0.45 * r, cx + 0.55 * r, cy + 0.45 * r],
                 width=max(1.5, 0.18 * r), cap="round", joint="round")
        else:
            for sx in (-1, 1):
                Line(points=[cx - 0.45 * r, cy - sx * 0.45 * r, cx + 0.45 * r, cy + sx * 0.45 * r],
                     width=max(1.5, 0.18 * r), cap="round")


def _child(cx: float, bottom: float, height: float, head_down: bool, clip=None) -> None:
    """A simple child figure standing at ``bottom``, ``height`` tall; ``head_down`` bows the
    head so the face is hidden (hair on top, no eyes). ``clip``: only what falls inside
    this rectangle is drawn (a figure too big for the picture)."""
    from kivy.graphics import ScissorPop, ScissorPush  # deferred: only for a clipped figure

    h = height
    if clip is not None:
        ScissorPush(x=int(clip[0]), y=int(clip[1]), width=int(clip[2]), height=int(clip[3]))
    lw = max(2.0, h * 0.045)
    Color(0.95, 0.5, 0.4, 1)  # body
    RoundedRectangle(pos=(cx - 0.12 * h, bottom + 0.42 * h), size=(0.24 * h, 0.33 * h), radius=[0.05 * h])
    Color(0.25, 0.3, 0.6, 1)  # legs and arms
    Line(points=[cx - 0.06 * h, bottom + 0.43 * h, cx - 0.08 * h, bottom], width=lw, cap="round")
    Line(points=[cx + 0.06 * h, bottom + 0.43 * h, cx + 0.08 * h, bottom], width=lw, cap="round")
    Color(0.95, 0.5, 0.4, 1)
    Line(points=[cx - 0.12 * h, bottom + 0.72 * h, cx - 0.22 * h, bottom + 0.45 * h], width=lw, cap="round")
    Line(points=[cx + 0.12 * h, bottom + 0.72 * h, cx + 0.22 * h, bottom + 0.45 * h], width=lw, cap="round")
    r = 0.1 * h
    hx, hy = cx, bottom + 0.75 * h + (0.55 * r if head_down else r)
    Color(1.0, 0.84, 0.7, 1)  # face
    Ellipse(pos=(hx - r, hy - r), size=(2 * r, 2 * r))
    Color(0.35, 0.2, 0.1, 1)  # hair
    if head_down:  # seen from the top of the head: hair over the face
        Ellipse(pos=(hx - r, hy - 0.7 * r), size=(2 * r, 1.8 * r))
    else:
        Ellipse(pos=(hx - r, hy + 0.2 * r), size=(2 * r, 0.9 * r))
        Color(0.1, 0.1, 0.1, 1)
        for ex in (-0.35, 0.35):
            Ellipse(pos=(hx + ex * r - 0.12 * r, hy - 0.15 * r), size=(0.24 * r, 0.24 * r))
        Line(ellipse=(hx - 0.35 * r, hy - 0.6 * r, 0.7 * r, 0.5 * r, 110, 250), width=max(1.0, 0.06 * r))
    if clip is not None:
        ScissorPop()


class ActItOutView(ModalView):
    """Camera preview, 3-2-1, a take, then the nearest motions (or a picture prompt).

    ``on_pick(label, trial)`` is called with the chosen clip. ``state`` is one of
    ``starting``, ``ready`` (preview, waiting for the start button), ``countdown``,
    ``take``, ``looking`` (searching), ``results``, ``prompt`` (too little of the body
    seen), ``failed`` (no camera, no pose estimator: said on screen)."""

    def __init__(self, on_pick: Callable[[str, str], object], camera: CameraSource | None = None,
                 flow: ActItOut | None = None, **kwargs):
        kwargs.setdefault("size_hint", (0.94, 0.95))
        kwargs.setdefault("auto_dismiss", False)
        super().__init__(**kwargs)
        app = App.get_running_app()
        self.t, self.on_pick = app.t, on_pick
        self.library = act_library(app)
        self._check_runtime = flow is None  # a flow given (tests) brings its own tracker
        self.flow = flow or ActItOut(None)
        self.thumbs = app.motion_thumbnails()
        self.state = "starting"
        self.verdict = None
        self.hits: list = []
        self.tiles: list[ClipTile] = []
        self.takes = 0
        self.last_take: dict = {}
        self.error: str | None = None
        self._camera = camera
        self._go = threading.Event()
        self._closing = threading.Event()
        self._latest = None
        self._latest_lock = threading.Lock()
        self._show_pending = False
        self._thread: threading.Thread | None = None
        self._count_event = None

        box = filled(BoxLayout(orientation="vertical", padding=dp(12), spacing=dp(8)), (1, 0.96, 0.9, 1))
        self.title = big_label(self.t("act_title"), 22)
        box.add_widget(self.title)
        row = BoxLayout(spacing=dp(12))
        self.preview = CameraPreview(size_hint_x=0.55)
        row.add_widget(self.preview)
        right = BoxLayout(orientation="vertical", spacing=dp(6))
        self.status = big_label(self.t("act_hint"), 17, halign="center", valign="middle")
        self.status.bind(width=lambda lbl, w: setattr(lbl, "text_size", (w, None)))
        right.add_widget(self.status)
        self.prompt = PromptPicture(size_hint_y=None, height=0, opacity=0)  # shown after a refused take
        right.add_widget(self.prompt)
        scroll, self.grid = tile_grid(2, TILE_DP)
        right.add_widget(scroll)
        self.start_button = IconButton("act", self.t("act_start"), on_press=self.start_take, size_hint_y=None,
                                       height=dp(96), font_size=dp(18), background=[0.75, 0.95, 0.75, 1])
        right.add_widget(self.start_button)
        row.add_widget(right)
        box.add_widget(row)
        self.back_button = IconButton("delete", self.t("back"), on_press=self.close, size_hint_y=None,
                                      height=dp(64))
        box.add_widget(self.back_button)
        self.add_widget(box)
        self._set_start(False)
        Clock.schedule_once(lambda dt: self._begin(), 0)

    # -- set-up -------------------------------------------------------------------
    def _begin(self) -> None:
        if self._check_runtime:
            problem = pose_runtime_problem()
            if problem is not None:
                return self._fail(problem)
        if self._camera is None:
            try:
                self._camera = open_act_camera(App.get_running_app())
            except StoryBeamError as exc:
                return self._fail(str(exc), "no_camera")
        self._thread = threading.Thread(target=self._work, name="storybeam-act-it-out", daemon=True)
        self._thread.start()
        self.library.when_ready(lambda: Clock.schedule_once(lambda dt: self._library_ready(), 0))

    def _library_ready(self) -> None:
        if self.library.error is not None:
            return self._fail(self.library.error)
        self.flow.search = self.library.search
        if self.state == "starting":
            self.state = "ready"
            self._set_start(True)

    def _fail(self, why: str, notice: str = "oops") -> None:
        """Act it out cannot go on: the notice's picture and sentence (spoken) for the child,
        the reason in the log."""
        self._closing.set()  # the worker stops and closes the camera; Back closes the view
        self.state, self.error, self.notice = "failed", why, notice
        log_notice(notice, f"act it out unavailable: {why}")
        self.status.text = notice_sentence(self.t, notice)
        parent = self.prompt.parent
        if parent is not None and getattr(self, "notice_picture", None) is None:
            self.notice_picture = NoticePicture(notice, size_hint_y=None, height=dp(PROMPT_DP))
            parent.add_widget(self.notice_picture, index=parent.children.index(self.prompt))
        app = App.get_running_app()
        if getattr(app, "speaker", None) is not None:
            app.speaker.say(self.status.text, app.lang)
        self._set_start(False)

    def _set_start(self, on: bool) -> None:
        self.start_button.disabled = not on
        self.start_button.opacity = 1.0 if on else 0.4

    # -- the worker: preview, take, verdict, results --------------------------------
    def _publish(self, _index: int, frame: np.ndarray, pose) -> None:
        """On the worker: the newest frame for the preview (an older one not yet shown goes)."""
        with self._latest_lock:
            self._latest = (frame, pose)
            if self._show_pending:
                return
            self._show_pending = True
        Clock.schedule_once(self._show_latest, 0)

    def _show_latest(self, _dt) -> None:
        with self._latest_lock:
            latest, self._latest, self._show_pending = self._latest, None, False
        if latest is not None and not self._closing.is_set():
            self.preview.show(*latest)

    def _work(self) -> None:
        camera = self._camera
        try:
            while not self._closing.is_set():
                self.flow.watch(camera, until=lambda: self._go.is_set() or self._closing.is_set(),
                                on_frame=self._publish)
                if self._closing.is_set():
                    break
                if not self._go.is_set():
                    raise StoryBeamError(f"camera {camera.name}: no more pictures")
                take = self.flow.take_from_source(camera, on_frame=self._publish, stop=self._closing)
                self._go.clear()
                if self._closing.is_set():
                    break
                Clock.schedule_once(lambda dt: self._looking(), 0)
                verdict = self.flow.judge(take)
                hits = []
                self.last_take = {"frames": len(take.poses), "fps": take.fps, "pose_ms_median": take.pose_ms_median,
                                  "detect_rate": take.detect_rate}  # numbers only (what the tests report)
                if verdict.ok:
                    self.library.wait()
                    t0 = time.perf_counter()
                    hits = self.flow.results(take, k=RESULTS)
                    self.last_take["search_ms"] = (time.perf_counter() - t0) * 1e3
                del take  # the landmarks go too: they were for this take only
                Clock.schedule_once(lambda dt, v=verdict, h=hits: self._finished(v, h), 0)
        except StoryBeamError as exc:
            why = str(exc)
            Clock.schedule_once(lambda dt: self._fail(why), 0)
        except Exception as exc:  # noqa: BLE001 - a camera or runtime failing its own way: said on screen, not a crash
            log.exception("act it out: the camera worker failed")
            why = f"{type(exc).__name__}: {exc}"
            Clock.schedule_once(lambda dt: self._fail(why), 0)
        finally:
            with self._latest_lock:
                self._latest = None
            camera.close()

    # -- the child's side -----------------------------------------------------------
    def start_take(self) -> None:
        """The start button: 3-2-1, then the take."""
        if self.state not in ("ready", "results", "prompt"):
            return
        self.state = "countdown"
        self._set_start(False)
        self.prompt.opacity, self.prompt.reason, self.prompt.height = 0, "", 0
        self.grid.clear_widgets()
        self.tiles = []
        self.status.text = self.t("act_get_ready")
        self._count(3)

    def _count(self, n: int) -> None:
        if self._closing.is_set():
            return
        if n == 0:
            self.preview.countdown = self.t("act_go")
            self.state = "take"
            self.status.text = self.t("act_moving")
            self._go.set()
            return
        self.preview.countdown = str(n)
        self._count_event = Clock.schedule_once(lambda dt: self._count(n - 1), COUNT_S)

    def _looking(self) -> None:
        self.state = "looking"
        self.preview.countdown = ""
        self.status.text = self.t("act_looking")

    def _finished(self, verdict, hits) -> None:
        if self._closing.is_set():
            return
        self.takes += 1
        self.verdict, self.hits = verdict, hits
        self.preview.countdown = ""
        self.start_button.text = self.t("act_again")
        self._set_start(True)
        if not verdict.ok:
            self.state = "prompt"
            self.prompt.reason = verdict.reason
            self.prompt.opacity, self.prompt.height = 1, dp(PROMPT_DP)
            self.status.text = self.t(f"act_{verdict.reason}")
            return
        self.state = "results"
        self.status.text = self.t("act_found") if hits else self.t("no_clips")
        for h in hits:
            name = clip_tile_name(self.t, h.label, h.trial, App.get_running_app().catalog.number_of)
            tile = ClipTile(h.trial, name, h.label if h.label in MOTION_COLOURS else "more",
                            MOTION_COLOURS.get(h.label, (0.4, 0.4, 0.4)), self.thumbs, lambda h=h: self._pick(h))
            self.tiles.append(tile)
            self.grid.add_widget(tile)

    def _pick(self, hit) -> None:
        self.close()
        self.on_pick(hit.label, hit.trial)

    def close(self) -> None:
        """Stop the camera and the worker, forget the picture, close the view."""
        self._closing.set()
        if self._count_event is not None:
            self._count_event.cancel()
        self.preview.release()
        self.dismiss()

    def on_dismiss(self):
        self._closing.set()
        self.preview.release()


__all__ = ["ActItOutView", "CameraPreview", "PromptPicture", "act_library", "open_act_camera",
           "ANDROID_ACT_CAMERA", "DESKTOP_ACT_CAMERA"]
