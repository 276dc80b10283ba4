"""The research's experiment: stratified k-fold 1-nearest-neighbour classification.

Protocol (docs/seed-method.md): the clips are split into ``folds`` class-stratified parts;
each part in turn is the query set and the other parts are the references. Every method is
fitted on the references only (PCA, μ/σ, k-means never see the queries) — that is its
*build* phase — and then answers every query with its nearest reference by DTW distance —
the *search* phase. A query is correct when that reference has the query's class.

Timing: build and search are timed separately with ``time.perf_counter`` (wall) and
``time.process_time`` (CPU) around exactly those calls, for every method in the same
process, after the compiled kernels have been warmed up. Within a fold every query is
answered by all methods back to back, so load from other processes on a shared machine
hits all methods alike. Search time includes turning the query's features into codes
(projection + thresholds, or k-d tree look-ups).

Protocols: ``split="random"`` is the research's stratified k-fold split; ``split="subject"``
leaves one ``subject`` group out at a time (:func:`subject_folds`: the performer on CMU,
the style on bandai2), so no take of the query's performer or style is among the
references.

Feature sets: the seed's methods (``quantized``, ``quantized-fast``, ``dtw``, ``forbes``)
always see the 17 MR17 columns; ``storybeam`` and ``dtw-storybeam`` (exact DTW on the
same features as ``storybeam``) see every column the clips carry — the ``"storybeam"``
set (MR17 + turning rate) when loaded by ``storybeam eval``.

Reported per method: accuracy, balanced accuracy (mean of per-class recalls — the classes
are unbalanced, kicks are scarce), per-class accuracy, search and build seconds.
:func:`sweep_dims` repeats the proposed method for n = 1..7 and records the cumulative
contribution ratio (mean over folds) beside accuracy and time.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from retrieval.codes import code_table, full_table
from retrieval.dtw import dtw_codes, dtw_features
from retrieval.errors import StoryBeamError
from lab.experiment.baselines import ExactDTWMatcher, ForbesFiumeMatcher
from lab.experiment.matchers import FastMatcher, QuantizedMatcher, StoryBeamMatcher
from retrieval.features import MR17
from retrieval.library import SHORTLIST, SUMMARY, Clip, StoryBeamSearcher, dtw_features_abandon
from retrieval.search import warm_up as warm_up_fast

#: "quantized" is the research's method as it describes it (full 4ⁿ×4ⁿ table, DTW against
#: every reference); "quantized-fast" gives bit-identical distances from a 20 KiB table with
#: lower bounds, early abandoning and run-length DTW (docs/notebook/retrieval-speed.md).
METHODS = ("storybeam", "dtw-storybeam", "quantized-fast", "quantized", "dtw", "forbes")

#: The methods that run on the seed's 17 MR17 columns only.
SEED_METHODS = ("quantized-fast", "quantized", "dtw", "forbes")

#: Protocols of :func:`evaluate`.
SPLITS = ("random", "subject")


class EvaluationError(StoryBeamError):
    """The experiment cannot run as asked (too few clips per class, unknown method)."""


def stratified_folds(labels: Sequence[str], folds: int, seed: int = 0) -> list[np.ndarray]:
    """Indices of each fold: every class is shuffled and dealt round-robin over the folds
    (the deal continues across classes so fold sizes differ by at most one)."""
    if folds < 2:
        raise EvaluationError(f"need at least 2 folds, got {folds}")
    labels = np.asarray(labels)
    if len(labels) < folds:
        raise EvaluationError(f"{len(labels)} clips cannot be split into {folds} folds")
    rng = np.random.default_rng(seed)
    parts: list[list[int]] = [[] for _ in range(folds)]
    k = 0
    for cls in sorted(set(labels.tolist())):
        idx = np.flatnonzero(labels == cls)
        for i in rng.permutation(idx):
            parts[k % folds].append(int(i))
            k += 1
    return [np.array(sorted(p), dtype=np.int64) for p in parts]


def subject_folds(subjects: Sequence[str]) -> list[np.ndarray]:
    """Leave-one-group-out: one fold per distinct ``subject`` (sorted), holding that
    group's clips. Raises when a clip has no subject or there are fewer than 2 groups."""
    subjects = np.asarray(subjects)
    if len(subjects) and np.any(subjects == ""):
        raise EvaluationError("--split subject: some clips have no subject (labels.csv needs a 'subject' column)")
    groups = sorted(set(subjects.tolist()))
    if len(groups) < 2:
        raise EvaluationError(f"--split subject needs at least 2 subject groups, got {len(groups)}")
    return [np.flatnonzero(subjects == g).astype(np.int64) for g in groups]


