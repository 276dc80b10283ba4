"""`storybeam board`: write a printable tracking/calibration board at true physical size."""
from __future__ import annotations

import argparse
from pathlib import Path

from retrieval.errors import StoryBeamError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "board", help="write a printable board (PNG/PDF at true size)", description=__doc__,
        epilog="Specs: charuco:5x7:0.04:0.02:DICT_6X6_250 (squares, square m, marker m, dictionary; default), "
               "grid:4x5:0.04:0.01:DICT_4X4_50 (markers, marker m, gap m, dictionary), "
               "checker:9x6:0.025 (INNER corners, square m). Print at 100 %% and check one square with a ruler.")
    p.add_argument("--board", default=None, help="board spec (default: the ChArUco default board)")
    p.add_argument("--out", type=Path, required=True, help="output file, .pdf or .png")
    p.add_argument("--dpi", type=int, default=300, help="print resolution (default 300)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ar.boards import DEFAULT_BOARD_SPEC, Board, write_board  # deferred: OpenCV loads only for this command

    if not 72 <= args.dpi <= 1200:
        raise StoryBeamError(f"--dpi must be between 72 and 1200, got {args.dpi}")
    board = Board(args.board or DEFAULT_BOARD_SPEC)
    if board.spec.kind == "checker" and (board.spec.cols + board.spec.rows) % 2 == 0:
        print(f"warning: {board.spec} is 180-degree symmetric (inner-corner counts add up to an even number); "
              "its orientation is ambiguous -- prefer odd x even, e.g. checker:9x6:...")
    out = write_board(board, args.out, args.dpi)
    w, h = board.sheet_size_m
    print(f"wrote {out}: {board.spec}, sheet {w * 1000:.0f} x {h * 1000:.0f} mm "
          f"(pattern {board.pattern_size_m[0] * 1000:.0f} x {board.pattern_size_m[1] * 1000:.0f} mm); print at 100 %")
    return 0
