"""The scanned table, measured end to end on the synthetic rig (``storybeam bench surface``).

    storybeam bench surface [--json out/surface_bench.json] [--plot PNG] [--characters robot,kid]

1. **Scan**: the teacher's *Scan the table* step without a rig
   (:func:`app.services.table_scan.synthetic_scan`): the Gray-code sequence rendered on
   the synthetic table with its two boxes (45 mm and 20 mm), decoded, triangulated with
   the rig's true calibration, rasterised into a height map. Per box: median and 95th
   percentile height error over its top (5 mm in from the edges), the share of the top
   known; the table's own median height.
2. **Landing**: a story character walks a path over the 45 mm box on the projector stage
   (:class:`app.player.stage.StageRenderer`, synthetic rig, hand-held) with the scan, and
   again on the bare table. For every planted sole point well inside the box top, the
   foot is projected with the *tracked* projector pose (what the stage draws) and the
   true projector's ray through that pixel is intersected with the true box top: the
   landing error is the distance from there to the foot (:func:`landing_errors`).
3. **Edges**: the edges the character met on each path (the 45 mm box, jumped; the
   20 mm box, walked) and the clearance of the jumps over the box top.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from app.player.stage import StageRenderer
from app.services.table_scan import SYNTHETIC_BOXES, scan_captures, synthetic_scan
from app.story.model import Character, MotionChoice, Scene
from ar import DEFAULT_BOARD_SPEC, Board, HeightMap, invert, project_points
from ar.rig import SyntheticRig
from ar.scene import scene_ground, scene_to_board_points
from retrieval.animation import contacts, follow_surface, sole_points

#: Story-table paths (metres on the 1.2 x 0.8 m table, a point every 0.3 s) that the
#: stage's miniature lays straight over each synthetic box along board y:
#: over the 45 mm pencil case (board x = 0.185, y 0.05 -> 0.30) and over the 20 mm book
#: (board x = 0.05, y 0.05 -> 0.30).
PATHS = {
    "pencil case 45 mm": [(0.92143 - 0.89286 * k / 20, 0.09643, 0.3 * k) for k in range(21)],
    "book 20 mm": [(0.92143 - 0.89286 * k / 20, 0.57857, 0.3 * k) for k in range(21)],
}
INSET_M = 0.005


def box_top_mask(x: np.ndarray, y: np.ndarray, box: tuple, inset: float = INSET_M) -> np.ndarray:
    """Where board ``(x, y)`` is on ``box`` ``(x0, y0, x1, y1, height)``, ``inset`` in from its edges."""
    x0, y0, x1, y1, _h = box
    return (x > x0 + inset) & (x < x1 - inset) & (y > y0 + inset) & (y < y1 - inset)


def scan_errors(height_map: HeightMap, boxes=SYNTHETIC_BOXES) -> dict:
    """Height errors of a scan against the boxes' truth (module docstring, step 1)."""
    cx, cy = height_map.cell_centres()
    out = {}
    for box in boxes:
        top = box_top_mask(cx, cy, box)
        err = np.abs(height_map.heights[top & height_map.known] - box[4]) * 1000
        out[f"{box[4] * 1000:.0f} mm"] = {"median_mm": float(np.median(err)), "p95_mm": float(np.percentile(err, 95)),
                                          "known_fraction": float(height_map.known[top].mean())}
    off = np.ones(cx.shape, bool)
    for box in boxes:
        off &= ~box_top_mask(cx, cy, box, inset=-0.01)
    out["table"] = {"median_abs_mm": float(np.median(np.abs(height_map.heights[off & height_map.known])) * 1000)}
    return out


