"""Identity ("find this clip") shortlist variants, through `storybeam eval --identity`."""
import sys, io, contextlib, re, os
sys.path.insert(0, "/work/main")
os.chdir("/work/main")
from retrieval.library import storybeam_search as S
from app import cli

ORIG = S.StoryBeamSearcher.identity_searcher

def variant(shortlist_extra, summary):
    def identity_searcher(self):
        if self._identity is None:
            self._identity = S.StoryBeamSearcher.fit([S.centre(f) for f in self.features], self.quantizer.n,
                                                     self.shortlist + shortlist_extra, self.band, self.backend,
                                                     self.mode, summary=summary)
        return self._identity
    return identity_searcher

folders = sys.argv[2].split(",")
for spec in sys.argv[1].split(","):
    extra, summ = map(int, spec.split("/"))
    S.StoryBeamSearcher.identity_searcher = variant(extra, summ)
    res = []
    for f in folders:
        args = ["eval", "--data", "../shared/data/cmu", "--identity", "--quiet"]
        if f != "roundtrip":
            args += ["--skeleton-from", f]
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            cli.main(args)
        line = [l for l in buf.getvalue().splitlines() if "find" in l][0]
        m = re.search(r"find (\d+)/(\d+)", line) or re.search(r"find ([\d.]+) %", line)
        miss = [l.strip() for l in buf.getvalue().splitlines() if "misses" in l]
        res.append(f"{os.path.basename(f)} {m.group(0)} {' '.join(miss)}")
    print(f"shortlist +{extra}, summary {summ}: " + " | ".join(res), flush=True)
