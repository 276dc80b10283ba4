"""`storybeam stress`: the long robustness campaign (fuzzed motion files, SIGKILLed story
saves, bad packages and calibration files, lost tracking, a random-touch monkey), and
on request coverage-guided fuzzing with atheris (``--only atheris``; ``pip install atheris``).
``storybeam stress power-loss --json OUT`` runs the power-loss campaign alone (the
product's recorded file-system calls replayed onto simulated post-crash disks; needs
strace) and writes its own JSON (``crash_states``, ``acked_lost``, ``corrupt_accepted``,
``open_failures``, ``integrity_failures``, ``control``). ``storybeam stress gate --json OUT``
runs scripted children against the real grown-up check, a simulated school day each, and
simulated grown-ups (:mod:`lab.stress.gate`): ``child_attempts``, ``child_passes``,
``lock_violations``, ``grownup_seconds_median``.

The short versions of the same harnesses run in CI (tests/robust/test_*.py); this command
runs them for as long as asked and writes one JSON summary with the headline figures
(``inputs``, ``crashes``, ``hangs``, ``kills``, ``stories_lost``,
``recovery_frames_max``) plus each harness's detail. See docs/notebook/reliability.md.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

from tqdm import tqdm

from app.paths import MOTIONS_DIR, SHARED_CMU
from lab.stress.atheris_fuzz import require_atheris, run_atheris_campaign  # cheap: stdlib, app.paths, errors
from retrieval.errors import StoryBeamError

#: The harnesses run by default (``--only`` picks a subset).
HARNESSES = ("fuzz", "kill", "packages", "tracking", "monkey", "monkey-teacher")
#: Harnesses that run only when named in ``--only``: atheris is an optional install;
#: power-loss needs strace (also ``storybeam stress power-loss``, with its own JSON).
OPTIONAL_HARNESSES = ("atheris", "power-loss")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("stress", help="robustness campaign (fuzzing, crash-safety, tracking loss, monkey)",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("campaign", nargs="?", choices=("power-loss", "gate"), default=None,
                   help="run one campaign alone and write its own JSON: power-loss (the product's recorded "
                        "file-system calls replayed onto simulated post-crash disks; docs/notebook/reliability.md), "
                        "gate (scripted children against the teacher gate's grown-up check, a school day each)")
    p.add_argument("--children", type=int, default=60,
                   help="gate: children per strategy, one simulated school day each (default 60: >= 10 000 answers)")
    p.add_argument("--grownups", type=int, default=400, help="gate: simulated grown-ups per language (default 400)")
    p.add_argument("--cuts", type=int, default=150,
                   help="power-loss: cut points per recorded workload, 7 crash states each (default 150)")
    p.add_argument("--workloads", type=int, default=2, help="power-loss: recorded workloads (default 2)")
    p.add_argument("--steps", type=int, default=60, help="power-loss: product operations per workload (default 60)")
    p.add_argument("--control", default="no-dir-fsync", choices=("no-dir-fsync", "plain-write", "synchronous-normal"),
                   help="power-loss: the weakened setting of the control run, which must lose data "
                        "(default no-dir-fsync)")
    p.add_argument("--seconds", type=float, default=60.0,
                   help="time budget per harness in seconds (default 60); a count option below stops it earlier")
    p.add_argument("--only", default=",".join(HARNESSES),
                   help=f"comma-separated harnesses to run (default: {','.join(HARNESSES)}; also "
                        f"{','.join(OPTIONAL_HARNESSES)}, coverage-guided fuzzing that needs `pip install atheris`)")
    p.add_argument("--json", type=Path, default=None, help="write the summary as JSON here")
    p.add_argument("--fuzz-inputs", type=int, default=None,
                   help="stop fuzzing (fuzz, atheris) after this many inputs")
    p.add_argument("--kills", type=int, default=None, help="stop the kill harness after this many kills")
    p.add_argument("--frames", type=int, default=3000, help="frames per tracking scenario (default 3000)")
    p.add_argument("--seed", type=int, default=0, help="random seed (every harness is reproducible from it)")
    p.add_argument("--work-dir", type=Path, default=None,
                   help="where crash inputs and scratch databases go (default: a temporary folder)")
    p.set_defaults(func=run)


def selected(only: str) -> list[str]:
    """The harness names of ``--only``, checked: a :class:`StoryBeamError` for an unknown
    name, or for ``atheris`` when atheris is not installed (before anything runs)."""
    names = [n.strip() for n in only.split(",") if n.strip()]
    known = HARNESSES + OPTIONAL_HARNESSES
    unknown = sorted(set(names) - set(known))
    if unknown:
        raise StoryBeamError(f"unknown harness(es) {', '.join(unknown)} (choose from {', '.join(known)})")
    if not names:
        raise StoryBeamError(f"--only names no harness (choose from {', '.join(known)})")
    if "atheris" in names:
        require_atheris()
    return names


def run(args: argparse.Namespace) -> int:
    """Run each selected harness in turn, add up the headline figures, print (and with
    ``--json`` write) the summary; exit 1 when any harness found a crash, hang, lost story
    or other failure."""
    if args.campaign == "power-loss":
        return _power_loss_command(args)
    if args.campaign == "gate":
        return _gate_command(args)
    names = selected(args.only)
    work = args.work_dir or Path(tempfile.mkdtemp(prefix="storybeam-stress-"))
    work.mkdir(parents=True, exist_ok=True)
    summary: dict = {"inputs": 0, "crashes": 0, "hangs": 0, "kills": 0, "stories_lost": 0,
                     "recovery_frames_max": None, "seed": args.seed, "seconds_per_harness": args.seconds,
                     "detail": {}}
    started = time.time()
    for name in names:
        t0 = time.time()
        detail = _RUNNERS[name](args, work / name)
        detail["seconds"] = round(time.time() - t0, 1)
        summary["detail"][name] = detail
        summary["inputs"] += detail.get("inputs", 0)
        summary["crashes"] += detail.get("crashes", 0)
        summary["hangs"] += detail.get("hangs", 0)
        summary["kills"] += detail.get("kills", 0)
        summary["stories_lost"] += detail.get("stories_lost", 0)
        if detail.get("recovery_frames_max") is not None:
            prev = summary["recovery_frames_max"]
            summary["recovery_frames_max"] = max(prev or 0, detail["recovery_frames_max"])
        print(f"{name}: " + ", ".join(f"{k}={v}" for k, v in detail.items() if not isinstance(v, (dict, list))),
              file=sys.stderr)
    summary["seconds"] = round(time.time() - started, 1)
    text = json.dumps(summary, indent=1, default=str)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text + "\n")
    print(text)
    failed = summary["crashes"] or summary["hangs"] or summary["stories_lost"] or any(
        d.get("failures") for d in summary["detail"].values())
    return 1 if failed else 0


# ----------------------------------------------------------------------------- runners


def _run_fuzz(args: argparse.Namespace, work: Path) -> dict:
    from lab.stress import fuzz_motion as fuzz  # deferred: the stress layer (numpy, the loaders) only when run

    seeds = fuzz.collect_seeds(SHARED_CMU if SHARED_CMU.is_dir() else None, MOTIONS_DIR / "bvh")
    with tqdm(total=args.fuzz_inputs, desc="fuzz motion files", unit="input", file=sys.stderr) as bar:
        stats = fuzz.run_campaign(seeds, inputs=args.fuzz_inputs, seconds=args.seconds, rng_seed=args.seed,
                                  crash_dir=work / "crashes", progress=bar.update)
    out = stats.to_dict()
    out["seeds"] = {k: sum(1 for s in seeds if s.kind == k) for k in fuzz.KINDS}
    out["seed_source"] = "shared CMU" if SHARED_CMU.is_dir() else "bundled BVH"
    out["probes"] = fuzz.memory_probes(work)
    out["failures"] = sum(1 for p in out["probes"] if not p["ok"])
    return out


def _run_atheris(args: argparse.Namespace, work: Path) -> dict:
    with tqdm(desc="atheris (libFuzzer)", unit="line", file=sys.stderr) as bar:
        def show(line: str) -> None:
            bar.set_postfix_str(line[:60], refresh=False)
            bar.update(1)

        return run_atheris_campaign(work, seconds=args.seconds, runs=args.fuzz_inputs, seed=args.seed, progress=show)


def _run_kill(args: argparse.Namespace, work: Path) -> dict:
    from lab.stress.kill import run_kill_campaign  # deferred: the stress layer only when run

    return run_kill_campaign(work, kills=args.kills, seconds=args.seconds, seed=args.seed)


def _run_packages(args: argparse.Namespace, work: Path) -> dict:
    from lab.stress.files import run_bad_file_campaign  # deferred: the stress layer (OpenCV) only when run

    return run_bad_file_campaign(work, seconds=args.seconds, seed=args.seed)


def _run_tracking(args: argparse.Namespace, work: Path) -> dict:
    from lab.stress.tracking import run_tracking_campaign  # deferred: the stress layer (OpenCV) only when run

    return run_tracking_campaign(frames=args.frames, seed=args.seed)


def _run_power_loss(args: argparse.Namespace, work: Path) -> dict:
    from lab.stress.power_loss import run_power_loss  # deferred: the stress layer (OpenCV, strace) only when run

    total = args.workloads * args.cuts * 7 + args.cuts * 7
    with tqdm(total=total, desc="power-loss crash states", unit="state", file=sys.stderr) as bar:
        return run_power_loss(work, workloads=args.workloads, steps=args.steps, cuts=args.cuts, seed=args.seed,
                              control=args.control, progress=bar.update)


def _power_loss_command(args: argparse.Namespace) -> int:
    """``storybeam stress power-loss``: print and write the campaign's own JSON; exit 1 when
    acknowledged data was lost, damage was accepted, a profile did not open or pass its
    integrity check, or the control lost nothing (the harness would then prove nothing)."""
    work = args.work_dir or Path(tempfile.mkdtemp(prefix="storybeam-power-loss-"))
    out = _run_power_loss(args, work)
    text = json.dumps(out, indent=1)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text + "\n")
    print(text)
    return 1 if out["failures"] else 0


def _gate_command(args: argparse.Namespace) -> int:
    """``storybeam stress gate``: print and write the campaign's JSON; exit 1 when a child
    passed, a lock was cut short, or the grown-ups' median is 30 s or more."""
    from lab.stress.gate import STRATEGIES, run_gate_campaign  # deferred: the stress layer only when run

    if args.children < 1 or args.grownups < 1:
        raise StoryBeamError("--children and --grownups must be at least 1")
    work = args.work_dir or Path(tempfile.mkdtemp(prefix="storybeam-gate-"))
    with tqdm(total=args.children * len(STRATEGIES) + 4, desc="gate: child-days, grown-up runs", unit="run",
              file=sys.stderr) as bar:
        out = run_gate_campaign(work, children=args.children, grownups=args.grownups, seed=args.seed,
                                progress=bar.update)
    text = json.dumps(out, indent=1)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text + "\n")
    print(text)
    return 1 if out["failures"] else 0


def _run_monkey(args: argparse.Namespace, work: Path) -> dict:
    from lab.stress.monkey import run_monkey  # deferred: the stress layer only when run (Kivy runs in a child)

    return run_monkey(work, seconds=args.seconds, seed=args.seed, progress=True)


def _run_monkey_teacher(args: argparse.Namespace, work: Path) -> dict:
    from lab.stress.monkey import run_monkey  # deferred: the stress layer only when run (Kivy runs in a child)

    return run_monkey(work, seconds=args.seconds, seed=args.seed, progress=True, teacher=True)


_RUNNERS: dict[str, Callable[[argparse.Namespace, Path], dict]] = {
    "fuzz": _run_fuzz, "kill": _run_kill, "packages": _run_packages, "tracking": _run_tracking,
    "monkey": _run_monkey, "monkey-teacher": _run_monkey_teacher, "atheris": _run_atheris,
    "power-loss": _run_power_loss,
}
