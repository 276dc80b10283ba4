"""Print Markdown tables from `storybeam eval --json` files (used for docs/notebook/results.md).

Usage: .venv/bin/python scripts/results_tables.py out/final/eval120.json [more.json ...]
"""
from __future__ import annotations

import json
import sys


def main(paths: list[str]) -> None:
    for path in paths:
        d = json.load(open(path))
        names = list(d["methods"])
        m = d["methods"]
        title = (f"{d['n_clips']} clips ({d['total_seconds']:.0f} s) at {d['fps']:g} fps, {d['folds']}-fold, "
                 f"n = {d['dims']}, back-end {d.get('backend', 'auto')}")
        print(f"**{title}** — `{path}`\n")
        print("| | " + " | ".join(names) + " |")
        print("|---|" + "---|" * len(names))
        rows = [
            ("search time, wall (s)", lambda r: f"{r['search_seconds']:.3f}"),
            ("search time, CPU (s)", lambda r: f"{r.get('search_cpu_seconds', float('nan')):.3f}"),
            ("ns per DTW cell (wall)", lambda r: f"{r['ns_per_cell']:.2f}"),
            ("build time, wall (s)", lambda r: f"{r['build_seconds']:.3f}"),
            ("accuracy (%)", lambda r: f"{100 * r['accuracy']:.3f}"),
            ("balanced accuracy (%)", lambda r: f"{100 * r['balanced_accuracy']:.3f}"),
        ]
        for label, fmt in rows:
            print(f"| {label} | " + " | ".join(fmt(m[n]) for n in names) + " |")
        for c in sorted(next(iter(m.values()))["per_class"]):
            print(f"| {c} (%) | " + " | ".join(f"{100 * m[n]['per_class'].get(c, 0):.1f}" for n in names) + " |")
        if "dtw_over_quantized_search_time" in d:
            print(f"\nexact DTW / quantised search time: {d['dtw_over_quantized_search_time']:.1f}× wall, "
                  f"{d['dtw_over_quantized_search_cpu_time']:.1f}× CPU. Classes: {d.get('classes')}")
        if "sweep" in d:
            print("\n| n | accuracy (%) | balanced (%) | search wall (s) | ns/cell | cumulative contribution (%) | table |")
            print("|---|---|---|---|---|---|---|")
            for r in d["sweep"]:
                print(f"| {r['dims']} | {100 * r['accuracy']:.2f} | {100 * r['balanced_accuracy']:.2f} | "
                      f"{r['search_seconds']:.2f} | {r['ns_per_cell']:.2f} | {100 * r['cumulative_ratio']:.1f} | "
                      f"{r['table']}, {r['table_bytes'] / 2**20:.2f} MiB |")
        print()


if __name__ == "__main__":
    main(sys.argv[1:])
