"""Scratch: hands weight sweep over the dev studios (storybeam, random+subject)."""
import sys
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[4]))
from retrieval.features import register_feature_set, storybeam_feature_set
from app.cli import build_parser
w = float(sys.argv[1]); data = sys.argv[2]; out = sys.argv[3]; extra = sys.argv[4:]
name = "storybeam-no-hands" if w == 0 else f"sbh{w:g}"
if w:  # hands at w; since 2026-11-29 the set leaves them out of the codes (coded=18)
    register_feature_set(storybeam_feature_set(name=name, hands_weight=w))
args = build_parser().parse_args(["eval", "--data", data, "--methods", "storybeam,dtw-storybeam", "--split", "random,subject",
                                  "--quiet", "--json", out] + extra)
args.features = name
rc = args.func(args)
