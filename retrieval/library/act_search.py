"""Search by performance ("Act it out"): the library clips nearest to a camera take.

:class:`ActSearch` is a frontal-feature motion index beside the 3-D one: every library
clip's features are those of the ``"frontal"`` set (:mod:`retrieval.features.frontal`:
the clip turned to its mean heading, depth dropped, MR17's distances and heights), and
so are the query's:

* a camera take — BlazePose landmarks per frame — becomes canonical joint positions with
  the root height from the image (:func:`retrieval.motion.landmarks.landmarks_to_positions`),
  then frontal features divided by the performer's leg length measured on the landmarks
  (:meth:`ActSearch.search_take`);
* true joint positions (a mocap clip, the evaluation's ceiling) take the same path from
  the positions on (:meth:`ActSearch.search_positions`).

**Per segment.** The frontal set's *relative* features (the ankle–hip distances, per
their median over the segment: :meth:`FrontalFeatureSet.relative_to_segment`) are made
relative per library window and per query, so a window and a take of the same motion
agree whatever the clip around the window does.

**Take-long windows.** A take lasts 3–4 s; library clips last 1–40 s (CMU's dances 4–16
s). DTW of a short take against a long clip must warp the whole clip onto the take, so
the library is indexed as *windows* of :data:`WINDOW_SECONDS` (the take's length) every
half window; a clip shorter than 1.25 windows is one entry. A take shorter than
:data:`SHORT_TAKE_SECONDS` (a child's kick lasts 2 s) is searched in a second index of
:data:`SHORT_WINDOW_SECONDS` windows (:attr:`ActSearch.short`), the same rule — a window
the take's length — for the short takes that break it against 3.5 s windows: synthetic
2 s takes (``storybeam bench act-cameras``, "short") 0.883 → 0.967 (kicks 5 → 8 of 9),
the real development set 30 → 31 of 47 (a 2.4 s drop kick found). A take longer than
:data:`LONG_TAKE_WINDOWS` (1.5) windows (a whole video passed to ``storybeam search
--video``) is cut the same way, into windows every half window, and their answers are
combined by class (:meth:`ActSearch._search_long`). A clip's distance is its nearest
window's, and each clip is answered once (:attr:`Match.start_s` / ``end_s`` say which
part matched). Measured on the true joints of the 145 CMU trials the reported bench does
not perform (their middle 3.5 s as the query, own trial left out, 1-NN):
whole clips 0.910, windows of 3.5 s 0.945 (dance 0.62 → 0.81), 4 s 0.938, 5 s 0.931.

The search is StoryBeam's own method (:class:`~retrieval.library.storybeam_search.StoryBeamSearcher`):
2-bit codes shortlist the windows, with a few places (:data:`ACT_SUMMARY`) for the windows
nearest by their summary (each feature's mean and spread), and exact float DTW on the
frontal features ranks them;
``exclude`` leaves named trials out (the query's own trial, or all of its subject's, for
evaluation) by dropping their windows from the shortlist before ranking, so the answer
is what a library without them would give, up to the quantiser (fitted once, on the
whole library). On disk an ActSearch is a :class:`~retrieval.library.index.MotionIndex`
folder (one entry per window) plus ``act.json`` (per entry: clip name, start frame,
subject and motion file).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Collection, Mapping, Sequence

import numpy as np

from retrieval.errors import IndexFormatError, StoryBeamError
from retrieval.features import FrontalFeatureSet, get_feature_set, measured_rest
from retrieval.library.clip import Clip, Match
from retrieval.library.dataset import load_dataset
from retrieval.library.index import MotionIndex
from retrieval.library.storybeam_search import StoryBeamSearcher
from retrieval.motion import CANONICAL_JOINTS, landmarks_to_positions

#: The feature set of the act index.
FEATURE_SET = "frontal"
#: Windows the code search shortlists for exact DTW. Wider than the 3-D index's: a
#: camera take's features are noisier than a mocap clip's, so its codes are a rougher
#: guide. Measured on the tuning takes (seed 1, 60 per figure, ar.body, the first version of
#: the features — before consistent sides and relative ankle–hip): 24 → person
#: 0.883, kid 0.550; 64 → 0.917, 0.550; 128 → 0.917, 0.533 (1-NN, trial left out);
#: search 3.4 / 4.9 / 7.7 ms median on one (shared) core.
ACT_SHORTLIST = 64
#: Of the :data:`ACT_SHORTLIST` windows, how many come from the clip-summary ranking
#: (:func:`~retrieval.search.summary.clip_summary`, each feature's mean and
#: spread over the window) instead of the code search: the 3-D index's answer to a style
#: it has never seen (issue 31), and a camera take is such a style. The 2-bit codes of a
#: camera take are shifted frame by frame by the estimator's noise, and the code search
#: then drops windows that exact DTW ranks first. Measured on the real development set
#: (``storybeam bench act-it-out --videos``): 0 → 38 of 47, 8 → 39 (a skipping-rope jump
#: whose nearest window by exact DTW over the whole library, a CMU jump, the codes had
#: not shortlisted); 16 and 32 gave the same 39. Rendered guard and act-cameras: see
#: docs/notebook/act-it-out.md, 2026-11-28, sixth round.
ACT_SUMMARY = 8
#: Length of a library window (seconds): a take's length (see the module docstring).
WINDOW_SECONDS = 3.5
#: Windows ranked by exact DTW per clip answered (a clip's windows overlap and may
#: crowd the top of the ranking; each clip is answered once). When the top
#: ``RANK_FACTOR·k`` windows hold fewer than ``k`` clips, every shortlisted window is ranked.
RANK_FACTOR = 3
#: Length of the second index's windows (seconds) and the take length under which it
#: answers (see the module docstring).
SHORT_WINDOW_SECONDS = 2.0
SHORT_TAKE_SECONDS = 2.75
#: A take longer than this many library windows is searched window by window (see
#: :meth:`ActSearch.search_features`), a window the library's length every half window.
LONG_TAKE_WINDOWS = 1.5
#: How deep each of a long take's windows is read when their answers are combined.
LONG_DEPTH = 5
#: At most this many of a long take's windows are searched (evenly spread over the take):
#: bounds the time of a minute-long video.
LONG_MAX_WINDOWS = 16
#: Subfolder of a saved act search holding its short-window index.
SHORT_FOLDER = "short"
ACT_JSON = "act.json"


def resample_positions(pos: np.ndarray, fps: float, to_fps: float) -> np.ndarray:
    """(T, J, 3) positions at ``fps`` linearly resampled to ``to_fps`` (same duration)."""
    pos = np.asarray(pos, dtype=np.float64)
    if abs(fps - to_fps) < 1e-9 or len(pos) < 2:
        return pos
    n = max(2, int(round((len(pos) - 1) * to_fps / fps)) + 1)
    src = np.arange(len(pos)) / fps
    dst = np.arange(n) / to_fps
    flat = pos.reshape(len(pos), -1)
    return np.stack([np.interp(dst, src, flat[:, c]) for c in range(flat.shape[1])], axis=1).reshape(n, *pos.shape[1:])


def windows(clips: Sequence[Clip], seconds: float = WINDOW_SECONDS) -> list[tuple[Clip, str, int]]:
    """``clips`` cut into windows of ``seconds`` every half window (the last one ending
    at the clip's end), as (window clip named ``trial@start``, the clip's trial, start
    frame); a clip shorter than 1.25 windows, or ``seconds`` ≤ 0, stays whole (start 0)."""
    out = []
    for c in clips:
        w = int(round(seconds * c.fps))
        if seconds <= 0 or c.n_frames <= 1.25 * w:
            out.append((c, c.trial, 0))
            continue
        starts = list(range(0, c.n_frames - w + 1, max(1, w // 2)))
        if starts[-1] != c.n_frames - w:
            starts.append(c.n_frames - w)
        out += [(Clip(f"{c.trial}@{s}", c.label, c.features[s:s + w], None, c.fps, c.source, c.subject), c.trial, s)
                for s in starts]
    return out


@dataclass(frozen=True)
class Augment:
    """Library-side augmentation of the act index, made from the library's own trials at
    build time (never new clips); every derived window carries its source trial's name,
    so ``exclude`` leaves it out with its source:

    * ``mirror``: every clip also left/right mirrored (the sided feature columns swapped,
      :func:`mirror_permutation`) — a kick with the other leg;
    * ``tempos``: every clip also played at these speeds (features resampled in time,
      :func:`time_scale`; 1.25 = faster);
    * ``hops``: every ``jump`` clip's highest take-off–flight–landing cycle, found from the
      hips' height (:func:`hop_cycle`), tiled end to end at its own cadence into one
      window — a repeated jump in place (two-footed cycles only,
      :data:`HOP_FEET_CORRELATION`).
    """

    mirror: bool = False
    tempos: tuple[float, ...] = ()
    hops: bool = False
    #: Where a hop cycle is cut (:func:`hop_cycle`): None at the crouch and landing
    #: minima; a number ``d``, where the hips cross the clip's median height less ``d``
    #: (a light hop: the flight without the crouch).
    hop_dip: float | None = None

    def key(self) -> str:
        """The settings as a saved index records them (:meth:`ActSearch.load` compares)."""
        parts = (["mirror"] if self.mirror else []) + [f"x{t:g}" for t in self.tempos]
        if self.hops:
            parts.append("hops" if self.hop_dip is None else f"hops@{self.hop_dip:g}")
        return "+".join(parts) or "none"


#: The act index's augmentation (:class:`Augment`): every clip mirrored, and each
#: two-footed jump's light hop (the cycle cut 0.3 feature units below the hips' median)
#: tiled into a repeated jump in place. Chosen on the real development set (31 -> 34 of
#: 47 clips) against one take lower on five synthetic camera conditions of 60
#: (docs/notebook/act-it-out.md, 2026-11-28, third round).
AUGMENT = Augment(mirror=True, hops=True, hop_dip=0.3)
#: Label of the clips whose hop cycles are tiled, and the cycle's limits: the flight must
#: lift the hips this many (weighted) feature units above the clip's median, the cycle
#: last between these many seconds.
HOP_LABEL = "jump"
HOP_MIN_RISE = 0.2
HOP_SECONDS = (0.2, 1.6)
#: A cycle is tiled only when both ankles rise together (the correlation of their heights
#: over the cycle at least this): a two-footed jump, as a jump in place is; a hop on one
#: foot or a running jump is not tiled.
HOP_FEET_CORRELATION = 0.9


def _swap_side(name: str) -> str:
    """"lhand_rshoulder" -> "rhand_lshoulder": swap the l/r prefix of every word."""
    words = []
    for w in name.split("_"):
        if len(w) > 1 and w[0] in "lr" and w[1:] in ("hand", "ankle", "knee", "elbow", "hip", "shoulder", "foot", "toe"):
            w = ("r" if w[0] == "l" else "l") + w[1:]
        words.append(w)
    return "_".join(words)


def mirror_permutation(feature_set: str = "mr17") -> np.ndarray:
    """Column permutation that mirrors a feature matrix left/right (each sided feature
    exchanged with its partner, ``lhand_head`` ↔ ``rhand_head``; symmetric ones stay)."""
    names = get_feature_set(feature_set).names
    index = {n: i for i, n in enumerate(names)}
    perm = []
    for n in names:
        m = _swap_side(n)
        if m not in index:
            raise StoryBeamError(f"feature set {feature_set!r}: no mirror partner {m!r} for feature {n!r}")
        perm.append(index[m])
    return np.array(perm, dtype=np.int64)


def time_scale(features: np.ndarray, factor: float) -> np.ndarray:
    """Resample (T, d) features to round(T·factor) frames by linear interpolation."""
    if not factor > 0:
        raise StoryBeamError(f"time-scale factor must be positive, got {factor}")
    x = np.asarray(features, dtype=np.float64)
    n = max(2, int(round(len(x) * factor)))
    src = np.linspace(0.0, len(x) - 1, n)
    lo = np.floor(src).astype(np.int64)
    hi = np.minimum(lo + 1, len(x) - 1)
    t = (src - lo)[:, None]
    return x[lo] * (1 - t) + x[hi] * t


def hop_cycle(hips: np.ndarray, fps: float, dip: float | None = None) -> tuple[int, int] | None:
    """(first, last) frame of the highest jump of a hips-height series: from the crouch
    before take-off (the lowest point of the descent into the peak) to the lowest point
    of the landing after it, read on a 5-frame running mean — or, with ``dip``, from where
    the hips rise through the median less ``dip`` to where they fall through it; None when
    the peak rises less than :data:`HOP_MIN_RISE` above the median or the cycle's length
    is outside :data:`HOP_SECONDS`."""
    h = np.asarray(hips, dtype=np.float64)
    if len(h) < 5:
        return None
    h = np.convolve(np.pad(h, 2, mode="edge"), np.ones(5) / 5, mode="valid")
    peak = int(np.argmax(h))
    if h[peak] - np.median(h) < HOP_MIN_RISE:
        return None
    a = peak
    while a > 0 and h[a - 1] <= h[a]:
        a -= 1
    b = peak
    while b < len(h) - 1 and h[b + 1] <= h[b]:
        b += 1
    if dip is not None:  # cut higher up: the last frame under the level before the peak, the first after it
        level = np.median(h) - dip
        before, after = np.flatnonzero(h[a:peak + 1] < level), np.flatnonzero(h[peak:b + 1] < level)
        a = a + int(before[-1]) if before.size else a
        b = peak + int(after[0]) if after.size else b
    if not HOP_SECONDS[0] * fps <= b - a <= HOP_SECONDS[1] * fps:
        return None
    return a, b


def augmented_clips(clips: Sequence[Clip], augment: Augment, feature_set: str,
                    seconds: float) -> list[tuple[Clip, str, int, float]]:
    """What :class:`Augment` derives from ``clips``, as (clip, source trial, start frame
    in the source, source frames per derived frame) to be cut into windows like the
    originals: mirrored and tempo-changed whole clips, and per jump a ``seconds``-long
    window of its tiled hop cycle."""
    out: list[tuple[Clip, str, int, float]] = []
    perm = mirror_permutation(feature_set) if augment.mirror else None
    names = get_feature_set(feature_set).names
    hips, ankles = names.index("hips_height"), [names.index("lankle_height"), names.index("rankle_height")]
    for c in clips:
        variants = [c.features] + ([c.features[:, perm]] if perm is not None else [])
        for f in variants[1:]:
            out.append((replace(c, features=f.astype(c.features.dtype)), c.trial, 0, 1.0))
        for t in augment.tempos:
            for f in variants:
                out.append((replace(c, features=time_scale(f, 1.0 / t).astype(c.features.dtype)), c.trial, 0, t))
        if augment.hops and c.label == HOP_LABEL:
            cyc = hop_cycle(c.features[:, hips], c.fps, augment.hop_dip)
            if cyc is not None and np.corrcoef(c.features[cyc[0]:cyc[1], ankles].T)[0, 1] >= HOP_FEET_CORRELATION:
                a, b = cyc
                n = max(2, int(round(seconds * c.fps)))
                tiled = np.resize(c.features[a:b], (n, c.features.shape[1]))  # cycle after cycle (rows repeat)
                out.append((replace(c, features=tiled.astype(c.features.dtype)), c.trial, a, 1.0))
    return out


class ActSearch:
    """A frontal-feature index over a labelled library (see the module docstring):
    ``index`` a storybeam-method :class:`MotionIndex` built with a frontal feature set,
    one entry per window; per entry the clip's ``names``, window ``starts`` (frames),
    ``subjects`` and ``paths``, in the index's order. ``short``: the same library in
    :data:`SHORT_WINDOW_SECONDS` windows, which answers takes shorter than
    :data:`SHORT_TAKE_SECONDS` (None: every take is searched here)."""

    def __init__(self, index: MotionIndex, names: Sequence[str], starts: Sequence[int], subjects: Sequence[str],
                 paths: Sequence[str], shortlist: int = ACT_SHORTLIST, short: "ActSearch | None" = None,
                 augment: str = "none", summary: int = ACT_SUMMARY, window_seconds: float = WINDOW_SECONDS):
        fset = get_feature_set(index.feature_set)
        if not isinstance(fset, FrontalFeatureSet) or index.clip_features is None:
            raise StoryBeamError(f"an act search needs a storybeam index of frontal features ({FEATURE_SET!r}), got "
                                 f"{index.method} / {index.feature_set!r}")
        if not (len(names) == len(starts) == len(subjects) == len(paths) == len(index)):
            raise StoryBeamError(f"act search: {len(names)} names, {len(starts)} starts, {len(subjects)} subjects and "
                                 f"{len(paths)} paths for {len(index)} index entries")
        self.index = index
        self.names = [str(n) for n in names]
        self.starts = [int(s) for s in starts]
        self.subjects = [str(s) for s in subjects]
        self.paths = [str(p) for p in paths]
        self._entries: dict[str, list[int]] = {}
        for i, n in enumerate(self.names):
            self._entries.setdefault(n, []).append(i)
        self.shortlist = int(shortlist)
        #: Of the shortlist, the windows the clip-summary ranking brings (:data:`ACT_SUMMARY`).
        self.summary = min(int(summary), self.shortlist)
        own = index.storybeam_searcher  # the index's own, when it was built with these settings
        if own is not None and (own.shortlist, own.summary) == (self.shortlist, self.summary):
            self.searcher = own
        else:
            self.searcher = StoryBeamSearcher(index.quantizer, index.codes, index.clip_features, self.shortlist,
                                              index.band, index.backend, summary=self.summary)
        self.feature_set = fset
        if short is not None and (short.index.feature_set != index.feature_set or short.clip_names != self.clip_names):
            raise StoryBeamError("act search: the short-window index must hold the same clips and features")
        self.short = short
        #: :meth:`Augment.key` of the augmentation the index was built with.
        self.augment = str(augment)
        #: Length of the library's windows (seconds; 0: whole clips), which sets when a
        #: take counts as long.
        self.window_seconds = float(window_seconds)

    # ------------------------------------------------------------------ building
    @classmethod
    def from_clips(cls, clips: Sequence[Clip], dims: int = 6, shortlist: int = ACT_SHORTLIST,
                   feature_set: str = FEATURE_SET, window_seconds: float = WINDOW_SECONDS,
                   short_seconds: float | None = SHORT_WINDOW_SECONDS, augment: Augment = AUGMENT) -> "ActSearch":
        """An act search over ``clips`` (their features must be of ``feature_set``, a
        frontal set), cut into windows of ``window_seconds`` (0: whole clips), with a
        second index of ``short_seconds`` windows for short takes (None: none), and the
        windows ``augment`` derives from the clips (:class:`Augment`)."""
        if clips and clips[0].features.shape[1] != get_feature_set(feature_set).dim:
            raise StoryBeamError(f"act search: clips must carry {feature_set!r} features")
        if len({c.trial for c in clips}) != len(clips):
            raise StoryBeamError("act search: clip names must be unique")
        entries = windows(clips, window_seconds)
        for clip, trial, start, speed in augmented_clips(clips, augment, feature_set, window_seconds or WINDOW_SECONDS):
            entries += [(w, trial, start + int(round(s * speed))) for w, _, s in windows([clip], window_seconds)]
        fset = get_feature_set(feature_set)
        if isinstance(fset, FrontalFeatureSet) and fset.relative:  # per window, as a take is per take
            entries = [(replace(w, features=fset.relative_to_segment(w.features).astype(w.features.dtype)), n, s)
                       for w, n, s in entries]
        index = MotionIndex.from_clips([w for w, _, _ in entries], dims, feature_set=feature_set, method="storybeam",
                                       shortlist=shortlist, summary=min(ACT_SUMMARY, shortlist))
        short = None if short_seconds is None else cls.from_clips(clips, dims, shortlist, feature_set, short_seconds,
                                                                  None, augment)
        return cls(index, [n for _, n, _ in entries], [s for _, _, s in entries], [w.subject for w, _, _ in entries],
                   [w.source for w, _, _ in entries], shortlist, short, augment.key(),
                   window_seconds=window_seconds)

    @classmethod
    def build(cls, folder: str | Path, fps: float = 30.0, dims: int = 6,
              progress: Callable[[int, int], None] | None = None, shortlist: int = ACT_SHORTLIST,
              feature_set: str = FEATURE_SET, window_seconds: float = WINDOW_SECONDS,
              short_seconds: float | None = SHORT_WINDOW_SECONDS, augment: Augment = AUGMENT,
              moves: str | Path | None = None) -> "ActSearch":
        """Every clip of a labelled folder (:mod:`retrieval.library.dataset`) at ``fps``,
        and those of the labelled folder ``moves`` (the app's moves from other studios,
        ``assets/motions/moves``) whose trial names ``folder`` does not already hold."""
        clips = load_dataset(folder, fps=fps, feature_set=feature_set, progress=progress)
        if moves is not None:
            held = {c.trial for c in clips}
            clips += [c for c in load_dataset(moves, fps=fps, feature_set=feature_set) if c.trial not in held]
        return cls.from_clips(clips, dims, shortlist, feature_set, window_seconds, short_seconds, augment)

    def save(self, folder: str | Path) -> Path:
        folder = Path(folder)
        self.index.save(folder)
        (folder / ACT_JSON).write_text(json.dumps({"names": self.names, "starts": self.starts,
                                                   "subjects": self.subjects, "paths": self.paths,
                                                   "shortlist": self.shortlist, "summary": self.summary,
                                                   "relative": list(self.feature_set.relative),
                                                   "features": feature_key(self.feature_set),
                                                   "augment": self.augment,
                                                   "window_seconds": self.window_seconds}, indent=1))
        if self.short is not None:
            self.short.save(folder / SHORT_FOLDER)
        return folder

    @classmethod
    def load(cls, folder: str | Path, augment: Augment = AUGMENT) -> "ActSearch":
        """A saved act search; :class:`IndexFormatError` when it was built with other
        features or another augmentation than ``augment`` (rebuild it)."""
        folder = Path(folder)
        index = MotionIndex.load(folder)
        path = folder / ACT_JSON
        try:
            meta = json.loads(path.read_text())
            names, starts = list(meta["names"]), [int(s) for s in meta["starts"]]
            subjects, paths, shortlist = list(meta["subjects"]), list(meta["paths"]), int(meta["shortlist"])
            summary = int(meta.get("summary", ACT_SUMMARY))  # a folder saved before the summary places: today's
            relative, features = tuple(meta.get("relative", ())), meta.get("features")
            built = str(meta.get("augment", "none"))
            # a folder saved before the field: its windows are those of its folder's role
            window_s = float(meta.get("window_seconds", SHORT_WINDOW_SECONDS if folder.name == SHORT_FOLDER
                                      else WINDOW_SECONDS))
        except FileNotFoundError:
            raise IndexFormatError(f"{path}: not found (not an act search folder)") from None
        except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
            raise IndexFormatError(f"{path}: unreadable ({type(exc).__name__}: {exc})") from None
        if built != augment.key():
            raise IndexFormatError(f"{path}: built with the augmentation {built!r}, the act index now uses "
                                   f"{augment.key()!r}: rebuild it")
        short = cls.load(folder / SHORT_FOLDER, augment) if (folder / SHORT_FOLDER / ACT_JSON).is_file() else None
        try:
            search = cls(index, names, starts, subjects, paths, shortlist, short, built, summary, window_s)
        except StoryBeamError as exc:
            raise IndexFormatError(f"{folder}: {exc}") from None
        if relative != search.feature_set.relative:
            raise IndexFormatError(f"{path}: built with relative features {list(relative)}, the feature set "
                                   f"{search.feature_set.name!r} now has {list(search.feature_set.relative)}: rebuild it")
        if features != feature_key(search.feature_set):
            raise IndexFormatError(f"{path}: built with the feature set {search.feature_set.name!r} as "
                                   f"{features or 'an older version'}, it is now {feature_key(search.feature_set)}: "
                                   f"rebuild it")
        return search

    # ------------------------------------------------------------------ searching
    def __len__(self) -> int:
        """The number of library clips (each indexed as one or more windows)."""
        return len(self._entries)

    @property
    def clip_names(self) -> list[str]:
        """The library's clips, in library order."""
        return list(self._entries)

    @property
    def fps(self) -> float:
        return self.index.fps

    def take_features(self, world: np.ndarray, image_xy: np.ndarray, valid: np.ndarray, fps: float,
                      image_size: tuple[int, int] | None = None) -> np.ndarray:
        """(frames, 17) frontal features of a camera take at the index's frame rate."""
        pos, jm, leg = landmarks_to_positions(world, image_xy, valid, image_size, fps)
        return self.position_features(pos, fps, jm, leg)

    def position_features(self, positions: np.ndarray, fps: float, joint_map: Mapping[str, int],
                          body_size: float) -> np.ndarray:
        """(frames, 17) frontal features of (T, J, 3) joint positions (metres, Y up) at
        ``fps``, divided by ``body_size`` (the leg length, metres)."""
        pos = np.asarray(positions, dtype=np.float64)
        if pos.ndim != 3 or pos.shape[2] != 3 or len(pos) == 0 or not np.all(np.isfinite(pos)):
            raise StoryBeamError(f"a query must be finite (frames, joints, 3) positions, got shape {pos.shape}")
        if not fps > 0:
            raise StoryBeamError(f"fps must be positive, got {fps}")
        pos = resample_positions(pos, fps, self.fps)
        jm = dict(joint_map)
        return self.feature_set.from_positions(pos, jm, body_size, self.fps, measured_rest(pos, jm))

    def search_features(self, features: np.ndarray, k: int = 5, exclude: Collection[str] = ()) -> list[Match]:
        """The ``k`` nearest clips to (frames, 17) frontal features, nearest first, the
        trials named in ``exclude`` left out.

        The take is matched as the library is cut: a take shorter than
        :data:`SHORT_TAKE_SECONDS` against the 2 s windows (:attr:`short`), one up to
        :data:`LONG_TAKE_WINDOWS` windows long whole, and a longer one (a video of a
        minute, say) as windows of the library's length every half window, at most
        :data:`LONG_MAX_WINDOWS` of them (:meth:`_search_long`)."""
        if k < 1:
            raise StoryBeamError(f"k must be at least 1, got {k}")
        q = np.asarray(features)
        width = self.feature_set.dim
        if q.ndim != 2 or q.shape[1] != width or len(q) == 0 or not np.all(np.isfinite(q)):
            raise StoryBeamError(f"query features must be finite (frames, {width}), got shape {q.shape}")
        if self.short is not None and len(q) < SHORT_TAKE_SECONDS * self.fps:
            return self.short._search_whole(q, k, exclude)  # a short take: take-long windows
        w = int(round(self.window_seconds * self.fps))
        if w > 1 and len(q) > LONG_TAKE_WINDOWS * w:
            return self._search_long(q, w, k, exclude)
        return self._search_whole(q, k, exclude)

    def _search_long(self, features: np.ndarray, w: int, k: int, exclude: Collection[str]) -> list[Match]:
        """A long take, window by window: its windows of ``w`` frames (every half window,
        the last one ending with the take; at most :data:`LONG_MAX_WINDOWS`, evenly
        spread) are each searched whole for their :data:`LONG_DEPTH` nearest clips, and
        the answers are combined **by class**: a class scores, in each window, the rank
        of its first clip there (:data:`LONG_DEPTH` when it has none) and the class with
        the smallest sum over the windows wins (ties: the smaller sum of those clips'
        distances). The answer opens with the winning class's best clip; the other clips
        follow by their own rank sum, then their summed distances (a window a clip is
        absent from counts :data:`LONG_DEPTH` and its last clip's distance). Each clip's
        ``distance``, ``start_s`` and ``end_s`` are those of the window that matched it
        best.

        Why not the whole take: DTW must then warp a minute of movement onto 3.5 s of
        library. The development set's clips tiled two and three times lost 4 and 6 of
        47 searched whole; by windows combined so, 2 and 4 (docs/notebook/act-it-out.md,
        seventh round). Combined by class rather than by nearest window or by vote, which
        measured worse: one window that resembles another class does not decide. From
        1.5 windows on, not 1.25 (the library's own rule): a 4.4 s take cut into two
        3.5 s windows that nearly overlap gained nothing and lost clips on the smaller
        libraries."""
        n = len(features)
        starts = list(range(0, n - w + 1, max(1, w // 2)))
        if starts[-1] != n - w:
            starts.append(n - w)
        if len(starts) > LONG_MAX_WINDOWS:
            starts = [starts[int(round(i))] for i in np.linspace(0, len(starts) - 1, LONG_MAX_WINDOWS)]
        depth = max(k, LONG_DEPTH)
        answers = [self._search_whole(features[s:s + w], depth, exclude) for s in starts]
        answers = [a for a in answers if a]
        if not answers:
            return []
        best: dict[str, Match] = {}
        for a in answers:
            for m in a:
                if m.trial not in best or m.distance < best[m.trial].distance:
                    best[m.trial] = m
        class_rank, class_dist = _rank_sums(answers, lambda m: m.label, depth)
        clip_rank, clip_dist = _rank_sums(answers, lambda m: m.trial, depth)
        winner = min(class_rank, key=lambda c: (class_rank[c], class_dist[c], c))
        order = sorted(best, key=lambda t: (clip_rank[t], clip_dist[t], t))
        lead = next(t for t in order if best[t].label == winner)
        return [best[lead]] + [best[t] for t in order if t != lead][:k - 1]

    def _search_whole(self, features: np.ndarray, k: int, exclude: Collection[str]) -> list[Match]:
        """The ``k`` nearest clips to the whole (frames, 17) take (checked by the caller)."""
        # the library's float32 precision, as the index keeps its clips
        q = np.ascontiguousarray(np.asarray(features, dtype=np.float32), dtype=np.float64)
        # the relative columns per the query, as the library's per window (idempotent)
        q = np.ascontiguousarray(self.feature_set.relative_to_segment(q).astype(np.float32), dtype=np.float64)
        drop = {i for t in exclude for i in self._entries.get(t, ())}
        if len(drop) >= len(self.index):
            return []
        # several windows of one clip may rank high: rank RANK_FACTOR·k windows, answer k clips
        s = self.searcher
        cands = s.shortlist_of(q, RANK_FACTOR * k, exclude=drop)
        out: list[Match] = []
        seen: set[str] = set()
        fps = self.index.fps
        n_rank = min(len(cands), RANK_FACTOR * k)
        # numpy computes every candidate's DTW anyway: keep them all, so a crowded top needs no second sweep
        ranked = s.rerank(q, cands, len(cands) if s.reranks_every_candidate else n_rank)
        if len({self.names[h.index] for h in ranked[:n_rank]}) < k and len(ranked) < len(cands):
            ranked = s.rerank(q, cands, len(cands))  # a few clips' windows crowded the top: rank every candidate
        for h in ranked:
            name = self.names[h.index]
            if name in seen:
                continue
            seen.add(name)
            start = self.starts[h.index]
            out.append(Match(name, self.index.labels[h.index], h.distance, subject=self.subjects[h.index],
                             clip_path=self.paths[h.index], start_s=start / fps,
                             end_s=(start + len(self.index.codes[h.index])) / fps))
            if len(out) == k:
                break
        return out

    def search_take(self, world: np.ndarray, image_xy: np.ndarray, valid: np.ndarray, fps: float,
                    image_size: tuple[int, int] | None = None, k: int = 5,
                    exclude: Collection[str] = ()) -> list[Match]:
        """The ``k`` clips nearest to a camera take: BlazePose world landmarks (T, 33, 3),
        image landmarks (T, 33, 2) in pixels and per-frame ``valid`` flags (what
        ``BodyTake.arrays()`` gives, visibility aside) at ``fps``; trials in ``exclude`` are
        left out. :class:`~retrieval.motion.landmarks.LandmarkError` when no frame saw a body."""
        return self.search_features(self.take_features(world, image_xy, valid, fps, image_size), k, exclude)

    def search_positions(self, positions: np.ndarray, fps: float, k: int = 5, exclude: Collection[str] = (),
                         joint_map: Mapping[str, int] | None = None, body_size: float | None = None) -> list[Match]:
        """The ``k`` clips nearest to true joint positions (T, J, 3) (metres, Y up) at
        ``fps``: ``joint_map`` maps canonical names to columns (default: the canonical
        order, :data:`~retrieval.motion.CANONICAL_JOINTS`), ``body_size`` is the leg length
        in metres (default: measured on the positions, the median hip→knee→ankle
        length)."""
        pos = np.asarray(positions, dtype=np.float64)
        jm = dict(joint_map) if joint_map is not None else {n: i for i, n in enumerate(CANONICAL_JOINTS)}
        if pos.ndim != 3 or pos.shape[2] != 3 or pos.shape[1] <= max(jm.values(), default=0):
            raise StoryBeamError(f"a query must be (frames, joints, 3) positions with the {len(jm)} joints of its "
                                 f"joint map, got shape {pos.shape}")
        if body_size is None:
            body_size = positions_leg_length(pos, jm)
        return self.search_features(self.position_features(pos, fps, jm, body_size), k, exclude)


def _rank_sums(answers: Sequence[Sequence[Match]], key: Callable[[Match], str],
               depth: int) -> tuple[dict[str, float], dict[str, float]]:
    """For each name ``key`` gives a match (its class, or its clip) in any of ``answers``
    (one nearest-first list per window of a long take): the sum over the windows of the
    rank of its first match in that window and the sum of that match's distance; a window
    without one counts ``depth`` and its last match's distance
    (:meth:`ActSearch._search_long`)."""
    names = {key(m) for a in answers for m in a}
    ranks, dists = dict.fromkeys(names, 0.0), dict.fromkeys(names, 0.0)
    for a in answers:
        first: dict[str, tuple[int, float]] = {}
        for i, m in enumerate(a):
            first.setdefault(key(m), (i, m.distance))
        for name in names:
            i, d = first.get(name, (depth, a[-1].distance))
            ranks[name] += i
            dists[name] += d
    return ranks, dists


def feature_key(feature_set: FrontalFeatureSet) -> str:
    """What a saved act index's features depend on beyond their names: each feature's
    weight and the floor the heights stand on (an index built before a change to either
    no longer matches the queries, and :meth:`ActSearch.load` refuses it)."""
    weights = ",".join(f"{s.weight:g}" for s in feature_set.specs)
    return f"weights {weights}; floor p{feature_set.floor_percentile:g}"


def positions_leg_length(pos: np.ndarray, joint_map: Mapping[str, int]) -> float:
    """Median over frames of both legs' mean hip→knee→ankle length (metres)."""
    pos = np.asarray(pos, dtype=np.float64)
    try:
        legs = [np.linalg.norm(pos[:, joint_map[f"{s}_knee"]] - pos[:, joint_map[f"{s}_hip"]], axis=1)
                + np.linalg.norm(pos[:, joint_map[f"{s}_ankle"]] - pos[:, joint_map[f"{s}_knee"]], axis=1)
                for s in ("left", "right")]
    except KeyError as exc:
        raise StoryBeamError(f"positions lack the joint {exc.args[0]!r} needed for the leg length") from None
    size = float(np.median((legs[0] + legs[1]) / 2))
    if not size > 1e-6:
        raise StoryBeamError("zero leg length: cannot normalise the query")
    return size


__all__ = ["ACT_SHORTLIST", "ACT_SUMMARY", "AUGMENT", "Augment", "augmented_clips", "hop_cycle", "mirror_permutation", "time_scale", "WINDOW_SECONDS", "RANK_FACTOR", "SHORT_TAKE_SECONDS", "SHORT_WINDOW_SECONDS", "ActSearch",
           "FEATURE_SET", "feature_key",
           "positions_leg_length", "resample_positions", "windows"]
