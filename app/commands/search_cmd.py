"""`storybeam search`: the clips of a motion library nearest to a query motion file.

``--data`` is a labelled folder (indexed on the fly) or a saved index folder (contains
index.json); by default the bundled library in assets/motions. Every answer comes from
:class:`retrieval.library.MotionIndex`, i.e. the exact fast search (the same clips and
distances as the brute-force look-up DTW against every clip). ``--subsequence`` asks
instead which clips pass closest through a short query, and at which frames.

``--json [PATH]`` (``-`` or no value: stdout) writes::

  {"query", "data", "mode", "results": [{"rank", "trial", "label", "distance"
   (, "start", "end" with --subsequence)}], "search_ms", "encode_ms", "kernels_ms",
   "backend", "clips"}

``encode_ms`` is the time from the loaded motion to its codes (resampling, features,
quantiser); ``search_ms`` the time from the query's codes to the answer (the index
search alone), both by :func:`time.perf_counter`. Before them one search for an indexed
clip loads the compiled kernels (from numba's cache; compiling them if the cache is
empty, see docs/notebook/retrieval-speed.md): ``kernels_ms``.

``--pose FILE:FRAME`` searches by pose instead (:class:`retrieval.library.PoseSearch`):
the posture at frame FRAME of the motion file (counted in the file's own frame rate, from
0) is turned into the library's features — computed over the whole file, so heights are
above its floor — and the clips passing closest through it are reported with the frame
where they do::

  {"query", "data", "mode": "pose", "pose_frame", "results": [{"rank", "trial", "label",
   "frame", "distance", "code_distance"}], "search_ms", "backend", "clips"}

``search_ms`` is the time from the pose's features to the answer (code search and
refinement). A pose search needs a labelled folder (a saved index keeps no features).

``--video FILE`` searches by a performance filmed from the front ("Act it out",
:mod:`app.services.act_it_out`): every frame of the video is run through the pose
estimator (:class:`ar.body.BodyTracker`), the landmarks are searched in the library's
frontal features (:class:`retrieval.library.ActSearch`, built from ``--data``: a labelled
folder, with the app's moves from other studios, ``assets/motions/moves``, beside it;
``--moves DIR`` names another such folder, ``--moves none`` searches ``--data`` alone), and
``--exclude TRIAL,...`` leaves those trials out of the library (to evaluate a
take of a library clip)::

  {"query", "data", "moves", "mode": "video", "results": [{"rank", "trial", "label", "subject",
   "distance", "clip_path"}], "detect_rate", "pose_ms_median", "search_ms", "frames",
   "fps", "image_size", "verdict": {"ok", "reason", "seen", "detected", ...}, "clips"}

``detect_rate`` is the share of frames with a body, ``pose_ms_median`` the median time
of the pose estimator per frame, ``search_ms`` the search alone (after one search that
loads the kernels); ``verdict`` is what the app would tell the child (at least 80 % of
the frames must show the whole body; the search is reported either way). No frame is
stored or written: only the landmarks, in memory.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from app.commands.output import add_moves_argument, emit_json_report, moves_folder
from app.paths import MOTIONS_DIR
from retrieval.errors import StoryBeamError

DEFAULT_LIBRARY = MOTIONS_DIR


def register(subparsers) -> None:
    p = subparsers.add_parser("search", help="find the library clips nearest to a motion file",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", default=str(DEFAULT_LIBRARY), help="labelled folder or saved index (default: bundled library)")
    p.add_argument("--query", help="motion file (.bvh, or .amc with --skeleton)")
    p.add_argument("--pose", metavar="FILE:FRAME",
                   help="search by the pose at frame FRAME of a motion file (instead of --query)")
    p.add_argument("--video", metavar="FILE",
                   help="search by a performance filmed from the front (instead of --query): "
                        "pose estimation on every frame, then the frontal-feature library")
    p.add_argument("--exclude", metavar="TRIAL,...", default="",
                   help="with --video: leave these trials out of the library (evaluation)")
    add_moves_argument(p)
    p.add_argument("--skeleton", help="ASF skeleton for an AMC query")
    p.add_argument("-k", "--top", type=int, default=5, help="how many clips to report (default 5)")
    p.add_argument("--subsequence", action="store_true",
                   help="find the clips that pass through a (short) query, with start/end frames")
    p.add_argument("--find", action="store_true",
                   help="find this clip: rank by identity (the same clip from another file, skeleton or frame "
                        "rate first) rather than by likeness; storybeam indexes")
    p.add_argument("--dims", type=int, default=6, help="PCA components when indexing a folder")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate when indexing a folder")
    p.add_argument("--save-index", help="also save the index built from --data here")
    p.add_argument("--json", dest="json_out", nargs="?", const="-", metavar="PATH",
                   help="write the results as JSON to PATH ('-' or no value: stdout, instead of the table)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Load the library and the query, encode the query, search, report (table and/or JSON)."""
    from retrieval.library import MotionIndex  # deferred: loads numba, only to search
    try:
        from retrieval.motion.formats import load_motion  # optional: the motion loaders
    except ImportError as exc:
        raise StoryBeamError(f"motion loaders unavailable: {exc}") from None

    data = Path(args.data)
    if args.top < 1:
        raise StoryBeamError(f"-k/--top must be at least 1, got {args.top}")
    if not data.exists():
        raise StoryBeamError(f"--data {data}: not found")
    given = [name for name, value in (("--query", args.query), ("--pose", args.pose), ("--video", args.video))
             if value is not None]
    if len(given) != 1:
        raise StoryBeamError("give one of --query FILE or --pose FILE:FRAME or --video FILE"
                             + (f" (got {' and '.join(given)})" if given else ""))
    if args.exclude and args.video is None:
        raise StoryBeamError("--exclude goes with --video")
    if args.video is not None:
        return _run_video(args, data)
    if args.pose is not None:
        return _run_pose(args, data, load_motion)
    query_path = Path(args.query)
    if not query_path.is_file():
        raise StoryBeamError(f"--query {query_path}: not found")
    index = MotionIndex.load(data) if MotionIndex.is_index(data) else MotionIndex.build(data, args.dims, args.fps)
    if args.save_index:
        index.save(args.save_index)
    motion = load_motion(query_path, args.skeleton) if args.skeleton else load_motion(query_path)

    # load the compiled kernels (from numba's cache, or compile them on a fresh install)
    # with one search for an indexed clip, outside the timings: search_ms is the search.
    # The storybeam method (the default) answers a nearest search by exact float DTW among
    # the code shortlist; the subsequence search and a quantized index use the codes alone.
    by_features = index.method == "storybeam" and not args.subsequence
    if args.find and not by_features:
        raise StoryBeamError("--find needs a storybeam index and no --subsequence")
    tw = time.perf_counter()
    if by_features and args.find:  # also builds the identity ranking's codes, outside the timings
        index.find(index.clip_features[0], k=1)
    elif by_features:
        index.query(index.clip_features[0], k=1)
    else:
        index.subsequence_codes(index.codes[0], k=1) if args.subsequence else index.query_codes(index.codes[0], k=1)
    t0 = time.perf_counter()
    encoded = index.features(motion) if by_features else index.encode(motion)
    t1 = time.perf_counter()
    if by_features:
        matches = index.find(encoded, k=args.top) if args.find else index.query(encoded, k=args.top)
    elif args.subsequence:
        matches = index.subsequence_codes(encoded, k=args.top)
    else:
        matches = index.query_codes(encoded, k=args.top)
    t2 = time.perf_counter()

    report = {
        "query": str(query_path), "data": str(data), "mode": "subsequence" if args.subsequence else ("find" if args.find else "nearest"),
        "results": [{"rank": i, **m.as_dict()} for i, m in enumerate(matches, 1)],
        "search_ms": (t2 - t1) * 1e3, "encode_ms": (t1 - t0) * 1e3, "kernels_ms": (t0 - tw) * 1e3,
        "backend": index.backend, "clips": len(index), "method": index.method,
    }
    if args.json_out != "-":
        _print_table(matches, args.subsequence)
        print(f"{len(index)} clips, search {report['search_ms']:.2f} ms ({index.backend}), "
              f"encode {report['encode_ms']:.2f} ms, kernels {report['kernels_ms']:.0f} ms")
    emit_json_report(args.json_out, report)
    return 0