def make_matcher(name: str, dims: int = 6, band: int | None = None, forbes_clusters: int | None = None,
                 seed: int = 0, backend: str = "auto", shortlist: int = SHORTLIST, summary: int = SUMMARY,
                 code_columns: int | None = None):
    """A fresh matcher for a method name. Forbes–Fiume's k defaults to 4ⁿ capped at 1024
    (k-means cost grows with k × frames; the cap is reported with the results)."""
    if name == "quantized":
        return QuantizedMatcher(dims, band, backend)
    if name == "quantized-fast":
        return FastMatcher(dims=dims, band=band, backend=backend)
    if name in ("dtw", "dtw-storybeam"):
        m = ExactDTWMatcher(band, backend)
        m.name = name
        return m
    if name == "storybeam":
        return StoryBeamMatcher(dims, band, shortlist, backend, summary, code_columns)
    if name == "forbes":
        k = forbes_clusters if forbes_clusters else min(4**dims, 1024)
        return ForbesFiumeMatcher(clusters=k, band=band, backend=backend, seed=seed)
    raise EvaluationError(f"unknown method {name!r} (choose from {', '.join(METHODS)})")


def warm_up(methods: Sequence[str] = METHODS) -> None:
    """Compile/load the DTW kernels ``methods`` use, once, so no method's timing pays for
    compilation."""
    t = full_table(np.array([0.6, 0.4]))
    c = np.array([0, 1, 2], dtype=np.int32)
    dtw_codes(c, c, t)
    split = code_table(np.array([0.5, 0.3, 0.2]), max_full_dims=1)
    dtw_codes(c, c, split)
    x = np.zeros((3, 2))
    dtw_features(x, x)
    if "quantized-fast" in methods or "storybeam" in methods:
        warm_up_fast()
    if "storybeam" in methods:
        dtw_features_abandon(x, x, 1.0)
        # the shortlist's search mode and the no-band re-ranking kernel, through the method itself
        rng = np.random.default_rng(0)
        lib = [rng.normal(size=(6 + i, 3)) for i in range(3)]
        StoryBeamSearcher.fit(lib, dims=2, shortlist=2).search(lib[0], k=1)


@dataclass
class MethodResult:
    name: str
    correct: int = 0
    total: int = 0
    confusion: dict[str, dict[str, int]] = field(default_factory=dict)
    search_seconds: float = 0.0
    build_seconds: float = 0.0
    per_class_correct: dict[str, int] = field(default_factory=dict)
    per_class_total: dict[str, int] = field(default_factory=dict)
    predictions: dict[str, str] = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    @property
    def accuracy(self) -> float:
        return self.correct / self.total if self.total else 0.0

    @property
    def per_class(self) -> dict[str, float]:
        return {c: self.per_class_correct.get(c, 0) / n for c, n in sorted(self.per_class_total.items())}

    @property
    def balanced_accuracy(self) -> float:
        pc = self.per_class
        return float(np.mean(list(pc.values()))) if pc else 0.0

    def as_dict(self) -> dict:
        cells = self.extra.get("dtw_cells", 0)
        return {
            "ns_per_cell": 1e9 * self.search_seconds / cells if cells else None,
            "accuracy": self.accuracy,
            "balanced_accuracy": self.balanced_accuracy,
            "search_seconds": self.search_seconds,
            "build_seconds": self.build_seconds,
            "per_class": self.per_class,
            "correct": self.correct,
            "queries": self.total,
            "confusion": self.confusion,
            **self.extra,
        }


def stratified_subset(clips: Sequence[Clip], size: int, seed: int = 0) -> list[Clip]:
    """``size`` clips drawn without replacement, each class keeping (to rounding) its share
    — the research reports two database sizes; this makes comparable smaller ones."""
    if not 1 <= size <= len(clips):
        raise EvaluationError(f"subset size must be 1..{len(clips)}, got {size}")
    labels = np.array([c.label for c in clips])
    classes = sorted(set(labels.tolist()))
    counts = np.array([np.sum(labels == c) for c in classes])
    want = np.floor(counts * size / len(clips)).astype(int)
    order = np.argsort(-(counts * size / len(clips) - want), kind="stable")
    want[order[: size - want.sum()]] += 1
    rng = np.random.default_rng(seed)
    chosen = []
    for c, k in zip(classes, want):
        chosen.extend(rng.choice(np.flatnonzero(labels == c), size=k, replace=False).tolist())
    return [clips[i] for i in sorted(chosen)]