def landing_errors(stage: StageRenderer, rig: SyntheticRig, character: Character, box: tuple) -> dict:
    """Landing errors (metres) of the planted feet on ``box``'s top through ``stage``
    (module docstring, step 2): ``errors`` per sole point and the feet's ``heights``."""
    _design, motion = stage.animator.animate(character)
    soles, touch = sole_points(motion), contacts(motion)
    scene = Scene(characters=[character])
    errors, heights = [], []
    for f in range(motion.n_frames):
        board = scene_to_board_points(soles[f], stage.board)
        planted = touch[f] & box_top_mask(board[:, 0], board[:, 1], box)
        if not planted.any():
            continue
        frame = stage.render(scene, f / stage.fps)
        if frame.description is None:  # the rig lost the board: nothing is drawn
            continue
        view = frame.description.view
        board_from_proj = invert(rig.T_proj_from_cam @ rig.true_pose(rig._i - 1))
        for k in np.flatnonzero(planted):
            px = project_points(soles[f, k][None], view.T_view_from_scene, view.K, np.zeros(5))[0]
            ray = board_from_proj[:3, :3] @ np.linalg.solve(view.K, [px[0], px[1], 1.0])
            origin = board_from_proj[:3, 3]
            land = origin + ray * ((-box[4] - origin[2]) / ray[2])  # the true top: z = -height
            errors.append(float(np.linalg.norm(land[:2] - board[k, :2])))
            heights.append(float(-board[k, 2]))
    return {"errors": np.array(errors), "heights": np.array(heights)}


def _stats_mm(values: np.ndarray) -> dict:
    v = np.asarray(values) * 1000
    if not v.size:
        return {"n": 0}
    return {"n": int(v.size), "median_mm": float(np.median(v)), "p90_mm": float(np.percentile(v, 90)),
            "max_mm": float(v.max())}


def _edges(stage: StageRenderer, character: Character, height_map: HeightMap) -> tuple[list[dict], float, object]:
    """The edges met along the character's path on ``height_map`` and the jumps' clearance (m)."""
    saved, stage.animator.ground = stage.animator.ground, None
    try:
        _design, flat = stage.animator.animate(character)
    finally:
        stage.animator.ground = saved
    res = follow_surface(flat, scene_ground(height_map, stage.board))
    edges = [{"rise_mm": e.rise * 1000, "jump": e.jump, "frames": list(e.window)} for e in res.edges]
    clear = min((res.offset[e.window[0]:e.window[1] + 1].max() - max(res.ground[e.start], res.ground[e.end + 1])
                 for e in res.edges if e.jump), default=float("nan"))
    return edges, float(clear), res


def run_surface_bench(characters: tuple[str, ...] = ("robot",), plot: Path | None = None,
                      progress: Callable | None = None) -> dict:
    """Scan, landing and edges (module docstring); ``plot`` writes the figure there;
    ``progress(done, total)`` is called after each step."""
    total = 1 + 2 * len(characters)
    done = [0]

    def say() -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], total)
    board = Board(DEFAULT_BOARD_SPEC)
    captures, calibration = synthetic_scan(board)
    height_map = scan_captures(captures, calibration, board)
    result: dict = {"scan": scan_errors(height_map), "boxes": [list(b) for b in SYNTHETIC_BOXES],
                    "height_map": {"shape": list(height_map.shape), "cell_mm": height_map.cell_m * 1000,
                                   "known_fraction": height_map.known_fraction},
                    "landing": {}, "edges": {}}
    say()
    traces = {}
    for kind in characters:
        character = Character(kind=kind, path=PATHS["pencil case 45 mm"], motion=MotionChoice("walk"))
        row = {}
        for name, hm in (("scanned", height_map), ("bare table", None)):
            rig = SyntheticRig()
            stage = StageRenderer(rig=rig, draw=None, height_map=hm)
            try:
                got = landing_errors(stage, rig, character, SYNTHETIC_BOXES[0])
                if hm is not None:
                    for path_name, path in PATHS.items():
                        walker = Character(kind=kind, path=path, motion=MotionChoice("walk"))
                        edges, clearance, res = _edges(stage, walker, hm)
                        result["edges"][f"{kind}, {path_name}"] = {
                            "edges": edges, "jump_clearance_mm": None if np.isnan(clearance) else clearance * 1000}
                        traces[(kind, path_name)] = res
            finally:
                stage.close()
            row[name] = {"landing": _stats_mm(got["errors"]), "foot_height": _stats_mm(got["heights"])}
            say()
        result["landing"][kind] = row
    if plot is not None:
        result["plot"] = str(plot_surface(height_map, traces, plot, board))
    return result


