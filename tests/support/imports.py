"""A static scan of StoryBeam's imports, shared by ``tests/test_layering.py`` and
``scripts/draw_architecture.py``.

Method: every ``.py`` file under the scanned packages is parsed with :mod:`ast` (nothing
is imported or executed). Each ``import`` / ``from ... import`` statement becomes one
:class:`Import` record per imported name, with

* the target resolved to an absolute module name: relative imports against the importing
  module's package; ``from pkg import name`` to the submodule ``pkg.name`` when such a file
  exists, otherwise to ``pkg`` itself (its ``__init__``, which in turn counts as importing
  whatever it imports);
* where it sits: at module level, or inside a ``def``/``class`` body (a *function-level*
  import), and whether it is guarded by ``if TYPE_CHECKING:`` (never executed);
* the ``optional:`` / ``deferred:`` marker from a comment on the same line or the line
  above, which is how a function-level import says why it is deferred.

On top of the records: :func:`unit_of` maps a module to its *unit* (the package-level node
of the architecture: ``retrieval.motion``, ``ar.render``, ``app.story``, ...),
:func:`module_graph` / :func:`unit_graph` build the dependency graphs of module-level
imports, and :func:`find_cycle` returns one cycle of a graph, if any.
"""
from __future__ import annotations

import ast
import re
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

#: The library packages the scan covers (tests and scripts are not library code).
PACKAGES = ("retrieval", "ar", "app", "lab")

#: Package-level nodes of the architecture, most specific first where they nest. A module
#: belongs to the longest unit that is a prefix of its name (``retrieval.motion.formats.bvh``
#: → ``retrieval.motion``; ``ar.pose`` → ``ar``; ``app.cli`` → ``app.cli``). ``ar`` is split
#: by what its modules need: the tracking core, body pose in ``ar.body`` (the core and a
#: TFLite interpreter), the renderer-agnostic ``ar.scene``, the pyrender/trimesh renderers in
#: ``ar.render`` (which use the core), and ``ar.closed_loop`` (which uses both).
UNITS = (
    "retrieval",
    "retrieval.errors",
    "retrieval.durable",
    "retrieval.motion",
    "retrieval.features",
    "retrieval.codes",
    "retrieval.dtw",
    "retrieval.search",
    "retrieval.library",
    "retrieval.animation",
    "ar",
    "ar.body",
    "ar.scene",
    "ar.render",
    "ar.closed_loop",
    "app",
    "app.paths",
    "app.progress",
    "app.story",
    "app.player",
    "app.services",
    "app.ui",
    "app.commands",
    "app.cli",
    "lab",
    "lab.experiment",
    "lab.bench",
    "lab.stress",
)

_MARKER = re.compile(r"#.*\b(optional|deferred):")
STDLIB = frozenset(sys.stdlib_module_names) | {"__future__"}


@dataclass(frozen=True)
class Import:
    """One imported name (or module) of one import statement."""

    path: Path  #: the importing file
    lineno: int
    importer: str  #: the importing module, e.g. ``retrieval.dtw.kernels``
    target: str  #: the resolved absolute module imported
    name: str | None  #: for ``from m import name``: the name (None for ``import m``)
    statement: str  #: the statement's source, for messages
    function_level: bool  #: inside a def/class body
    type_checking: bool  #: under ``if TYPE_CHECKING:``
    marker: str | None  #: ``optional`` or ``deferred`` when a comment says so
    asname: str | None = None  #: ``as`` name, when the import renames

    @property
    def bound(self) -> str | None:
        """The name ``from m import name [as other]`` binds (None for ``import m``)."""
        return self.asname or self.name

    @property
    def top(self) -> str:
        return self.target.split(".")[0]

    def where(self, root: Path = REPO) -> str:
        try:
            rel = self.path.relative_to(root)
        except ValueError:
            rel = self.path
        return f"{rel}:{self.lineno}"

    def describe(self, root: Path = REPO) -> str:
        return f"{self.where(root)}: {self.statement}"