def evaluate(clips: Sequence[Clip], methods: Sequence[str] = METHODS, folds: int = 3, dims: int = 6,
             seed: int = 0, band: int | None = None, forbes_clusters: int | None = None,
             progress: Callable[[int, int], None] | None = None, matcher_factory: Callable | None = None,
             backend: str = "auto", split: str = "random", shortlist: int = SHORTLIST,
             summary: int = SUMMARY, seed_clips: Sequence[Clip] | None = None,
             code_columns: int | None = None) -> dict[str, MethodResult]:
    """Run the k-fold 1-NN protocol for each method; returns results keyed by method.
    ``split``: "random" (stratified ``folds``) or "subject" (leave one subject group out;
    ``folds`` is then ignored). ``progress(done, total)`` is called after each fold.
    ``seed_clips``: the same clips in the seed's MR17 features, for the seed's methods
    (needed when ``clips`` carry a set whose MR17 columns are not the seed's, such as
    the storybeam set on the canonical body); by default the first MR17 columns of
    ``clips``. ``code_columns``: the storybeam method's codes see only the first that
    many feature columns (the clips' set's ``code_columns``; None: all)."""
    for m in methods:
        if m not in METHODS and matcher_factory is None:
            raise EvaluationError(f"unknown method {m!r} (choose from {', '.join(METHODS)})")
    if split not in SPLITS:
        raise EvaluationError(f"unknown split {split!r} (choose from {', '.join(SPLITS)})")
    labels = [c.label for c in clips]
    parts = stratified_folds(labels, folds, seed) if split == "random" else subject_folds([c.subject for c in clips])
    # the seed's methods see the MR17 columns only (a clip of the "storybeam" set carries them first)
    seed_view = list(clips)
    if seed_clips is not None:
        if [c.trial for c in seed_clips] != [c.trial for c in clips]:
            raise EvaluationError("seed_clips must be the same clips, in the same order, as clips")
        seed_view = list(seed_clips)
    elif clips and clips[0].features.shape[1] > MR17.dim:
        seed_view = [replace(c, features=c.features[:, : MR17.dim]) for c in clips]
    warm_up(methods)
    results = {m: MethodResult(m) for m in methods}
    for f, query_idx in enumerate(parts):
        ref_idx = np.setdiff1d(np.arange(len(clips)), query_idx)
        refs = [clips[i] for i in ref_idx]
        factory = matcher_factory or make_matcher
        matchers = {}
        for name in methods:  # build phase, timed per method
            kw = ({"shortlist": shortlist, "summary": summary, "code_columns": code_columns}
                  if name == "storybeam" and matcher_factory is None else {})
            matcher = factory(name, dims=dims, band=band, forbes_clusters=forbes_clusters, seed=seed + f,
                              backend=backend, **kw)
            view = seed_view if name in SEED_METHODS else clips
            t0, c0 = time.perf_counter(), time.process_time()
            matcher.fit([view[i] for i in ref_idx])
            results[name].build_seconds += time.perf_counter() - t0
            results[name].extra["build_cpu_seconds"] = (results[name].extra.get("build_cpu_seconds", 0.0)
                                                        + time.process_time() - c0)
            matchers[name] = matcher
        ref_frames = sum(c.n_frames for c in refs)
        # Search phase: every query is answered by every method back to back (the order
        # rotating per query), so a busy neighbour on the shared machine slows all
        # methods alike instead of whichever happened to run at that moment.
        for qn, q in enumerate(query_idx):
            for k in range(len(methods)):
                name = methods[(qn + k) % len(methods)]
                r = results[name]
                query = (seed_view if name in SEED_METHODS else clips)[q]
                t0, c0 = time.perf_counter(), time.process_time()
                nearest = int(np.argmin(matchers[name].distances(query)))
                r.search_seconds += time.perf_counter() - t0
                r.extra["search_cpu_seconds"] = r.extra.get("search_cpu_seconds", 0.0) + time.process_time() - c0
                r.extra["dtw_cells"] = r.extra.get("dtw_cells", 0) + clips[q].n_frames * ref_frames
                truth, guess = clips[q].label, refs[nearest].label
                r.total += 1
                r.correct += truth == guess
                r.per_class_total[truth] = r.per_class_total.get(truth, 0) + 1
                r.per_class_correct[truth] = r.per_class_correct.get(truth, 0) + (truth == guess)
                r.predictions[clips[q].trial] = refs[nearest].trial
                row = r.confusion.setdefault(truth, {})
                row[guess] = row.get(guess, 0) + 1
        for name in methods:
            m, r = matchers[name], results[name]
            if name == "quantized":
                r.extra.setdefault("cumulative_ratio_per_fold", []).append(m.quantizer.cumulative_ratio)
            if name == "forbes":
                r.extra.setdefault("clusters_per_fold", []).append(int(m.centroids.shape[0]))
                r.extra.setdefault("pose_dims_per_fold", []).append(int(m.axes.shape[0]))
        if progress is not None:
            progress(f + 1, len(parts))
    return results


