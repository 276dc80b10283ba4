import sys; sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
from harness import REPO, get_search, features, report
from retrieval.library.act_search import ActSearch
full = get_search(); app = ActSearch.build(REPO / "assets" / "motions")
F = features(full)
def fr(h, c, d): return next((i for i, m in enumerate(h) if m.label == c), d)
P_full = {k: full.search_features(f, k=3)[0].label for k, (l, f) in F.items()}
P_app = {k: app.search_features(f, k=3)[0].label for k, (l, f) in F.items()}
report("full", P_full, F); report("app", P_app, F)
for d in (3, 5):
    P = {}
    for k, (l, f) in F.items():
        a = full.search_features(f, k=d); b = app.search_features(f, k=d)
        labs = {m.label for m in a + b}
        P[k] = min(labs, key=lambda c: (fr(a, c, d) + fr(b, c, d), fr(a, c, d)))
    report(f"full+app rank d{d}", P, F)
