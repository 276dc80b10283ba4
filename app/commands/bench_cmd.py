"""`storybeam bench TARGET`: benchmarks, one sub-target each.

``storybeam bench retrieval [--json OUT] [--quick]`` runs the retrieval speed benchmark
(:mod:`app.bench.retrieval`): the paper protocol for the fast search, the seed's
method, exact DTW and dtaidistance side by side, the ablations, 1-NN latency over a
CMU-sized derived library, and memory. Other targets join by adding an entry to
:data:`TARGETS`.
"""
from __future__ import annotations

import argparse

from app.commands.output import write_json_report


def _add_retrieval(sub) -> None:
    p = sub.add_parser("retrieval", help="retrieval speed: paper protocol, ablations, library-scale latency",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", help="labelled folder (default: the shared CMU set, else the bundled library)")
    p.add_argument("--fps", type=float, default=120.0,
                   help="frame rate of the protocol, the same for every method (default 120: CMU's and the research's)")
    p.add_argument("--scale-fps", type=float, default=30.0, help="frame rate of the scale library (default 30, the app's)")
    p.add_argument("--dims", type=int, default=6)
    p.add_argument("--quick", action="store_true", help="tiny run: bundled library, small scale library, 5 queries")
    p.add_argument("--json", dest="json_out", help="write the results as JSON here")
    p.add_argument("--plot", help="write the latency-vs-library-size plot here (PNG)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=_run_retrieval)


def _run_retrieval(args) -> int:
    from app.bench.retrieval import format_report, run_retrieval_bench

    out = run_retrieval_bench(args.data, fps=args.fps, scale_fps=args.scale_fps, quick=args.quick, dims=args.dims,
                              plot=args.plot, progress=not args.quiet)
    print(format_report(out))
    if args.json_out:
        write_json_report(args.json_out, out)
    return 0


#: Benchmark targets: name -> function adding its sub-parser.
TARGETS = {"retrieval": _add_retrieval}


def register(subparsers) -> None:
    p = subparsers.add_parser("bench", help="benchmarks (retrieval, ...)", description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="bench_target", metavar="TARGET")
    for add in TARGETS.values():
        add(sub)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
