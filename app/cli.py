"""The `storybeam` command line: one subcommand per module in `app.commands`.

Every module ``app/commands/*_cmd.py`` is a command: it defines ``register(subparsers)``,
which adds its parser and sets ``func`` to a callable taking the parsed arguments and
returning an exit code. The modules are found with :mod:`pkgutil`, so a new command is a
new file; :data:`COMMAND_ORDER` fixes the order `storybeam --help` lists them in (others
follow alphabetically). A command module that fails to import is an error naming the
module and the exception -- never a command silently missing from the list.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from types import ModuleType

import app.commands
from retrieval.errors import StoryBeamError

#: Commands in the order `storybeam --help` lists them (module names without ``_cmd``);
#: a command module not named here is listed after these, alphabetically.
COMMAND_ORDER = (
    "eval", "search", "cluster", "build_library", "board", "calibrate", "render", "demo", "export", "app", "bench",
    "stress",
)


class CommandImportError(StoryBeamError):
    """A module under app/commands could not be imported."""


def command_modules() -> list[str]:
    """The full names of the command modules (``app.commands.*_cmd``), in help order."""
    names = [m.name for m in pkgutil.iter_modules(app.commands.__path__) if m.name.endswith("_cmd")]
    rank = {name: i for i, name in enumerate(COMMAND_ORDER)}
    names.sort(key=lambda n: (rank.get(n[: -len("_cmd")], len(rank)), n))
    return [f"{app.commands.__name__}.{n}" for n in names]


def load_command(name: str) -> ModuleType:
    """Import one command module; :class:`CommandImportError` (naming the module and the
    exception) if it fails or defines no ``register``."""
    try:
        module = importlib.import_module(name)
    except Exception as exc:  # any failure: report it, do not drop the command
        path = name.replace(".", "/") + ".py"
        raise CommandImportError(f"{path}: command module {name} failed to import: "
                                 f"{type(exc).__name__}: {exc}") from exc
    if not callable(getattr(module, "register", None)):
        raise CommandImportError(f"{module.__file__}: command module {name} defines no register(subparsers)")
    return module


def build_parser() -> argparse.ArgumentParser:
    """The parser with every command module registered (raises CommandImportError)."""
    parser = argparse.ArgumentParser(
        prog="storybeam",
        description="StoryBeam: projected AR storytelling with motion-capture retrieval.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in command_modules():
        load_command(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        parser = build_parser()
    except CommandImportError as exc:
        print(f"storybeam: error: {exc}", file=sys.stderr)
        return 1
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
