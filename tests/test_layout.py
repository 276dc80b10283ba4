"""Tests mirror the layout: every module of ``retrieval/`` and ``ar/`` is imported by at
least one test file (``tests/**/test_*.py``).

A module counts as imported when a test file imports it by its path
(``from retrieval.dtw.lower_bounds import lb_kim``, ``import retrieval.dtw.jit``) or takes
one of its names through a package that re-exports it (``from retrieval.dtw import
lb_kim`` reaches ``retrieval.dtw.lower_bounds`` through ``retrieval/dtw/__init__.py``;
``import retrieval.dtw as dtw`` followed by ``dtw.lb_kim`` too), following re-exports
through nested packages (``retrieval.motion`` → ``retrieval.motion.formats`` →
``retrieval.motion.formats.bvh``). The static scan is ``tests/support/imports.py``.
"""
from __future__ import annotations

import ast
import textwrap
from collections.abc import Iterable, Mapping
from pathlib import Path

from tests.support.imports import REPO, Module, scan

LIBRARY = ("retrieval", "ar")


def reexports(modules: Mapping[str, Module]) -> dict[tuple[str, str], str]:
    """(package, name) → the module that defines ``name``, following re-exports through
    nested packages."""
    direct: dict[tuple[str, str], str] = {}
    for module in modules.values():
        if not module.is_package:
            continue
        for imp in module.imports:
            if imp.name and not imp.function_level and imp.target in modules:
                direct[(module.name, imp.name)] = imp.target
    resolved = {}
    for key, target in direct.items():
        name, seen = key[1], {key}
        while target in modules and modules[target].is_package and (target, name) in direct:
            if (target, name) in seen:
                break
            seen.add((target, name))
            target = direct[(target, name)]
        resolved[key] = target
    return resolved


def _attributes(tree: ast.AST) -> set[str]:
    return {node.attr for node in ast.walk(tree) if isinstance(node, ast.Attribute)}


def covered(modules: Mapping[str, Module], test_names: Iterable[str]) -> set[str]:
    """The library modules the given test modules import, directly or through packages."""
    via = reexports(modules)
    out: set[str] = set()
    for name in test_names:
        test = modules[name]
        attributes = _attributes(test.tree)
        for imp in test.imports:
            target = imp.target
            if target not in modules:
                continue
            parts = target.split(".")
            out.update(".".join(parts[:i]) for i in range(1, len(parts) + 1))
            if not modules[target].is_package:
                continue
            names = [imp.name] if imp.name else []
            if imp.name is None or imp.name == "*":  # `import pkg` / `from pkg import *`: use attributes
                names = [n for (pkg, n) in via if pkg == target and (n in attributes or imp.name == "*")]
            for n in names:
                if (target, n) in via:
                    out.add(via[(target, n)])
    return out


def untested(modules: Mapping[str, Module], library: Iterable[str] = LIBRARY) -> list[str]:
    tests = [name for name, m in modules.items() if name.startswith("tests.") and m.path.name.startswith("test_")]
    seen = covered(modules, tests)
    prefixes = tuple(library)
    return sorted(
        name for name, m in modules.items()
        if name.split(".")[0] in prefixes and not m.is_package and name not in seen
    )


def test_every_library_module_is_imported_by_a_test():
    modules = scan(packages=("retrieval", "ar", "app", "tests"))
    missing = untested(modules)
    assert not missing, (
        f"{len(missing)} modules of retrieval/ and ar/ that no tests/**/test_*.py imports "
        f"(by module path or through a package): {missing}"
    )


def test_coverage_scan_can_fail(tmp_path: Path):
    files = {
        "lib/__init__.py": '"""L."""\nfrom lib.sub import thing\n',
        "lib/sub/__init__.py": '"""S."""\nfrom lib.sub.deep import thing\n',
        "lib/sub/deep.py": "thing = 1\n",
        "lib/alone.py": "x = 1\n",
        "lib/attr.py": "y = 1\n",
        "lib/other.py": "from lib.attr import y\n",
        "tests/__init__.py": "",
        "tests/test_a.py": "from lib import thing\nimport lib.other\n",
        "tests/helper.py": "import lib.alone\n",  # not a test file: does not count
    }
    for rel, text in files.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(textwrap.dedent(text), encoding="utf-8")
    modules = scan(tmp_path, packages=("lib", "tests"))
    assert untested(modules, library=("lib",)) == ["lib.alone", "lib.attr"]


def test_repo_scan_sees_the_test_files():
    modules = scan(packages=("retrieval", "ar", "app", "tests"))
    assert "tests.test_layout" in modules and (REPO / "tests" / "test_layout.py") == modules["tests.test_layout"].path


#: The most lines one module may have (issue 30): past it, a module holds more than one concept.
MAX_MODULE_LINES = 700


def long_modules(root: Path, limit: int = MAX_MODULE_LINES) -> list[str]:
    """``path: N lines`` for every ``.py`` under ``root`` (virtual environments and build
    folders aside) longer than ``limit`` lines."""
    skip = {".venv", ".git", ".buildozer", "build", "out", ".kivy"}
    out = []
    for path in sorted(root.rglob("*.py")):
        if skip & set(path.relative_to(root).parts):
            continue
        n = len(path.read_text(encoding="utf-8", errors="replace").splitlines())
        if n > limit:
            out.append(f"{path.relative_to(root)}: {n} lines")
    return out


def test_no_module_is_over_the_line_limit():
    long = long_modules(REPO)
    assert not long, f"modules over {MAX_MODULE_LINES} lines (split them by concept): {long}"


def test_line_limit_check_can_fail(tmp_path: Path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "big.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    (tmp_path / "pkg" / "small.py").write_text("x = 1\n" * MAX_MODULE_LINES)
    assert long_modules(tmp_path) == [f"pkg/big.py: {MAX_MODULE_LINES + 1} lines"]
