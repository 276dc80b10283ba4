"""A saved, searchable motion library: StoryBeam's one search path.

:class:`MotionIndex` keeps, per clip, its trial name, label and 2-bit code sequence, plus
the fitted PCA/quantiser. Every question the product asks goes through the exact fast
search (:mod:`retrieval.search`) over the 20 KiB difference table — never the seed's
64 MiB table, never a loop over every clip:

* :meth:`MotionIndex.query` — the ``k`` clips nearest to a motion (or its features);
* :meth:`MotionIndex.similar_to` — "More like this": the clips nearest to an indexed one;
* :meth:`MotionIndex.subsequence` — the clips that pass through a short query, and where;
* :meth:`MotionIndex.among` — the nearest clips within a subset (the motion choice's class).

Two methods (``method``):

* ``"storybeam"`` — StoryBeam's own, the default of :meth:`MotionIndex.build` (the app,
  ``storybeam search`` and the demo build with it): features of the ``"storybeam"`` set
  (MR17 + turning rate), and :meth:`query` / :meth:`similar_to` answer by exact float DTW
  among the code shortlist (:class:`~retrieval.library.storybeam_search.StoryBeamSearcher`),
  so the shortlist's coarse ties are broken by an exact distance. The library's features
  are kept at float32 precision (rounded when the index is built, so a saved and
  reloaded index answers bit for bit the same; queries are rounded alike, so an indexed
  clip is at distance exactly 0 from itself).
* ``"quantized"`` — the seed's: the answers are those of the seed's look-up DTW against
  every clip, sorted (same clips, same distances bit for bit, ties by library order);
  the tests check it against :mod:`retrieval.search.reference`. The low-level
  constructors (:meth:`from_clips`, :meth:`from_motions`) default to it.

:meth:`subsequence`, :meth:`among` and the ``*_codes`` methods answer by code distance
under either method. On disk an index is a folder with ``index.json`` (format version,
method, settings, trials, labels) and ``index.npz`` (quantiser arrays, all codes
concatenated, per-clip offsets, and for ``storybeam`` the float32 features). An index
saved before the method existed loads as ``quantized``. ``index.json`` also records the
body the features were taken on (:func:`features_tag`; before issue 31 the file's own,
since then the canonical body for ``"storybeam"``): an index whose body is not the one
this StoryBeam computes a query on raises :class:`IndexFormatError` (build it again),
since its distances to a query would compare two bodies. Anything unreadable or
inconsistent raises :class:`IndexFormatError` naming the file.
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from retrieval.codes import DiffTable, Quantizer
from retrieval.errors import IndexFormatError, StoryBeamError
from retrieval.features import FeatureError, FeatureSet, get_feature_set
from retrieval.library.clip import Clip, Match
from retrieval.library.dataset import clip_from_motion, load_dataset
from retrieval.library.storybeam_search import SHORTLIST, SUMMARY, StoryBeamSearcher
from retrieval.motion import CANONICAL_POSE_VERSION, Motion
from retrieval.search import FastSearcher, SubsequenceSearcher

FORMAT = "storybeam-motion-index"
VERSION = 1


def features_tag(feature_set: str) -> str:
    """Which body a feature set's features are taken on, as a saved index records it:
    ``"source"`` (the file's own skeleton; also what an index saved before issue 31
    holds) or ``"canonical-<version>"`` (:func:`~retrieval.motion.canonical_pose`, its
    :data:`~retrieval.motion.body.CANONICAL_POSE_VERSION`). A feature set this StoryBeam
    does not know keeps the saved tag (nothing to compare)."""
    known = _known_set(feature_set)
    if known is None:
        return ""
    return f"canonical-{CANONICAL_POSE_VERSION}" if known.body == "canonical" else known.body


def _known_set(feature_set: str) -> FeatureSet | None:
    """The registered feature set of that name, None for one this StoryBeam does not know
    (a saved index then keeps what it recorded: nothing to compare)."""
    try:
        return get_feature_set(feature_set)
    except FeatureError:
        return None


METHODS = ("storybeam", "quantized")
JSON_NAME = "index.json"
NPZ_NAME = "index.npz"


class MotionIndex:
    """Nearest-clip search by table-look-up DTW over 2-bit PCA codes, through the exact
    fast search. ``backend`` is the DTW back-end ("auto": numba where installed, else the
    numpy path the tablet runs; both give the same answers)."""

    def __init__(self, quantizer: Quantizer, codes: Sequence[np.ndarray], trials: list[str], labels: list[str],
                 fps: float, feature_set: str = "mr17", band: int | None = None, backend: str = "auto",
                 method: str = "quantized", features: Sequence[np.ndarray] | None = None,
                 shortlist: int = SHORTLIST, summary: int = SUMMARY):
        if not (len(trials) == len(labels) == len(codes)):
            raise StoryBeamError("index: trials, labels and codes differ in length")
        if not codes:
            raise StoryBeamError("cannot build an index from no clips")
        if method not in METHODS:
            raise StoryBeamError(f"index: unknown method {method!r} (choose from {', '.join(METHODS)})")
        if method == "storybeam" and (features is None or len(features) != len(codes)
                                      or any(len(f) != len(c) for f, c in zip(features, codes))):
            raise StoryBeamError("index: the storybeam method needs one feature array per clip, as long as its codes")
        self.method = method
        self.shortlist = int(shortlist)
        self.summary = int(summary)
        self.quantizer = quantizer
        self.codes = [np.ascontiguousarray(c, dtype=np.int32) for c in codes]
        self.trials = list(trials)
        self.labels = list(labels)
        self.fps = float(fps)
        self.feature_set = feature_set
        self.band = band
        self.table = DiffTable.from_ratios(quantizer.ratios)
        self.searcher = FastSearcher(self.codes, self.table, band=band, backend=backend)
        self._storybeam: StoryBeamSearcher | None = None
        self.clip_features: list[np.ndarray] | None = None
        if method == "storybeam":
            # float32 precision, so that a saved and reloaded index answers bit for bit the same
            self.clip_features = [np.asarray(f, dtype=np.float32).astype(np.float64) for f in features]
            self._storybeam = StoryBeamSearcher(quantizer, self.codes, self.clip_features, shortlist, band, backend,
                                                searcher=self.searcher, summary=summary)
        self._subsequence: SubsequenceSearcher | None = None
        self._subsets: dict[tuple[int, ...], FastSearcher] = {}  # fast searchers over subsets (see among)
        self._position = {t: i for i, t in enumerate(self.trials)}

    @property
    def storybeam_searcher(self) -> StoryBeamSearcher | None:
        """The storybeam method's searcher over this index (its ``shortlist`` and
        ``summary``); None for the quantized method."""
        return self._storybeam

    # ------------------------------------------------------------------ building
    @classmethod
    def from_clips(cls, clips: Sequence[Clip], dims: int = 6, band: int | None = None,
                   feature_set: str = "mr17", backend: str = "auto", method: str = "quantized",
                   shortlist: int = SHORTLIST, summary: int = SUMMARY) -> "MotionIndex":
        if not clips:
            raise StoryBeamError("cannot build an index from no clips")
        fps = {round(c.fps, 6) for c in clips}
        if len(fps) != 1:
            raise StoryBeamError(f"clips have different frame rates {sorted(fps)}: resample them to one fps")
        # the codes see the set's coded columns only (the StoryBeam set's hand columns are not coded)
        quantizer = Quantizer.fit(np.concatenate([c.features for c in clips], axis=0), dims,
                                  get_feature_set(feature_set).code_columns)
        codes = [quantizer.encode(c.features) for c in clips]
        return cls(quantizer, codes, [c.trial for c in clips], [c.label for c in clips], clips[0].fps,
                   feature_set, band, backend, method, [c.features for c in clips] if method == "storybeam" else None,
                   shortlist, summary)

    @classmethod
    def build(cls, folder: str | Path, dims: int = 6, fps: float = 30.0, band: int | None = None,
              feature_set: str | None = None, progress: Callable[[int, int], None] | None = None,
              method: str = "storybeam") -> "MotionIndex":
        """Index every clip of a labelled folder (see :mod:`retrieval.library.dataset`) at
        ``fps``; ``progress(done, total)`` is called after each clip. The feature set
        defaults to the method's ("storybeam" for storybeam, "mr17" for quantized)."""
        fset = feature_set or ("storybeam" if method == "storybeam" else "mr17")
        clips = load_dataset(folder, fps=fps, feature_set=fset, progress=progress)
        return cls.from_clips(clips, dims, band, fset, method=method)

    @classmethod
    def from_motions(cls, motions: Sequence[Motion], labels: Sequence[str] | None = None, dims: int = 6,
                     fps: float = 30.0, band: int | None = None, method: str = "quantized") -> "MotionIndex":
        labels = list(labels) if labels is not None else [""] * len(motions)
        fset = "storybeam" if method == "storybeam" else "mr17"
        clips = [clip_from_motion(m, m.name or f"clip{i}", labels[i], fps, fset) for i, m in enumerate(motions)]
        return cls.from_clips(clips, dims, band, fset, method=method)

    # ------------------------------------------------------------------ searching
    def __len__(self) -> int:
        return len(self.trials)

    @property
    def dims(self) -> int:
        return self.quantizer.n

    @property
    def backend(self) -> str:
        """The DTW back-end the searches run on ("numba" or "numpy")."""
        return self.searcher.backend

    def features(self, query: Motion | Clip | np.ndarray) -> np.ndarray:
        """A query's (frames, 17) features: a motion is resampled to the index's fps."""
        if isinstance(query, Motion):
            return clip_from_motion(query, query.name or "query", "", self.fps, self.feature_set).features
        if isinstance(query, Clip):
            return query.features
        arr = np.asarray(query, dtype=np.float64)
        width = self.quantizer.pca.mean.shape[0]
        if arr.ndim != 2 or arr.shape[1] != width or arr.shape[0] == 0:
            raise StoryBeamError(f"query features must be (frames, {width}), got {arr.shape}")
        return arr

    def encode(self, query: Motion | Clip | np.ndarray) -> np.ndarray:
        """A query's 2-bit codes under this index's quantiser."""
        return self.quantizer.encode(self.features(query))

    def position(self, trial: str) -> int:
        """Library position of an indexed trial."""
        try:
            return self._position[trial]
        except KeyError:
            raise StoryBeamError(f"no clip {trial!r} in the index") from None

    def _nearest(self, codes: np.ndarray, k: int, exclude: int | None = None) -> list[Match]:
        if k <= 0:
            return []
        want = min(len(self), k + (exclude is not None))
        res = self.searcher.search([codes], k=want, parallel=False)
        out = [Match(self.trials[i], self.labels[i], float(d))
               for i, d in zip(res.indices[0], res.distances[0]) if i >= 0 and i != exclude]
        return out[:k]

    def among(self, codes: np.ndarray, positions: Sequence[int], k: int = 5,
              exclude: int | None = None) -> list[Match]:
        """The ``k`` clips nearest to ``codes`` among the library ``positions`` only (the
        library position ``exclude`` left out), nearest first.

        Method: the exact fast search (:class:`~retrieval.search.FastSearcher`) over just
        those clips, kept in library order, so the answer is the full search's answer
        filtered to them — same distances (a clip's distance does not depend on the other
        clips), ties by library order — at the cost of a search over the subset. The
        subset's searcher is built once and kept (a few subsets at a time; the whole library
        uses the index's own), and ``exclude`` is dropped from its answer rather than from
        the subset, so asking about each member of a class in turn reuses one searcher."""
        pos = tuple(sorted({int(p) for p in positions}))
        if pos and (pos[0] < 0 or pos[-1] >= len(self)):
            raise StoryBeamError(f"positions must lie in [0, {len(self)}), got {pos[0]}..{pos[-1]}")
        dropped = exclude is not None and exclude in pos
        if k <= 0 or len(pos) <= dropped:
            return []
        searcher = self.searcher if len(pos) == len(self) else self._subsets.get(pos)
        if searcher is None:
            if len(self._subsets) >= 8:
                self._subsets.clear()
            searcher = self._subsets[pos] = FastSearcher([self.codes[i] for i in pos], self.table, band=self.band,
                                                         backend=self.searcher.backend)
        res = searcher.search([np.ascontiguousarray(codes, dtype=np.int32)], k=min(k + dropped, len(pos)),
                              parallel=False)
        out = [Match(self.trials[pos[i]], self.labels[pos[i]], float(d))
               for i, d in zip(res.indices[0], res.distances[0]) if i >= 0 and pos[i] != exclude]
        return out[:k]

    def query(self, query: Motion | Clip | np.ndarray, k: int = 5) -> list[Match]:
        """The ``k`` nearest clips to a motion (resampled to the index's fps) or to a
        (frames, d) feature array of the index's feature set, nearest first (storybeam:
        by exact float DTW among the code and clip-summary shortlist; quantized: by code DTW)."""
        if self._storybeam is not None:
            # the query at the library's float32 precision: a clip's own features give exactly 0
            feats = np.asarray(self.features(query), dtype=np.float32).astype(np.float64)
            hits = self._storybeam.search(feats, k)
            return [Match(self.trials[h.index], self.labels[h.index], h.distance) for h in hits]
        return self.query_codes(self.encode(query), k)

    def query_codes(self, codes: np.ndarray, k: int = 5) -> list[Match]:
        """:meth:`query` for codes already encoded with this index's quantiser."""
        return self._nearest(np.ascontiguousarray(codes, dtype=np.int32), k)

    def similar_to(self, trial: str, k: int = 5) -> list[Match]:
        """The ``k`` clips nearest to an indexed clip (itself excluded)."""
        i = self.position(trial)
        if self._storybeam is not None:
            hits = self._storybeam.search(self.clip_features[i], k, codes=self.codes[i], exclude=i)
            return [Match(self.trials[h.index], self.labels[h.index], h.distance) for h in hits]
        return self._nearest(self.codes[i], k, exclude=i)

    def find(self, query: Motion | Clip | np.ndarray, k: int = 1) -> list[Match]:
        """"Find this clip": the ``k`` library clips most likely to *be* the query (the
        same clip from another file, skeleton or frame rate), nearest first. Storybeam
        indexes rank by exact float DTW on per-clip centred features among their own
        code shortlist (:meth:`StoryBeamSearcher.find`; distances are those centred
        DTWs); a quantized index has no float features and answers as :meth:`query`."""
        if self._storybeam is None:
            return self.query(query, k)
        feats = np.asarray(self.features(query), dtype=np.float32).astype(np.float64)
        hits = self._storybeam.find(feats, k)
        return [Match(self.trials[h.index], self.labels[h.index], h.distance) for h in hits]

    def subsequence(self, query: Motion | Clip | np.ndarray, k: int = 5) -> list[Match]:
        """The ``k`` clips that pass closest through a (short) query, each with the
        library frames ``[start, end)`` where it does, nearest first."""
        return self.subsequence_codes(self.encode(query), k)

    def subsequence_codes(self, codes: np.ndarray, k: int = 5) -> list[Match]:
        """:meth:`subsequence` for codes already encoded with this index's quantiser."""
        if k <= 0:
            return []
        if self._subsequence is None:
            self._subsequence = SubsequenceSearcher(self.codes, self.table, self.searcher.backend)
        hits = self._subsequence.search(np.ascontiguousarray(codes, dtype=np.int32), k=min(k, len(self)))
        return [Match(self.trials[h.index], self.labels[h.index], h.distance, h.start, h.end + 1) for h in hits]

    # ------------------------------------------------------------------ disk
    def save(self, folder: str | Path) -> Path:
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        codes = self.codes
        offsets = np.cumsum([0] + [len(c) for c in codes]).astype(np.int64)
        arrays = self.quantizer.to_arrays()
        if self.clip_features is not None:
            arrays["features"] = np.concatenate(self.clip_features).astype(np.float32)
        np.savez_compressed(folder / NPZ_NAME, codes=np.concatenate(codes).astype(np.int32), offsets=offsets, **arrays)
        meta = {
            "format": FORMAT, "version": VERSION, "fps": self.fps, "dims": self.dims,
            "band": self.band, "feature_set": self.feature_set, "method": self.method, "shortlist": self.shortlist,
            "summary": self.summary, "body": features_tag(self.feature_set),
            "trials": self.trials, "labels": self.labels,
        }
        (folder / JSON_NAME).write_text(json.dumps(meta, indent=1))
        return folder

    @staticmethod
    def is_index(path: str | Path) -> bool:
        return (Path(path) / JSON_NAME).is_file()

    @classmethod
    def load(cls, folder: str | Path) -> "MotionIndex":
        folder = Path(folder)
        jpath, npath = folder / JSON_NAME, folder / NPZ_NAME
        try:
            meta = json.loads(jpath.read_text())
        except FileNotFoundError:
            raise IndexFormatError(f"{jpath}: not found") from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise IndexFormatError(f"{jpath}: unreadable ({exc})") from None
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise IndexFormatError(f"{jpath}: not a StoryBeam motion index")
        if meta.get("version") != VERSION:
            raise IndexFormatError(f"{jpath}: index version {meta.get('version')!r}, expected {VERSION}")
        try:
            trials, labels = list(meta["trials"]), list(meta["labels"])
            fps, band, fset = float(meta["fps"]), meta.get("band"), str(meta.get("feature_set", "mr17"))
            method, shortlist = str(meta.get("method", "quantized")), int(meta.get("shortlist", SHORTLIST))
            summary = int(meta.get("summary", SUMMARY))
            saved_body, body = str(meta.get("body", "source")), features_tag(fset)
        except (KeyError, ValueError, TypeError) as exc:
            raise IndexFormatError(f"{jpath}: damaged index ({type(exc).__name__}: {exc})") from None
        if body and saved_body != body:
            # a query's features would be computed on another body than the library's
            def name(tag: str) -> str:
                return "the file's own body" if tag == "source" else f"the {tag} body"
            raise IndexFormatError(f"{jpath}: its {fset!r} features were taken on {name(saved_body)}, this "
                                   f"StoryBeam takes them on {name(body)}: build the index again "
                                   "(storybeam search --data FOLDER --save-index DIR)")
        try:
            with np.load(npath) as z:
                arrays = {k: z[k] for k in z.files}
            quantizer = Quantizer.from_arrays(arrays)
            codes_all, offsets = arrays["codes"], arrays["offsets"]
            feats_all = arrays["features"] if method == "storybeam" else None
        except FileNotFoundError:
            raise IndexFormatError(f"{npath}: not found") from None
        except (KeyError, ValueError, TypeError, OSError, EOFError, zipfile.BadZipFile) as exc:
            raise IndexFormatError(f"{npath}: damaged index ({type(exc).__name__}: {exc})") from None
        n_codes = 4 ** quantizer.n
        if (len(offsets) != len(trials) + 1 or len(labels) != len(trials) or offsets[0] != 0
                or offsets[-1] != len(codes_all) or np.any(np.diff(offsets) <= 0)
                or (len(codes_all) and (codes_all.min() < 0 or codes_all.max() >= n_codes))):
            raise IndexFormatError(f"{npath}: codes, offsets and trials are inconsistent")
        if feats_all is not None and (feats_all.ndim != 2 or len(feats_all) != len(codes_all)
                                      or feats_all.shape[1] != quantizer.pca.mean.shape[0]):
            raise IndexFormatError(f"{npath}: features and codes are inconsistent")
        known = _known_set(fset)
        width = 0 if known is None else known.dim
        if feats_all is not None and width and feats_all.shape[1] != width:
            raise IndexFormatError(f"{npath}: its {fset!r} features have {feats_all.shape[1]} columns, this StoryBeam's "
                                   f"have {width}: build the index again "
                                   "(storybeam search --data FOLDER --save-index DIR)")
        codes = [codes_all[offsets[i]:offsets[i + 1]] for i in range(len(trials))]
        feats = None if feats_all is None else [feats_all[offsets[i]:offsets[i + 1]] for i in range(len(trials))]
        try:
            return cls(quantizer, codes, trials, labels, fps, fset, band, method=method, features=feats,
                       shortlist=shortlist, summary=summary)
        except StoryBeamError as exc:
            raise IndexFormatError(f"{jpath}: {exc}") from None