def _run_pose(args, data: Path, load_motion) -> int:
    """``--pose FILE:FRAME``: the pose's features, the pose search, the report."""
    from retrieval.library import MotionIndex, PoseSearch  # deferred: loads numba, only to search

    file, sep, frame_text = args.pose.rpartition(":")
    try:
        frame = int(frame_text)
    except ValueError:
        frame = -1
    if not sep or not file or frame < 0:
        raise StoryBeamError(f"--pose {args.pose!r}: expected FILE:FRAME with FRAME a whole number >= 0")
    path = Path(file)
    if not path.is_file():
        raise StoryBeamError(f"--pose {path}: not found")
    if MotionIndex.is_index(data):
        raise StoryBeamError(f"--data {data}: a pose search needs a labelled folder, not a saved index")
    search = PoseSearch.build(data, args.dims, args.fps)
    motion = load_motion(path, args.skeleton) if args.skeleton else load_motion(path)
    if frame >= motion.n_frames:
        raise StoryBeamError(f"--pose {path}: frame {frame} is past the last frame ({motion.n_frames - 1})")
    pose = search.motion_pose(motion, frame)
    search.search(pose, k=1)  # loads the compiled kernels, outside the timing
    t0 = time.perf_counter()
    hits = search.search(pose, k=args.top)
    t1 = time.perf_counter()
    report = {
        "query": str(path), "data": str(data), "mode": "pose", "pose_frame": frame,
        "results": [{"rank": i, **h.as_dict()} for i, h in enumerate(hits, 1)],
        "search_ms": (t1 - t0) * 1e3, "backend": search.index.backend, "clips": len(search),
    }
    if args.json_out != "-":
        print(f"{'rank':>4}  {'trial':<16} {'label':<10} distance  frame")
        for i, h in enumerate(hits, 1):
            print(f"{i:>4}  {h.trial:<16} {h.label:<10} {h.distance:.5f} {h.frame:>6}")
        print(f"{len(search)} clips, search {report['search_ms']:.2f} ms ({search.index.backend})")
    emit_json_report(args.json_out, report)
    return 0


