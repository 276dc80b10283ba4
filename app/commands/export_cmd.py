"""``storybeam export STORY.json OUT.mp4``: a saved story as an H.264 MP4.

    storybeam export STORY.json OUT.mp4 [--view story|camera|overhead|projector|2d] [--fps N]
                                        [--size WxH] [--progress-lines]

The story file is a ``Story.to_dict`` JSON document (what the app exports and what
:func:`app.player.export_in_subprocess` hands this command). The 3-D views render the
characters through pyrender: ``story`` (the default) is the film a child takes home --
title card, each scene's place with the characters large on their paths, ending card,
1280x720 at 30 fps unless ``--size``/``--fps`` say otherwise; the others are the rig's
views (15 fps unless ``--fps``). Where 3-D cannot run, the video is the top-down 2-D
animation and the result's note says why. The app runs this command in a child process
with ``--progress-lines``: it then prints ``progress DONE TOTAL`` after every frame
instead of a progress bar, and in every case ends with one ``result {json}`` line
(``path``, ``mode``, ``frames``, ``note``). ``--narration-dir DIR``: the folder of the
story's assets, so narrated scenes are heard in the video (``storybeam export-video``,
:mod:`app.commands.export_video_cmd`, does the same for the demo story and one file).
"""
from __future__ import annotations

import argparse
import json

from app.progress import progress_bar

#: The views of app.player.video_export.VIEWS, repeated here so that `storybeam --help`
#: does not load the scene layer (tests/app/test_cli.py keeps the two equal).
VIEWS = ("story", "camera", "overhead", "projector", "2d")


def video_size(text: str) -> tuple[int, int]:
    """``WxH`` -> (W, H), for ``--size`` (argparse reports a bad value with the option's name)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT (e.g. 1280x720)") from None
    if w < 64 or h < 48 or w % 2 or h % 2 or w > 3840 or h > 2160:
        raise argparse.ArgumentTypeError(f"{text!r}: width and height must be even, from 64x48 to 3840x2160")
    return w, h


def add_video_options(p: argparse.ArgumentParser) -> None:
    """--view, --fps and --size, shared with ``storybeam export-video``."""
    p.add_argument("--view", choices=VIEWS, default="story",
                   help="story (default: the film a child takes home), camera, overhead or projector "
                        "(the rig's 3-D views), or the top-down 2d animation")
    p.add_argument("--fps", type=float, default=None, help="frames per second (default 30 for story, else 15)")
    p.add_argument("--size", type=video_size, default=None, metavar="WxH",
                   help="the story film's size (default 1280x720)")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("export", help="write a saved story (JSON) as an MP4 video",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("story_json", metavar="STORY.json", help="the story, as Story.to_dict JSON")
    p.add_argument("out", metavar="OUT.mp4", help="the video to write")
    add_video_options(p)
    p.add_argument("--progress-lines", action="store_true",
                   help="print 'progress DONE TOTAL' lines instead of a progress bar (for the app)")
    p.add_argument("--narration-dir", metavar="DIR", default=None,
                   help="the folder of the story's assets: narrated scenes get their voice in the video")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read the story (a clear error naming the file if it is not a story), render every
    frame with :func:`app.player.export_story_mp4`, report progress, print the result line."""
    from app.player import default_fps, export_story_mp4, frame_count, read_story  # deferred: the scene layer (numpy, imageio, 3-D) only for this command

    story = read_story(args.story_json)
    total = frame_count(story, args.fps or default_fps(args.view), args.view)
    bar = None if args.progress_lines else progress_bar("export", "frame")

    def progress(i: int) -> None:
        if bar is None:
            print(f"progress {i + 1} {total}", flush=True)
        else:
            bar(i + 1, total)

    result = export_story_mp4(story, args.out, args.fps, progress, args.view, args.narration_dir, args.size)
    print("result " + json.dumps({"path": str(result.path), "mode": result.mode, "frames": result.frames,
                                  "note": result.note}), flush=True)
    return 0

