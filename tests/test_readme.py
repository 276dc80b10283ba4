"""The README stays true and short (issue 30).

* Every ``storybeam`` line of its *Commands* block names a command the CLI registers,
  sub-targets it has (``bench retrieval|ar|...``), options that command accepts, and, where
  an option has a fixed set of values, only values from that set.
* It reads in five minutes: under 1 200 words, no table cell over 40 words.
* Every link into the repository points at a file that exists.

The parser is the real one (:func:`app.cli.build_parser`); argparse's own records of each
parser's actions are read to know its options, sub-commands and choices.
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from app.cli import build_parser

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
PLACEHOLDER = re.compile(r"^[A-Z0-9_.,:/*]|[./:]|^\d")


def _readme() -> str:
    return README.read_text(encoding="utf-8")


def _commands_block(text: str) -> list[str]:
    """The ``storybeam ...`` lines of the fenced block under ``## Commands`` (comments cut)."""
    section = text.split("## Commands", 1)[1].split("\n## ", 1)[0]
    block = section.split("```", 2)[1]
    lines = [line.split("#", 1)[0].rstrip() for line in block.splitlines()]
    return [line.strip() for line in lines if line.strip().startswith("storybeam ")]


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:  # argparse keeps its actions here; no public accessor
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _options(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    return {opt: action for action in parser._actions for opt in action.option_strings}


def _positional_choices(parser: argparse.ArgumentParser) -> set[str]:
    return {str(c) for a in parser._actions if not a.option_strings and a.choices
            and not isinstance(a, argparse._SubParsersAction) for c in a.choices}


def command_problems(line: str, root: argparse.ArgumentParser) -> list[str]:
    """What in one README command line the CLI does not know (empty when all is true)."""
    tokens = [t.strip("[]()") for t in line.split()][1:]
    tokens = [t for t in tokens if t and t != "|"]
    problems: list[str] = []
    commands = _subparsers(root)
    if not tokens or tokens[0] not in commands:
        return [f"{line!r}: no command {tokens[0] if tokens else ''!r}"]
    parsers = [commands[tokens[0]]]
    i = 1
    while i < len(tokens):
        token = tokens[i]
        if token.startswith("-"):
            option = token.split("=", 1)[0]
            value = tokens[i + 1] if i + 1 < len(tokens) and not tokens[i + 1].startswith("-") else None
            for parser in parsers:
                action = _options(parser).get(option)
                if action is None:
                    problems.append(f"{line!r}: {parser.prog} has no option {option}")
                    continue
                if value is not None and action.choices and action.nargs != 0:
                    for part in re.split(r"[|,]", value):
                        if part and not PLACEHOLDER.search(part) and part not in {str(c) for c in action.choices}:
                            problems.append(f"{line!r}: {option} does not take {part!r}")
            i += 2 if value is not None and all(_options(p).get(option) is not None
                                                and _options(p)[option].nargs != 0 for p in parsers) else 1
            continue
        if PLACEHOLDER.search(token):
            i += 1
            continue
        names = token.split("|")
        nested = [_subparsers(p) for p in parsers]
        if all(nested):
            for name in names:
                if not all(name in n for n in nested):
                    problems.append(f"{line!r}: no sub-command {name!r}")
            parsers = [n[name] for n in nested for name in names if name in n]
        else:
            for name in names:
                if not any(name in _positional_choices(p) for p in parsers):
                    problems.append(f"{line!r}: {name!r} is not a choice of {parsers[0].prog}")
        i += 1
    return problems


def test_every_readme_command_exists_with_its_options():
    lines = _commands_block(_readme())
    assert len(lines) >= 15, lines
    root = build_parser()
    problems = [p for line in lines for p in command_problems(line, root)]
    assert not problems, "\n".join(problems)
    named = {line.split()[1] for line in lines}
    assert named == set(_subparsers(root)), ("commands the README does not list, or lists but the CLI lacks",
                                             sorted(named ^ set(_subparsers(root))))
    bench_targets = {t for line in lines if line.startswith("storybeam bench ")
                     for t in line.split()[2].split("|")}
    assert bench_targets == set(_subparsers(_subparsers(root)["bench"])), "README's bench targets drifted"


def test_the_checker_catches_a_drifted_line():
    root = build_parser()
    assert command_problems("storybeam search --query FILE", root) == []
    assert command_problems("storybeam serch --query FILE", root)
    assert command_problems("storybeam search --nearest 3", root)
    assert command_problems("storybeam bench retrieval|nonsense [--json OUT]", root)
    assert command_problems("storybeam app --lang fr", root)
    assert command_problems("storybeam stress power-cut", root)
    assert command_problems("storybeam stress power-loss [--json OUT]", root) == []


def test_readme_reads_in_five_minutes():
    text = _readme()
    words = len(re.findall(r"\S+", text))
    assert words < 1200, f"README has {words} words; keep it under 1 200 (details belong in docs/)"
    cells = [cell.strip() for line in text.splitlines() if line.startswith("|")
             for cell in line.strip().strip("|").split("|")]
    long = [c for c in cells if len(c.split()) > 40]
    assert not long, f"table cells over 40 words: {long}"


@pytest.mark.parametrize("page", ["README.md", *sorted(str(p.relative_to(REPO)) for p in (REPO / "docs").rglob("*.md"))])
def test_links_into_the_repository_exist(page):
    path = REPO / page
    text = path.read_text(encoding="utf-8")
    missing = []
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
        if re.match(r"^[a-z]+:", target):
            continue  # a URL
        if not (path.parent / target).exists():
            missing.append(target)
    assert not missing, f"{page}: links to missing files: {missing}"