def plot_surface(height_map: HeightMap, traces: dict, path: Path, board: Board) -> Path:
    """The scanned height map with the paths, and the root's height along each path."""
    import matplotlib  # optional: matplotlib, for the figure only
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # optional: as above

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 6.0), gridspec_kw={"width_ratios": [1, 1.6]})
    x0, x1, y0, y1 = height_map.extent
    shown = np.where(height_map.known, height_map.heights * 1000, np.nan)
    im = ax0.imshow(shown, origin="upper", extent=(x0 * 100, x1 * 100, y1 * 100, y0 * 100), cmap="viridis")
    fig.colorbar(im, ax=ax0, label="height above the board (mm); white: not seen")
    ax0.set(xlabel="board x (cm)", ylabel="board y (cm)", title="scanned table (synthetic scan)")
    for (kind, name), res in traces.items():
        m = res.motion
        root = scene_to_board_points(m.root_translation * m.skeleton.metres_per_unit, board)
        ax0.plot(root[:, 0] * 100, root[:, 1] * 100, lw=1.2, label=f"{kind}: {name}")
        ax1.plot(root[:, 1] * 100, res.offset * 1000, lw=1.5, label=f"{kind}, {name}: root lift")
        ax1.plot(root[:, 1] * 100, res.ground * 1000, lw=0.8, ls="--", label=f"{kind}, {name}: ground under the feet")
    ax0.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    ax1.set(xlabel="board y along the path (cm)", ylabel="mm above the board",
            title="character lifted onto the surface (jump > 40 mm, step <= 40 mm)")
    ax1.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def format_summary(result: dict) -> str:
    """The bench's table."""
    lines = ["scan (synthetic Gray-code, true calibration)", "  box     median err  p95 err  top known"]
    for name, row in result["scan"].items():
        if name == "table":
            continue
        lines.append(f"  {name:7s} {row['median_mm']:8.2f} mm {row['p95_mm']:6.2f} mm {100 * row['known_fraction']:7.0f} %")
    lines.append(f"  table   median |height| {result['scan']['table']['median_abs_mm']:.2f} mm")
    lines.append("landing of planted feet on the 45 mm box top (projector view, tracked pose vs truth)")
    lines.append("  character  table        n   median    p90      max   foot height median")
    for kind, rows in result["landing"].items():
        for name, row in rows.items():
            la, fh = row["landing"], row["foot_height"]
            if not la.get("n"):
                lines.append(f"  {kind:10s} {name:11s} no planted feet on the box")
                continue
            lines.append(f"  {kind:10s} {name:11s} {la['n']:3d} {la['median_mm']:6.2f} mm {la['p90_mm']:6.2f} mm "
                         f"{la['max_mm']:6.2f} mm   {fh['median_mm']:6.2f} mm")
    lines.append("edges met along each path (rise mm, jumped?) and the jumps' clearance over the top")
    for name, row in result["edges"].items():
        edges = ", ".join(f"{e['rise_mm']:+.0f} {'jump' if e['jump'] else 'walk'}" for e in row["edges"])
        clear = row["jump_clearance_mm"]
        lines.append(f"  {name}: {edges or 'none'}" + (f"; jumps clear the top by {clear:.1f} mm" if clear else ""))
    return "\n".join(lines)


__all__ = ["PATHS", "box_top_mask", "scan_errors", "landing_errors", "run_surface_bench", "plot_surface",
           "format_summary"]