def sweep_dims(clips: Sequence[Clip], dims_range: Sequence[int], folds: int = 3, seed: int = 0,
               band: int | None = None, progress: Callable[[int, int], None] | None = None,
               backend: str = "auto") -> list[dict]:
    """Proposed method for each n: accuracy, balanced accuracy, search and build seconds,
    mean cumulative contribution ratio, and the table's size in bytes."""
    rows = []
    dims_list = list(dims_range)
    for step, n in enumerate(dims_list):
        res = evaluate(clips, ["quantized"], folds, n, seed, band, backend=backend)["quantized"]
        if progress is not None:
            progress(step + 1, len(dims_list))
        m = QuantizedMatcher(n)
        table_bytes = 4 * (16**n) if n <= m.max_full_dims else None
        if table_bytes is None:
            k = (n + 1) // 2
            table_bytes = 4 * (16**k + 16 ** (n - k))
        rows.append({
            "dims": n,
            "accuracy": res.accuracy,
            "balanced_accuracy": res.balanced_accuracy,
            "search_seconds": res.search_seconds,
            "build_seconds": res.build_seconds,
            "search_cpu_seconds": res.extra.get("search_cpu_seconds"),
            "ns_per_cell": res.as_dict()["ns_per_cell"],
            "cumulative_ratio": float(np.mean(res.extra["cumulative_ratio_per_fold"])),
            "table": "full" if n <= m.max_full_dims else "split",
            "table_bytes": int(table_bytes),
        })
    return rows


def plot_sweep(rows: Sequence[dict], folder) -> list[str]:
    """Accuracy, search time and cumulative contribution against n, as three PNGs
    (the research's figures 3, 4 and 5)."""
    import matplotlib  # optional: matplotlib (plots only; absent on the tablet)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # optional: matplotlib

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    n = [r["dims"] for r in rows]
    specs = [
        ("sweep_accuracy.png", "accuracy (%)", [100 * r["accuracy"] for r in rows],
         [100 * r["balanced_accuracy"] for r in rows]),
        ("sweep_time.png", "search time (s)", [r["search_seconds"] for r in rows], None),
        ("sweep_contribution.png", "cumulative contribution ratio (%)", [100 * r["cumulative_ratio"] for r in rows], None),
    ]
    paths = []
    for fname, ylabel, ys, ys2 in specs:
        fig, ax = plt.subplots(figsize=(4.2, 3.0), dpi=100)
        ax.plot(n, ys, "o-", label=ylabel.split(" (")[0])
        if ys2 is not None:
            ax.plot(n, ys2, "s--", label="balanced accuracy")
            ax.legend(fontsize=8)
        ax.set_xlabel("kept PCA components n")
        ax.set_ylabel(ylabel)
        ax.set_xticks(n)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(out / fname)
        plt.close(fig)
        paths.append(str(out / fname))
    return paths


def plot_confusion(results: dict[str, dict], folder, prefix: str = "confusion", title: str = "") -> list[str]:
    """One confusion-matrix PNG per method (rows: true class, columns: the nearest
    reference's class; cells: query counts, rows also as % of the class) from the
    ``as_dict()`` results of :func:`evaluate`; file names ``{prefix}_{method}.png``."""
    import matplotlib  # optional: matplotlib (plots only; absent on the tablet)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # optional: matplotlib

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, res in results.items():
        conf = res.get("confusion") or {}
        classes = sorted(set(conf) | {g for row in conf.values() for g in row})
        if not classes:
            continue
        m = np.array([[conf.get(t, {}).get(g, 0) for g in classes] for t in classes], dtype=float)
        share = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
        size = 1.6 + 0.45 * len(classes)
        fig, ax = plt.subplots(figsize=(size + 1.2, size), dpi=100)
        ax.imshow(share, cmap="Blues", vmin=0, vmax=1)
        for i in range(len(classes)):
            for j in range(len(classes)):
                if m[i, j]:
                    ax.text(j, i, f"{int(m[i, j])}", ha="center", va="center", fontsize=7,
                            color="white" if share[i, j] > 0.6 else "black")
        ax.set_xticks(range(len(classes)), classes, rotation=60, ha="right", fontsize=7)
        ax.set_yticks(range(len(classes)), classes, fontsize=7)
        ax.set_xlabel("nearest reference's class")
        ax.set_ylabel("true class")
        ax.set_title(f"{title}{name}: {100 * res['accuracy']:.1f} %", fontsize=9)
        fig.tight_layout()
        path = out / f"{prefix}_{name}.png"
        fig.savefig(path)
        plt.close(fig)
        paths.append(str(path))
    return paths
