"""Draw StoryBeam's layers from its real imports (a developer tool).

Usage::

    .venv/bin/python scripts/draw_architecture.py [--no-png]

Method: the static import scan of ``tests/support/imports.py`` (the one
``tests/test_layering.py`` enforces the rules with) gives, for every package-level node
(``retrieval.motion``, ``ar.render``, ``app.story``, ...), the nodes its modules import. The
script writes

* a Mermaid ``flowchart`` into ``docs/design/architecture.md`` between
  ``<!-- BEGIN GENERATED: layers -->`` and ``<!-- END GENERATED -->``: an arrow ``A --> B``
  when a module of A imports one of B at module level, dotted (``A -.-> B``) when A
  imports B only inside functions; arrows into ``retrieval.errors``, which every layer may
  use, are left out;
* ``docs/img/architecture.png``: the same graph drawn with matplotlib in layers, bottom
  (imports nothing of StoryBeam) to top, one column per top-level package; arrows implied
  by a chain of others are left out of the picture to keep it legible.

``tests/test_layering.py::test_architecture_diagram_is_current`` fails when the Mermaid
block no longer matches the imports.
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from tests.support.imports import UNITS, Module, scan, unit_of  # noqa: E402

DOC = REPO / "docs" / "design" / "architecture.md"
PNG = REPO / "docs" / "img" / "architecture.png"
BEGIN = "<!-- BEGIN GENERATED: layers -->"
END = "<!-- END GENERATED -->"

#: Not drawn as arrows: every layer may import it (said in a note instead).
SHARED = "retrieval.errors"
#: Imports the scan cannot see (made with importlib): (from, to, label).
DYNAMIC_EDGES = (("app.cli", "app.commands", "importlib"),)
#: Package docstrings only: no node unless something imports them.
EMPTY_ROOTS = ("retrieval", "app", "lab")


def edges(modules: Mapping[str, Module]) -> dict[tuple[str, str], bool]:
    """(importer unit, imported unit) → True when some import is at module level, False
    when all are inside functions."""
    out: dict[tuple[str, str], bool] = {}
    for module in modules.values():
        source = unit_of(module.name)
        for imp in module.imports:
            target = unit_of(imp.target)
            if source is None or target is None or source == target or target == SHARED or imp.type_checking:
                continue
            out[(source, target)] = out.get((source, target), False) or not imp.function_level
    return out


def nodes(modules: Mapping[str, Module], graph: Mapping[tuple[str, str], bool]) -> list[str]:
    present = {unit_of(name) for name in modules} - {None}
    used = {u for edge in graph for u in edge} | {SHARED}
    return [u for u in UNITS if u in present and (u not in EMPTY_ROOTS or u in used)]


def layers(names: list[str], graph: Mapping[tuple[str, str], bool]) -> dict[str, int]:
    """Longest-path layering: a node sits one above the highest node it imports."""
    deps = {n: {b for (a, b) in graph if a == n and b in names} for n in names}
    for a, b, _label in DYNAMIC_EDGES:
        if a in deps and b in names:
            deps[a].add(b)
    level: dict[str, int] = {}

    def depth(node: str, trail: tuple[str, ...] = ()) -> int:
        if node in level:
            return level[node]
        if node in trail:  # a cycle between units: keep going, the test reports it
            return 0
        level[node] = 1 + max((depth(d, trail + (node,)) for d in deps[node]), default=-1)
        return level[node]

    for node in names:
        depth(node)
    return level


def reduced(graph: Mapping[tuple[str, str], bool]) -> dict[tuple[str, str], bool]:
    """The transitive reduction of an acyclic ``graph``: drop A → B when A reaches B through
    another node as well (for the drawing only; the Mermaid block lists every arrow)."""
    succ: dict[str, set[str]] = {}
    for a, b in graph:
        succ.setdefault(a, set()).add(b)

    def reaches(start: str, goal: str, skip: tuple[str, str]) -> bool:
        seen, todo = set(), [start]
        while todo:
            node = todo.pop()
            for nxt in succ.get(node, ()):
                if (node, nxt) == skip or nxt in seen:
                    continue
                if nxt == goal:
                    return True
                seen.add(nxt)
                todo.append(nxt)
        return False

    return {edge: style for edge, style in graph.items() if not reaches(edge[0], edge[1], edge)}


def _id(unit: str) -> str:
    return unit.replace(".", "_")


def mermaid(modules: Mapping[str, Module]) -> str:
    """The generated block (without the markers): a fenced Mermaid flowchart."""
    graph = edges(modules)
    names = nodes(modules, graph)
    lines = ["```mermaid", "flowchart BT"]
    for top in ("retrieval", "ar", "app", "lab"):
        members = [n for n in names if n.split(".")[0] == top]
        if not members:
            continue
        lines.append(f"  subgraph {top}_layer[\"{top}/\"]")
        lines.extend(f"    {_id(n)}[\"{n}\"]" for n in members)
        lines.append("  end")
    for (a, b), module_level in sorted(graph.items()):
        if a in names and b in names:
            lines.append(f"  {_id(a)} {'-->' if module_level else '-.->'} {_id(b)}")
    for a, b, label in DYNAMIC_EDGES:
        if a in names and b in names:
            lines.append(f"  {_id(a)} -. {label} .-> {_id(b)}")
    lines.append("```")
    lines.append("")
    lines.append(
        f"Solid: imported at module level; dotted: only inside functions (optional or deferred "
        f"imports). Every layer may import `{SHARED}`; those arrows are not drawn."
    )
    return "\n".join(lines)


def update_document(text: str, block: str) -> str:
    """``text`` with everything between the markers replaced by ``block``."""
    head, sep, rest = text.partition(BEGIN)
    if not sep or END not in rest:
        raise SystemExit(f"{DOC}: the markers {BEGIN} ... {END} are missing")
    _old, _sep, tail = rest.partition(END)
    return f"{head}{BEGIN}\n{block}\n{END}{tail}"


def draw_png(modules: Mapping[str, Module], path: Path = PNG) -> None:
    """The layered drawing: rows by layer, columns by top-level package, the transitive
    reduction of the arrows, retrieval.errors as a bar under everything."""
    import matplotlib  # optional: matplotlib (only this developer tool draws)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # optional: matplotlib
    from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # optional: matplotlib

    graph = edges(modules)
    names = [n for n in nodes(modules, graph) if n != SHARED]
    level = layers(names, graph)
    full = dict(graph)
    for a, b, _label in DYNAMIC_EDGES:
        full.setdefault((a, b), True)
    drawn = reduced(full)
    tops = ("retrieval", "ar", "app", "lab")
    fill = {"retrieval": "#dbe9f6", "ar": "#e3f1dc", "app": "#fbe5cf", "lab": "#ece4f5"}
    ink = {"retrieval": "#2b6cb0", "ar": "#2f855a", "app": "#c05621", "lab": "#6b46c1"}
    box_w, box_h, gap = 1.55, 0.44, 0.25
    # each column is as wide as its widest row
    spans, x0 = {}, 0.0
    for top in tops:
        rows = [sum(1 for n in names if n.split(".")[0] == top and level[n] == lvl) for lvl in set(level.values())]
        w = max(rows) * (box_w + gap)
        spans[top] = (x0, x0 + w)
        x0 += w + 0.6
    pos: dict[str, tuple[float, float]] = {}
    for top in tops:
        lo, hi = spans[top]
        for lvl in sorted({level[n] for n in names if n.split(".")[0] == top}):
            row = [n for n in names if n.split(".")[0] == top and level[n] == lvl]
            for i, n in enumerate(row):
                pos[n] = (lo + (hi - lo) * (i + 0.5) / len(row), float(lvl))
    top_level = max(level.values())
    fig, ax = plt.subplots(figsize=(x0 * 1.25, (top_level + 3) * 0.85), dpi=110)
    for (a, b), module_level in sorted(drawn.items()):
        if a not in pos or b not in pos:
            continue
        (xa, ya), (xb, yb) = pos[a], pos[b]
        dynamic = any((a, b) == (p, q) for p, q, _l in DYNAMIC_EDGES)
        rad = 0.25 if abs(xa - xb) < 0.3 and ya - yb > 1.5 else 0.0
        ax.add_patch(
            FancyArrowPatch(
                (xa, ya - box_h / 2), (xb, yb + box_h / 2),
                arrowstyle="-|>", mutation_scale=11, lw=1.2,
                color="grey" if dynamic else ink[a.split(".")[0]], alpha=0.75,
                linestyle="-" if module_level and not dynamic else (0, (3, 2)),
                connectionstyle=f"arc3,rad={rad}", shrinkA=0, shrinkB=1, zorder=2,
            )
        )
        if dynamic:
            ax.text(xa + 0.08, (ya + yb) / 2, "importlib", fontsize=7, color="grey", va="center")
    for n, (x, y) in pos.items():
        top = n.split(".")[0]
        ax.add_patch(
            FancyBboxPatch((x - box_w / 2, y - box_h / 2), box_w, box_h, boxstyle="round,pad=0.02,rounding_size=0.08",
                           facecolor=fill[top], edgecolor=ink[top], lw=1.3, zorder=3)
        )
        ax.text(x, y, n, ha="center", va="center", fontsize=10, zorder=4)
    # the shared errors module, under everything
    ax.add_patch(
        FancyBboxPatch((-0.2, -1.0 - box_h / 2), x0 - 0.4, box_h, boxstyle="round,pad=0.02,rounding_size=0.08",
                       facecolor="#eeeeee", edgecolor="#777777", lw=1.0, zorder=3)
    )
    ax.text((x0 - 0.6) / 2, -1.0, f"{SHARED}: the StoryBeamError hierarchy, which every layer may import",
            ha="center", va="center", fontsize=10, zorder=4)
    for top, (lo, hi) in spans.items():
        ax.text((lo + hi) / 2, top_level + 0.8, f"{top}/", ha="center", va="center", fontsize=14,
                weight="bold", color=ink[top])
    ax.text(-0.2, -1.75,
            "A → B: a module of A imports one of B (dashed: only inside functions). Arrows implied by a chain "
            "of others are omitted; docs/design/architecture.md lists them all. Drawn by scripts/draw_architecture.py.",
            fontsize=8, color="#444444", va="center")
    ax.set_xlim(-0.3, x0 - 0.5)
    ax.set_ylim(-2.0, top_level + 1.1)
    ax.axis("off")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-png", action="store_true", help="update docs/design/architecture.md only")
    args = parser.parse_args(argv)
    modules = scan()
    text = DOC.read_text(encoding="utf-8")
    new = update_document(text, mermaid(modules))
    if new != text:
        DOC.write_text(new, encoding="utf-8")
        print(f"updated {DOC.relative_to(REPO)}")
    else:
        print(f"{DOC.relative_to(REPO)} already current")
    if not args.no_png:
        draw_png(modules)
        print(f"wrote {PNG.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
