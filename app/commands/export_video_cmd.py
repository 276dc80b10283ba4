"""``storybeam export-video --demo-story --narration AUDIO --out OUT.mp4``: the demo story
as an MP4 with a voice.

    storybeam export-video --demo-story [--narration AUDIO] --out OUT.mp4
                           [--view story|camera|overhead|projector|2d] [--fps N] [--size WxH]

AUDIO (WAV or OGG) is checked exactly like a file a child imports in the app
(:func:`app.story.read_audio`: size, format, rate, length, damage, silence -- a refused
file is named with the reason and nothing is written), stored as the demo story's first
scene's narration in a temporary asset folder, and muxed into the video
(:func:`app.player.export_story_mp4`): the audio stream lasts exactly as long as the video.
The default view is the story film (title card, the places and characters, ending card).
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from app.commands.export_cmd import add_video_options
from app.progress import progress_bar


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("export-video", help="write the demo story as an MP4 with a narration",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--demo-story", action="store_true", required=True, help="export the bundled demo story")
    p.add_argument("--narration", metavar="AUDIO", default=None, help="a WAV or OGG file: the first scene's voice")
    p.add_argument("--out", metavar="OUT.mp4", required=True, help="the video to write")
    add_video_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Check AUDIO, attach it to the demo story's first scene, export, print the result."""
    from app.player import default_fps, export_story_mp4, frame_count  # deferred: the scene layer only for this command
    from app.story import Narration, demo_story, encode_wav, read_audio  # deferred: the story layer only here
    from app.story.narration import asset_name  # deferred: the story layer only for this command

    story = demo_story()
    with tempfile.TemporaryDirectory(prefix="storybeam-narration-") as folder:
        if args.narration:
            audio = read_audio(args.narration)
            wav = encode_wav(audio)
            name = asset_name(wav)
            (Path(folder) / name).write_bytes(wav)
            story.scenes[0].narration = Narration(name, round(audio.seconds, 6))
        total = frame_count(story, args.fps or default_fps(args.view), args.view)
        bar = progress_bar("export", "frame")
        result = export_story_mp4(story, args.out, args.fps, lambda i: bar(i + 1, total), args.view, folder, args.size)
    voice = f", narration {args.narration} ({story.scenes[0].narration.seconds:.2f} s)" if args.narration else ""
    print(f"wrote {result} -- {story.duration:.2f} s{voice}")
    return 0
