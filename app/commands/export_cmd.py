"""``storybeam export STORY.json OUT.mp4``: a saved story as an H.264 MP4.

    storybeam export STORY.json OUT.mp4 [--view camera|overhead|projector|2d] [--fps 15]
                                        [--progress-lines]

The story file is a ``Story.to_dict`` JSON document (what the app exports and what
:func:`app.player.export_in_subprocess` hands this command). The 3-D views render the
characters through pyrender; where that cannot run, the video is the top-down 2-D
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
VIEWS = ("camera", "overhead", "projector", "2d")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("export", help="write a saved story (JSON) as an MP4 video",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("story_json", metavar="STORY.json", help="the story, as Story.to_dict JSON")
    p.add_argument("out", metavar="OUT.mp4", help="the video to write")
    p.add_argument("--view", choices=VIEWS, default="camera",
                   help="camera (default), overhead or projector (3-D), or the top-down 2d animation")
    p.add_argument("--fps", type=float, default=15.0, help="frames per second (default 15)")
    p.add_argument("--progress-lines", action="store_true",
                   help="print 'progress DONE TOTAL' lines instead of a progress bar (for the app)")
    p.add_argument("--narration-dir", metavar="DIR", default=None,
                   help="the folder of the story's assets: narrated scenes get their voice in the video")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read the story (a clear error naming the file if it is not a story), render every
    frame with :func:`app.player.export_story_mp4`, report progress, print the result line."""
    from app.player import export_story_mp4, frame_count, read_story  # deferred: the scene layer (numpy, imageio, 3-D) only for this command

    story = read_story(args.story_json)
    total = frame_count(story, args.fps)
    bar = None if args.progress_lines else progress_bar("export", "frame")

    def progress(i: int) -> None:
        if bar is None:
            print(f"progress {i + 1} {total}", flush=True)
        else:
            bar(i + 1, total)

    result = export_story_mp4(story, args.out, args.fps, progress, args.view, args.narration_dir)
    print("result " + json.dumps({"path": str(result.path), "mode": result.mode, "frames": result.frames,
                                  "note": result.note}), flush=True)
    return 0

