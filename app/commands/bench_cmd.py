"""`storybeam bench TARGET`: every benchmark and profile, one sub-target each.

Every target prints its table and, with ``--json OUT``, writes its full result as JSON.
The harnesses live in :mod:`lab.bench`; a target joins by adding an ``_add_*`` function
to :data:`TARGETS`. The harness modules are imported only when their target runs, so
``storybeam --help`` stays light.
"""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Callable

from app.commands.output import add_moves_argument, moves_folder, write_json_report
from app.paths import SHARED_CMU
from app.progress import progress_bar
from retrieval.errors import StoryBeamError


def _parser(sub: argparse._SubParsersAction, name: str, help: str, doc: str, func: Callable[[argparse.Namespace], int],
            json_default: str | None = None) -> argparse.ArgumentParser:
    """A target's sub-parser with the ``--json`` option every target shares."""
    p = sub.add_parser(name, help=help, description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    where = f" (default {json_default})" if json_default else ""
    p.add_argument("--json", dest="json_out", type=Path, default=json_default,
                   help=f"write the full result as JSON here{where}")
    p.set_defaults(func=func)
    return p


def _finish(args: argparse.Namespace, result: dict, table: str) -> int:
    """Print a target's table and write its result to ``--json`` when asked; exit code 0."""
    print(table)
    if args.json_out:
        write_json_report(args.json_out, result)
    return 0


def _at_least(minimum: int) -> Callable[[str], int]:
    """An argparse type: a whole number of at least ``minimum`` (a usage error otherwise)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value
    parse.__name__ = "int"
    return parse


def _fps(text: str) -> float:
    """An argparse type: a positive frame rate (a usage error otherwise)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0:  # also rejects nan
        raise argparse.ArgumentTypeError(f"a frame rate must be positive, got {text}")
    return value


# ------------------------------------------------------------------------- retrieval
RETRIEVAL_DOC = """Retrieval speed (lab/bench/retrieval.py), per query, interleaved, one core: the
fast search against a UCR-suite-style exact rival and the seed's brute force on the same
code distance (the headline), and float-feature DTW (brute force, dtaidistance pruned) as
another distance; on the paper protocol, a CMU-sized derived library and one ten times
bigger; the ablations, latency against library size, and memory."""


def _add_retrieval(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "retrieval", "retrieval speed: paper protocol, ablations, library-scale latency",
                RETRIEVAL_DOC, _run_retrieval)
    p.add_argument("--data", help="labelled folder (default: the shared CMU set, else the bundled library)")
    p.add_argument("--fps", type=_fps, default=120.0,
                   help="frame rate of the protocol, the same for every method (default 120: CMU's and the research's)")
    p.add_argument("--scale-fps", type=_fps, default=30.0, help="frame rate of the scale library (default 30, the app's)")
    p.add_argument("--dims", type=_at_least(1), default=6)
    p.add_argument("--quick", action="store_true", help="tiny run: bundled library, small scale library, 5 queries")
    p.add_argument("--plot", help="write the latency-vs-library-size plot here (PNG)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def _run_retrieval(args: argparse.Namespace) -> int:
    # deferred: lab.bench.retrieval loads numba, tqdm and the whole retrieval stack
    from lab.bench.retrieval import format_report, run_retrieval_bench

    out = run_retrieval_bench(args.data, fps=args.fps, scale_fps=args.scale_fps, quick=args.quick, dims=args.dims,
                              plot=args.plot, progress=not args.quiet)
    return _finish(args, out, format_report(out))


# ------------------------------------------------------------------------------- ar
AR_DOC = """AR tracking accuracy, jitter, landing error and timing on synthetic camera frames
(lab/bench/ar.py): per condition (clean, blur, low light, occlusion, ...), the board pose
error, detection rate, filtered jitter, projected landing error and detect/render times."""


def _add_ar(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "ar", "AR tracking/rendering on synthetic camera frames", AR_DOC, _run_ar)
    p.add_argument("--frames", type=_at_least(2), default=100, help="frames per condition (default 100)")
    p.add_argument("--board", default=None, help="board spec (default: the ChArUco default board)")
    p.add_argument("--conditions", default=None, help="comma-separated subset of conditions to run")
    p.add_argument("--true-calibration", action="store_true",
                   help="use the synthetic rig's true calibration instead of calibrating it first")
    p.add_argument("--examples", type=Path, help="write example frames (ar_*.png) into this folder")
    p.add_argument("--blur-sigma", type=float, default=1.5, help="Gaussian blur of the 'blur' condition, px (default 1.5)")
    p.add_argument("--filter", choices=("kalman", "one-euro"), default="kalman",
                   help="pose filter whose jitter is reported (default kalman)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--renderers", default="kivy-gl,pyrender",
                   help="camera frame -> projector frame timing at 640x480 on one core, per renderer "
                        "(comma-separated from kivy-gl = as the projector screen draws, one sample per pixel; "
                        "kivy-gl-2x = 2x2 supersampling, as the Play preview draws; pyrender; "
                        "'none' skips it; default kivy-gl,pyrender)")
    p.add_argument("--frame-only", action="store_true",
                   help="only the frame timing (and its 640x480 accuracy), not the calibrated accuracy bench")


def kivy_gl_renderer(supersample: int | None = None):
    """The app's Kivy GL renderer (:mod:`app.ui.gl`) on a hidden window, as the projector
    screen draws (``PROJECTOR_SUPERSAMPLE``, one sample per pixel) unless ``supersample``
    is given, for the frame timing of ``storybeam bench ar`` (a factory: called in the
    process that measures it)."""
    from app.ui.env import prepare_kivy_env  # deferred: Kivy reads its environment at import

    prepare_kivy_env(headless=True, width=640, height=480)
    from kivy.core.window import Window  # noqa: F401  deferred: opens the GL context the renderer draws in

    from app.ui.gl import PROJECTOR_SUPERSAMPLE, KivyGLRenderer  # deferred: after prepare_kivy_env()

    return KivyGLRenderer(PROJECTOR_SUPERSAMPLE if supersample is None else supersample)


def kivy_gl_renderer_2x():
    """:func:`kivy_gl_renderer` at the Play preview's 2 x 2 supersampling."""
    return kivy_gl_renderer(supersample=2)


def _run_ar(args: argparse.Namespace) -> int:
    from tqdm import tqdm  # deferred: only the benchmarks draw bars

    from lab.bench.ar import (  # deferred: loads OpenCV and pyrender
        FRAME_RENDERERS,
        BenchConfig,
        default_conditions,
        format_frame_table,
        format_table,
        merge_frame_results,
        run_bench,
        run_frame_bench,
        write_examples,
    )
    from ar.boards import DEFAULT_BOARD_SPEC, Board  # deferred: loads OpenCV

    conditions = default_conditions(blur_sigma=args.blur_sigma)
    if args.conditions:
        wanted = [c.strip() for c in args.conditions.split(",") if c.strip()]
        known = {c.name for c in conditions}
        unknown = [w for w in wanted if w not in known]
        if unknown or not wanted:
            raise StoryBeamError(f"unknown condition(s) {', '.join(unknown) or '(none given)'}; "
                                 f"known: {', '.join(sorted(known))}")
        conditions = [c for c in conditions if c.name in wanted]
    spec = args.board or DEFAULT_BOARD_SPEC
    Board(spec)  # validate early, before the long run
    cfg = BenchConfig(frames=args.frames, board_spec=spec, estimated_calibration=not args.true_calibration,
                      seed=args.seed, conditions=conditions, pose_filter=args.filter)
    renderers = [] if args.renderers.strip() == "none" else [r.strip() for r in args.renderers.split(",") if r.strip()]
    factories = {"kivy-gl": kivy_gl_renderer, "kivy-gl-2x": kivy_gl_renderer_2x, **FRAME_RENDERERS}
    unknown = [r for r in renderers if r not in factories]
    if unknown:
        raise StoryBeamError(f"unknown renderer(s) {', '.join(unknown)}; known: {', '.join(factories)}")
    examples: dict | None = {} if args.examples else None
    if args.frame_only:
        result = {"conditions": {c.name: {"description": c.description} for c in conditions}, "calibration": {}}
    else:
        with tqdm(total=args.frames * len(conditions), unit="frame", desc="bench ar") as bar:
            result = run_bench(cfg, progress=bar.update, examples=examples)
        print(format_table(result))
    if renderers:
        print(f"camera frame -> projector frame, 640x480, one core: {', '.join(renderers)} "
              f"({args.frames} frames x {len(conditions)} conditions each, one process per renderer)", flush=True)
        merge_frame_results(result, run_frame_bench(conditions, args.frames, args.seed,
                                                    {r: factories[r] for r in renderers}, spec))
        print(format_frame_table(result))
    cal = result["calibration"]
    if not args.frame_only and "camera_fx_error_pct" in cal:
        print(f"calibration: camera rms {cal['camera_rms_px']:.3f} px, fx error {cal['camera_fx_error_pct']:+.3f} %; "
              f"projector rms {cal['projector_rms_px']:.3f} px, fx error {cal['projector_fx_error_pct']:+.3f} %; "
              f"extrinsics {cal['extrinsics_rot_err_deg']:.3f} deg, {cal['extrinsics_trans_err_mm']:.2f} mm")
    if not args.frame_only:
        print(f"landing error (clean, median): {result['landing_error_mm_median']:.2f} mm; "
              f"detect+pose {result['detect_pose_ms_median']:.1f} ms; render {result['render_ms_median']:.1f} ms (medians)")
    if args.json_out:
        write_json_report(args.json_out, result, indent=2)
    if examples:
        write_examples(args.examples, examples)
        print(f"wrote example frames to {args.examples}")
    return 0


# ------------------------------------------------------------------------ animation
ANIMATION_DOC = """The animation numbers quoted in docs/design/animation.md (lab/bench/animation.py): path
following and foot skate of every bundled walk and run per character (and at human
scale), code-table transitions against random ones, retargeting of one clip per shared
skeleton (when the shared CMU data is present), and the character render at 640x480."""


def _add_animation(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "animation", "path following, foot skate, transitions, retargeting, render time",
                ANIMATION_DOC, _run_animation, json_default="out/animation_bench.json")
    p.add_argument("--shared", type=Path, default=None,
                   help="shared CMU folder for the retargeting step (default ../shared/data/cmu; skipped if absent)")
    p.add_argument("--characters", default="robot,cat,kid", help="comma-separated characters (default robot,cat,kid)")


def _run_animation(args: argparse.Namespace) -> int:
    from lab.bench.animation import (  # deferred: loads pyrender and the retrieval stack
        check_characters,
        format_summary,
        run_animation_bench,
    )

    characters = check_characters([c.strip() for c in args.characters.split(",") if c.strip()])
    kw = {"shared": args.shared} if args.shared is not None else {}
    result = run_animation_bench(characters=characters, progress=progress_bar("bench animation", "step"), **kw)
    return _finish(args, result, format_summary(result))


# ---------------------------------------------------------------------- surface
SURFACE_DOC = """The scanned table on the synthetic rig (lab/bench/surface.py): the teacher's Scan the
table step (Gray-code sequence rendered over a table with a 45 mm and a 20 mm box,
decoded, triangulated, rasterised) against the boxes' true heights; the landing error of
a character's planted feet on the 45 mm box top in the projector view (tracked pose,
scanned vs bare table); the edges each path meets (jumped above 40 mm, walked below)."""


def _add_surface(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "surface", "scanned box heights, feet landing on a box top, jumps at its edges",
                SURFACE_DOC, _run_surface, json_default="out/surface_bench.json")
    p.add_argument("--characters", default="robot", help="comma-separated characters (default robot)")
    p.add_argument("--plot", type=Path, default=None, help="write the height map and lift figure here (PNG)")


def _run_surface(args: argparse.Namespace) -> int:
    from app.player.animator import CHARACTER_DESIGNS  # deferred: the stage's modules, only for this target
    from lab.bench.surface import format_summary, run_surface_bench  # deferred: the scan and the stage

    kinds = tuple(c.strip() for c in args.characters.split(",") if c.strip())
    unknown = [k for k in kinds if k not in CHARACTER_DESIGNS]
    if not kinds or unknown:
        raise StoryBeamError(f"--characters: choose from {', '.join(CHARACTER_DESIGNS)} (got {args.characters!r})")
    result = run_surface_bench(kinds, args.plot, progress_bar("bench surface", "step"))
    return _finish(args, result, format_summary(result))


# ---------------------------------------------------------------------- dtw-kernels
DTW_KERNELS_DOC = """Nanoseconds per DTW cell for StoryBeam's kernels, with dtaidistance's C code as a
peer (lab/bench/dtw_kernels.py): one pair of smooth 17-D random walks of --frames frames,
each kernel warmed up once and timed --repeat times (median)."""


def _add_dtw_kernels(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "dtw-kernels", "nanoseconds per DTW cell of each kernel", DTW_KERNELS_DOC, _run_dtw_kernels)
    p.add_argument("--frames", type=_at_least(2), default=1000, help="frames of each clip (default 1000)")
    p.add_argument("--repeat", type=_at_least(1), default=5, help="timed runs per kernel (default 5)")


def _run_dtw_kernels(args: argparse.Namespace) -> int:
    # deferred: lab.bench.dtw_kernels loads numba and the DTW kernels
    from lab.bench.dtw_kernels import format_table, run_dtw_kernels_bench

    result = run_dtw_kernels_bench(frames=args.frames, repeat=args.repeat)
    return _finish(args, result, format_table(result))


# ------------------------------------------------------------------------ motion-io
MOTION_IO_DOC = """Time loading every motion listed in a folder's labels.csv (lab/bench/motion_io.py):
--repeat passes, the skeleton cache cleared before each, best pass reported."""


def _add_motion_io(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "motion-io", "time loading every motion of a labelled folder", MOTION_IO_DOC, _run_motion_io)
    p.add_argument("--data", type=Path, default=None,
                   help="labelled folder (default: the shared CMU set, ../shared/data/cmu)")
    p.add_argument("--repeat", type=_at_least(1), default=3, help="passes; the best is reported (default 3)")


def _run_motion_io(args: argparse.Namespace) -> int:
    # deferred: lab.bench.motion_io loads the motion parsers
    from lab.bench.motion_io import DEFAULT_DATA, format_table, run_motion_io_bench

    result = run_motion_io_bench(args.data or DEFAULT_DATA, repeat=args.repeat)
    return _finish(args, result, format_table(result))


# ------------------------------------------------------------------ numpy-retrieval
NUMPY_RETRIEVAL_DOC = """The numpy-only search path (Android: no numba), lab/bench/numpy_retrieval.py:
3-fold 1-NN on a labelled folder, the fast exact search with and without the range-cover
bound against the seed's method, all on the numpy back-end."""


def _add_numpy_retrieval(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "numpy-retrieval", "the numpy-only (no numba) search against the seed's method",
                NUMPY_RETRIEVAL_DOC, _run_numpy_retrieval)
    p.add_argument("folder", nargs="?", default=None, help="labelled folder (default: the bundled library)")
    p.add_argument("fps", nargs="?", type=_fps, default=30.0, help="frame rate (default 30)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _run_numpy_retrieval(args: argparse.Namespace) -> int:
    # deferred: lab.bench.numpy_retrieval loads the retrieval stack
    from lab.bench.numpy_retrieval import format_table, run_numpy_retrieval_bench

    kw = {"folder": args.folder} if args.folder else {}
    result = run_numpy_retrieval_bench(fps=args.fps, progress=not args.quiet, **kw)
    return _finish(args, result, format_table(result))


# -------------------------------------------------------------- fast-search-profile
FAST_SEARCH_PROFILE_DOC = """Where the fast exact search spends its time, and what the range-cover bound buys
(lab/bench/fast_search_profile.py): the paper protocol's folds searched with the bound on
and off (interleaved, answers must match), then the default search's stages timed."""


def _add_fast_search_profile(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "fast-search-profile", "range-cover bound on/off, and the stages of the fast search",
                FAST_SEARCH_PROFILE_DOC, _run_fast_search_profile)
    p.add_argument("fps", nargs="?", type=_fps, default=120.0, help="frame rate (default 120)")
    p.add_argument("--data", default=None, help="labelled folder (default: the shared CMU set, else the bundled library)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _run_fast_search_profile(args: argparse.Namespace) -> int:
    # deferred: lab.bench.fast_search_profile loads numba and the search kernels
    from lab.bench.fast_search_profile import format_report, run_fast_search_profile

    result = run_fast_search_profile(args.data, fps=args.fps, progress=not args.quiet)
    return _finish(args, result, format_report(result))


# ---------------------------------------------------------------------- pose-search
POSE_SEARCH_DOC = """Search by pose (lab/bench/pose_search.py): the pose at the most characteristic frame
of every jump, kick and run clip, its own clip held back; top-1 class accuracy per class
and search_ms (features to answer), beside the same queries refined over every clip."""


def _add_pose_search(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "pose-search", "search by pose: held-back top-1 class and search_ms", POSE_SEARCH_DOC,
                _run_pose_search)
    p.add_argument("--data", default=None, help="labelled folder (default: the shared CMU set)")
    p.add_argument("--fps", type=_fps, default=30.0, help="frame rate of the library (default 30, the app's)")
    p.add_argument("--backend", choices=("auto", "numba", "numpy"), default="auto",
                   help="DTW back-end (numpy: the tablet's path without numba)")
    p.add_argument("--against", default=None, metavar="FEATURE_SET",
                   help="also time the same queries on a pose search over this feature set, interleaved "
                        "with the default's (old vs new side by side; e.g. mr17, the file's own body)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _run_pose_search(args: argparse.Namespace) -> int:
    # deferred: lab.bench.pose_search loads numba and the retrieval stack
    from lab.bench.pose_search import format_report, run_pose_search_bench

    data = args.data or SHARED_CMU
    if not Path(data).is_dir():
        raise StoryBeamError(f"--data {data}: not a folder")
    result = run_pose_search_bench(data, fps=args.fps, progress=not args.quiet, backend=args.backend,
                                   against=args.against)
    return _finish(args, result, format_report(result))


# ---------------------------------------------------------------------- storybeam-scale
STORYBEAM_SCALE_DOC = """The product's search method at library scale (lab/bench/storybeam_scale.py, issue 12):
a derived library of >= --clips clips and >= --hours hours at 30 fps with the storybeam
features kept, StoryBeamSearcher fitted on it, the 1-NN of every held-out real CMU clip
timed on one core; exact DTW on the same features over the whole library on the first
--baseline queries gives the ratio and how often both find the same clip."""


def _add_storybeam_scale(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "storybeam-scale", "storybeam method: 1-NN over the scale library, one core",
                STORYBEAM_SCALE_DOC, _run_storybeam_scale)
    p.add_argument("--data", type=Path, default=None, help="labelled folder (default: the shared CMU set)")
    p.add_argument("--clips", type=_at_least(1), default=2600, help="at least this many derived clips (default 2600)")
    p.add_argument("--hours", type=float, default=9.0, help="and at least this many hours (default 9)")
    p.add_argument("--baseline", type=_at_least(0), default=5, help="queries also run by exact DTW (default 5)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _run_storybeam_scale(args: argparse.Namespace) -> int:
    from lab.bench.storybeam_scale import format_table, run_storybeam_scale_bench  # deferred: numba

    if not args.hours >= 0:
        raise StoryBeamError(f"--hours {args.hours:g}: must be 0 or more")
    data = args.data or SHARED_CMU
    if not (Path(data) / "labels.csv").is_file():
        raise StoryBeamError(f"--data {data}: no labels.csv (the shared CMU set, or a labelled folder)")
    result = run_storybeam_scale_bench(data, min_clips=args.clips, min_hours=args.hours,
                                       baseline_queries=args.baseline, progress=not args.quiet)
    return _finish(args, result, format_table(result))


# ---------------------------------------------------------------------- act-it-out
ACT_IT_OUT_DOC = """"Act it out" end to end (lab/bench/act_it_out.py, docs/notebook/act-it-out.md): synthetic
performances of --limit trials (a human-proportioned figure and the kid character, 5
classes, in place, facing the camera; the person also turned 30 degrees and before a
cluttered background), rendered at 640x480 and 30 fps, tracked by ar.body on one core,
searched by the frontal ActSearch. Reports detection rate, 1-NN class accuracy with the
trial and with the subject left out, the true-joint ceiling, per-class recall,
pose_ms_median and search_ms. Landmarks (never frames) are cached under --cache.

With --videos DIR (a folder of clips with labels.csv: file,label) it runs real footage
instead (lab/bench/act_videos.py): every clip through the product's flow (ar.body, then
the frontal ActSearch over --data), per-class top-1 and top-k accuracy, a confusion-matrix
PNG beside the JSON, the body-found rate per clip, pose and search medians, one core."""


ACT_JSON_DEFAULT = "out/act_it_out_bench.json"


def _add_act_it_out(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "act-it-out", "Act it out: detection, class accuracy, ceiling, pose and search time",
                ACT_IT_OUT_DOC, _run_act_it_out, json_default=ACT_JSON_DEFAULT)
    p.add_argument("--data", type=Path, default=None, help="labelled folder (default: the shared CMU set)")
    p.add_argument("--limit", type=_at_least(1), default=60, help="trials performed per variant (default 60)")
    p.add_argument("--extra-limit", type=_at_least(1), default=None,
                   help="trials for the turned and cluttered variants (default: --limit)")
    p.add_argument("--seed", type=int, default=2, help="which trials are drawn (default 2; 1 was used for tuning)")
    p.add_argument("--variants", default="person,kid,person-turned,person-clutter",
                   help="comma-separated variants (default: all four)")
    p.add_argument("--seconds", type=_fps, default=None, help="take length in seconds (default 3.5)")
    p.add_argument("--cache", type=Path, default=Path("out/act_it_out"), help="landmark cache folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--videos", type=Path, default=None,
                   help="real footage instead: a folder of clips with labels.csv (file,label); "
                        "the JSON then goes to out/act_it_out_videos.json unless --json names another file")
    p.add_argument("--top", type=_at_least(1), default=3, help="with --videos: top-k accuracy (default 3)")
    add_moves_argument(p)


def _run_act_it_out(args: argparse.Namespace) -> int:
    data = args.data or SHARED_CMU
    if not (Path(data) / "labels.csv").is_file():
        raise StoryBeamError(f"--data {data}: no labels.csv (the shared CMU set, or a labelled folder)")
    if args.videos is not None:
        return _run_act_videos(args, Path(data))
    from lab.bench.act_it_out import format_table, run_act_it_out_bench  # deferred: pyrender, ar.body

    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    kw = {"take_seconds": args.seconds} if args.seconds else {}
    kw["extra_limit"] = args.extra_limit
    kw["moves"] = moves_folder(args.moves)
    result = run_act_it_out_bench(Path(data), args.limit, args.seed, variants, args.cache,
                                  None if args.quiet else progress_bar("bench act-it-out", "take"), **kw)
    return _finish(args, result, format_table(result))


def _run_act_videos(args: argparse.Namespace, data: Path) -> int:
    """``bench act-it-out --videos DIR``: real clips through the flow (lab/bench/act_videos.py)."""
    from lab.bench.act_videos import format_videos_table, run_act_videos_bench  # deferred: ar.body, matplotlib

    if args.json_out == Path(ACT_JSON_DEFAULT):  # the synthetic bench's file is left alone
        args.json_out = Path("out/act_it_out_videos.json")
    plot = args.json_out.with_name(args.json_out.stem + "_confusion.png") if args.json_out else None
    result = run_act_videos_bench(args.videos, data, args.cache, args.top,
                                  None if args.quiet else progress_bar("bench act-it-out --videos", "clip"), plot,
                                  moves=moves_folder(args.moves))
    return _finish(args, result, format_videos_table(result))


ACT_CAMERAS_DOC = """How real cameras change "Act it out"'s answer (lab/bench/act_cameras.py,
docs/notebook/act-it-out.md): --limit held-out CMU trials' true joints turned into
BlazePose-like landmarks and filmed by pinhole cameras of each condition (table height,
pitch, wide lens, 24/60 fps, travel towards or across, short/long takes, cut at the
knees), searched as a camera take is (1-NN, trial left out). No renderer, no estimator."""


def _add_act_cameras(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "act-cameras", "Act it out under real-camera geometry: accuracy per condition",
                ACT_CAMERAS_DOC, _run_act_cameras, json_default="out/act_cameras_bench.json")
    p.add_argument("--data", type=Path, default=None, help="labelled folder (default: the shared CMU set)")
    p.add_argument("--limit", type=_at_least(1), default=60, help="trials per condition (default 60)")
    p.add_argument("--seed", type=int, default=2, help="which trials are drawn (default 2)")
    p.add_argument("--conditions", default=None, help="comma-separated conditions (default: all)")
    p.add_argument("--noise-px", type=float, default=0.0, help="Gaussian pixel noise on the image landmarks")
    add_moves_argument(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _run_act_cameras(args: argparse.Namespace) -> int:
    from lab.bench.act_cameras import CONDITIONS, format_table, run_act_cameras_bench  # deferred: the library

    data = args.data or SHARED_CMU
    if not (Path(data) / "labels.csv").is_file():
        raise StoryBeamError(f"--data {data}: no labels.csv (the shared CMU set, or a labelled folder)")
    conds = [c.strip() for c in args.conditions.split(",") if c.strip()] if args.conditions else list(CONDITIONS)
    result = run_act_cameras_bench(Path(data), args.limit, args.seed, conds, args.noise_px,
                                   progress=None if args.quiet else progress_bar("bench act-cameras", "take"),
                                   moves=moves_folder(args.moves))
    return _finish(args, result, format_table(result))


# ------------------------------------------------------------------------ find-body
FIND_BODY_DOC = """Finding the body wherever it is (lab/bench/find_body.py, docs/notebook/pose.md):
scenes of known truth at 1920x1080 (a person in the middle, one 1/6 of the height at the
edge, one walking in, three people with the central one to follow, an empty room),
tracked on one core with and without the tile pass: frames found, frames on the right
person, ms per frame (all, tracked, with the detector), tile runs; the cost of an
acquisition frame alone; with --videos DIR (labels.csv: file,label) real clips too."""


def _add_find_body(sub: argparse._SubParsersAction) -> None:
    p = _parser(sub, "find-body", "finding the body: small, at the edge, several people; cost per frame",
                FIND_BODY_DOC, _run_find_body, json_default="out/find_body_bench.json")
    p.add_argument("--frames", type=_at_least(4), default=45, help="frames per scene (default 45)")
    p.add_argument("--tiles-per-frame", type=_at_least(1), default=4,
                   help="tile runs per frame while a sweep looks for a body (default 4)")
    p.add_argument("--videos", type=Path, default=None, help="a folder of real clips with labels.csv (file,label)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _run_find_body(args: argparse.Namespace) -> int:
    from lab.bench.find_body import format_table, run_find_body_bench  # deferred: ar.body, the interpreter

    result = run_find_body_bench(args.frames, args.tiles_per_frame, args.videos,
                                 progress=None if args.quiet else progress_bar("bench find-body", "part"))
    return _finish(args, result, format_table(result))


#: Benchmark targets: name -> function adding its sub-parser (in `storybeam bench --help` order).
TARGETS: dict[str, Callable[[argparse._SubParsersAction], None]] = {
    "retrieval": _add_retrieval,
    "ar": _add_ar,
    "animation": _add_animation,
    "dtw-kernels": _add_dtw_kernels,
    "motion-io": _add_motion_io,
    "numpy-retrieval": _add_numpy_retrieval,
    "fast-search-profile": _add_fast_search_profile,
    "pose-search": _add_pose_search,
    "act-it-out": _add_act_it_out,
    "act-cameras": _add_act_cameras,
    "find-body": _add_find_body,
    "storybeam-scale": _add_storybeam_scale,
    "surface": _add_surface,
}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``bench`` and one sub-parser per entry of :data:`TARGETS`."""
    p = subparsers.add_parser("bench", help="benchmarks: " + ", ".join(TARGETS), description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="bench_target", metavar="TARGET")
    for add in TARGETS.values():
        add(sub)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
