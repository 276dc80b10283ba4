"""The `storybeam` command line: one subcommand per module in `app.commands`.

Each command module defines ``register(subparsers)``, which adds its parser and sets
``func`` to a callable taking the parsed arguments and returning an exit code. Keeping
one module per command lets the retrieval, AR and app parts grow their commands without
touching each other.
"""
from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys

from retrieval.errors import StoryBeamError

#: Command modules, in the order `storybeam --help` lists them.
COMMAND_MODULES = (
    "app.commands.eval_cmd",
    "app.commands.search_cmd",
    "app.commands.board_cmd",
    "app.commands.calibrate_cmd",
    "app.commands.ar_bench_cmd",
    "app.commands.render_cmd",
    "app.commands.demo_cmd",
    "app.commands.app_cmd",
    "app.commands.bench_cmd",
    "app.commands.stress_cmd",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="storybeam",
        description="StoryBeam: projected AR storytelling with motion-capture retrieval.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        if importlib.util.find_spec(name) is None:  # command not built yet
            continue
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except StoryBeamError as exc:  # a user-facing problem: say it plainly, no traceback
        print(f"storybeam {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