@dataclass
class Module:
    """One scanned source file."""

    name: str
    path: Path
    is_package: bool
    tree: ast.Module
    source_lines: list[str]
    imports: list[Import] = field(default_factory=list)

    @property
    def docstring(self) -> str | None:
        return ast.get_docstring(self.tree)


def module_name(path: Path, root: Path) -> tuple[str, bool]:
    """Dotted module name of ``path`` below ``root``, and whether it is a package."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    is_package = parts[-1] == "__init__"
    if is_package:
        parts = parts[:-1]
    return ".".join(parts), is_package


def discover(root: Path = REPO, packages: Iterable[str] = PACKAGES) -> dict[str, Path]:
    """Every module file under ``packages`` (recursively): dotted name → path."""
    found: dict[str, Path] = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            if any(part.startswith(".") or part == "__pycache__" for part in path.relative_to(root).parts):
                continue
            found[module_name(path, root)[0]] = path
    return found


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _marker(lines: list[str], lineno: int) -> str | None:
    for index in (lineno - 1, lineno - 2):  # the line itself, then the line above
        if 0 <= index < len(lines):
            match = _MARKER.search(lines[index])
            if match:
                return match.group(1)
    return None


def _resolve_base(importer: str, is_package: bool, level: int, module: str | None) -> str:
    if level == 0:
        return module or ""
    parts = importer.split(".") if is_package else importer.split(".")[:-1]
    if level > 1:
        parts = parts[: len(parts) - (level - 1)]
    base = ".".join(parts)
    return f"{base}.{module}" if module else base


def bound_names(tree: ast.Module) -> set[str]:
    """Names a module binds at its top level (imports, defs, classes, assignments): for a
    package ``__init__``, the attributes ``from package import name`` finds before it
    would fall back to importing a submodule called ``name``."""
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            for alias in node.names:
                names.add(alias.asname or alias.name.split(".")[0])
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                names.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
    return names


def parse_module(
    name: str,
    path: Path,
    is_package: bool,
    known: Mapping[str, Path],
    package_names: Mapping[str, set[str]] | None = None,
) -> Module:
    """Parse one file and collect its :class:`Import` records.

    ``known`` is the set of module names that exist and ``package_names`` what each
    package's ``__init__`` binds (:func:`bound_names`), to tell ``from pkg import
    submodule`` from ``from pkg import attribute`` the way Python does: an attribute the
    ``__init__`` binds wins (``from retrieval.animation import retarget`` is the function
    the package re-exports, reached through the package), otherwise the submodule."""
    source = path.read_text(encoding="utf-8")
    tree = ast.parse(source, filename=str(path))
    lines = source.splitlines()
    module = Module(name, path, is_package, tree, lines)
    package_names = package_names or {}

    def exists(candidate: str) -> bool:
        package, _, attribute = candidate.rpartition(".")
        return candidate in known and attribute not in package_names.get(package, set())

    def visit(node: ast.AST, function_level: bool, type_checking: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Lambda)):
                visit(child, True, type_checking)
            elif isinstance(child, ast.If) and _is_type_checking(child.test):
                for item in child.body:
                    visit(ast.Module(body=[item], type_ignores=[]), function_level, True)
                for item in child.orelse:
                    visit(ast.Module(body=[item], type_ignores=[]), function_level, type_checking)
            elif isinstance(child, (ast.Import, ast.ImportFrom)):
                record(child, function_level, type_checking)
            else:
                visit(child, function_level, type_checking)

    def record(node: ast.Import | ast.ImportFrom, function_level: bool, type_checking: bool) -> None:
        statement = " ".join(
            line.strip() for line in lines[node.lineno - 1 : (node.end_lineno or node.lineno)]
        )
        common = dict(
            path=path,
            lineno=node.lineno,
            importer=name,
            statement=statement,
            function_level=function_level,
            type_checking=type_checking,
            marker=_marker(lines, node.lineno),
        )
        if isinstance(node, ast.Import):
            for alias in node.names:
                module.imports.append(Import(target=alias.name, name=None, **common))
            return
        base = _resolve_base(name, is_package, node.level, node.module)
        for alias in node.names:
            candidate = f"{base}.{alias.name}"
            target = candidate if alias.name != "*" and exists(candidate) else base
            module.imports.append(Import(target=target, name=alias.name, asname=alias.asname, **common))

    visit(tree, False, False)
    return module


def scan(root: Path = REPO, packages: Iterable[str] = PACKAGES) -> dict[str, Module]:
    """Parse every module of ``packages`` below ``root``: dotted name → :class:`Module`."""
    files = discover(root, packages)
    package_names = {
        name: bound_names(ast.parse(path.read_text(encoding="utf-8")))
        for name, path in files.items()
        if path.name == "__init__.py"
    }
    return {
        name: parse_module(name, path, module_name(path, root)[1], files, package_names)
        for name, path in files.items()
    }


def is_storybeam(target: str, packages: Iterable[str] = PACKAGES) -> bool:
    return target.split(".")[0] in set(packages)


def is_third_party(target: str, packages: Iterable[str] = PACKAGES) -> bool:
    top = target.split(".")[0]
    return bool(top) and top not in STDLIB and not is_storybeam(target, packages) and top != "tests"


def unit_of(module: str, units: Iterable[str] = UNITS) -> str | None:
    """The architecture node ``module`` belongs to (longest matching unit), or None."""
    best = None
    for unit in units:
        if module == unit or module.startswith(unit + "."):
            if best is None or len(unit) > len(best):
                best = unit
    return best


def runtime_imports(modules: Mapping[str, Module]) -> Iterable[Import]:
    """Module-level imports that execute when the module is imported (not TYPE_CHECKING)."""
    for module in modules.values():
        for imp in module.imports:
            if not imp.function_level and not imp.type_checking:
                yield imp


def module_graph(modules: Mapping[str, Module]) -> dict[str, set[str]]:
    """Module → the scanned modules it imports at module level (a package's ``__init__`` is
    the node named after the package)."""
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for imp in runtime_imports(modules):
        if imp.target in modules and imp.target != imp.importer:
            graph[imp.importer].add(imp.target)
    return graph


def unit_graph(modules: Mapping[str, Module], units: Iterable[str] = UNITS) -> dict[str, set[str]]:
    """Unit → the other units it imports at module level (the architecture diagram)."""
    units = tuple(units)
    graph: dict[str, set[str]] = {}
    for name in modules:
        unit = unit_of(name, units)
        if unit is not None:
            graph.setdefault(unit, set())
    for imp in runtime_imports(modules):
        source, target = unit_of(imp.importer, units), unit_of(imp.target, units)
        if source is not None and target is not None and source != target:
            graph[source].add(target)
    return graph


def find_cycle(graph: Mapping[str, Iterable[str]]) -> list[str] | None:
    """One cycle of ``graph`` as ``[a, b, ..., a]``, or None when it is acyclic (iterative
    depth-first search, nodes visited in sorted order so the answer is reproducible)."""
    WHITE, GREY, BLACK = 0, 1, 2
    colour = {node: WHITE for node in graph}
    for start in sorted(graph):
        if colour[start] != WHITE:
            continue
        stack: list[tuple[str, list[str]]] = [(start, sorted(graph.get(start, ())))]
        path = [start]
        colour[start] = GREY
        while stack:
            node, todo = stack[-1]
            if not todo:
                stack.pop()
                path.pop()
                colour[node] = BLACK
                continue
            nxt = todo.pop(0)
            state = colour.get(nxt, WHITE)
            if state == GREY:
                return path[path.index(nxt) :] + [nxt]
            if state == WHITE:
                colour[nxt] = GREY
                path.append(nxt)
                stack.append((nxt, sorted(graph.get(nxt, ()))))
    return None