def _run_video(args, data: Path) -> int:
    """``--video FILE``: the take's landmarks, its verdict, the frontal search, the report."""
    from ar.camera_sources import VIDEO_SUFFIXES, VideoFileSource  # deferred: OpenCV, only for a video
    from app.services.act_it_out import ActItOut, pose_runtime_problem  # deferred: the camera flow, only for a video

    path = Path(args.video)
    if not path.is_file():
        raise StoryBeamError(f"--video {path}: not found")
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise StoryBeamError(f"--video {path}: not a video file (expected one of {', '.join(VIDEO_SUFFIXES)})")
    if not data.is_dir() or not (data / "labels.csv").is_file():
        raise StoryBeamError(f"--data {data}: a video search needs a labelled folder (with labels.csv)")
    problem = pose_runtime_problem()
    if problem is not None:
        raise StoryBeamError(f"--video: {problem}")
    exclude = [t.strip() for t in args.exclude.split(",") if t.strip()]
    from retrieval.library import ActSearch  # deferred: loads the search stack, only to search

    moves = moves_folder(args.moves)
    search = ActSearch.build(data, moves=moves)
    # a trial's name, not its windows' (10_01@0, 10_01@52, ...): leaving it out leaves all of them out
    unknown = [t for t in exclude if t not in set(search.clip_names)]
    if unknown:
        raise StoryBeamError(f"--exclude: {', '.join(unknown)} not in the library {data}")
    flow = ActItOut(search)
    with VideoFileSource(path, paced=False) as source:
        take = flow.take_from_source(source, seconds=0)  # the whole video
    if not take.poses:
        raise StoryBeamError(f"--video {path}: no frame could be read")
    verdict = flow.judge(take)
    flow.results(take, k=1, exclude=exclude)  # loads the compiled kernels, outside the timing
    t0 = time.perf_counter()
    hits = flow.results(take, k=args.top, exclude=exclude)
    t1 = time.perf_counter()
    report = {
        "query": str(path), "data": str(data), "moves": None if moves is None else str(moves), "mode": "video",
        "exclude": exclude,
        "results": [{"rank": i, **h.as_dict()} for i, h in enumerate(hits, 1)],
        "detect_rate": take.detect_rate, "pose_ms_median": take.pose_ms_median, "search_ms": (t1 - t0) * 1e3,
        "frames": len(take.poses), "fps": take.fps, "image_size": list(take.image_size),
        "verdict": verdict.as_dict(), "clips": len(search),
    }
    if args.json_out != "-":
        print(f"{'rank':>4}  {'trial':<16} {'label':<10} distance")
        for i, h in enumerate(hits, 1):
            print(f"{i:>4}  {h.trial:<16} {h.label:<10} {h.distance:.5f}")
        note = "" if verdict.ok else f"; the app would ask to {verdict.reason.replace('_', ' ')} ({verdict.seen:.0%} seen)"
        print(f"{report['frames']} frames, body in {take.detect_rate:.0%}, pose {take.pose_ms_median:.1f} ms/frame, "
              f"search {report['search_ms']:.2f} ms, {len(search)} clips{note}")
    emit_json_report(args.json_out, report)
    return 0


def _print_table(matches, subsequence: bool) -> None:
    frames = f" {'frames':>11}" if subsequence else ""
    print(f"{'rank':>4}  {'trial':<16} {'label':<10} distance{frames}")
    for i, m in enumerate(matches, 1):
        where = f" {m.start:>5}-{m.end:<5}" if subsequence else ""
        print(f"{i:>4}  {m.trial:<16} {m.label:<10} {m.distance:.5f}{where}")
