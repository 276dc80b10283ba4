"""Time drawing + reading back the parity cases' projector views with Kivy GL or pyrender.

    taskset -c 0 env LP_NUM_THREADS=1 SDL_VIDEODRIVER=offscreen .venv/bin/python \
        scripts/time_scene_renderers.py kivy-gl|pyrender

Prints one JSON line: renderer, frames, median and p95 milliseconds per 640x480 frame.
Each renderer runs in its own process (Kivy keeps one window per process); run both
back to back to compare them under the same load.
"""
import sys, time, json
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1]))
import numpy as np
which = sys.argv[1]
if which == "kivy-gl":
    from app.ui.env import prepare_kivy_env
    prepare_kivy_env(headless=True, width=320, height=240)
    from kivy.core.window import Window  # noqa
    from app.ui.gl import KivyGLRenderer
    r = KivyGLRenderer(); draw = r.render
else:
    from ar.render import PyrenderSceneRenderer
    r = PyrenderSceneRenderer(); draw = r.render
from tests.support.gl_parity import parity_cases
cases = [c for c in parity_cases() if c[2] == "projector"]
for _n, _k, _v, d in cases[:3]:
    draw(d)
ts = []
for _n, _k, _v, d in cases:
    t = time.perf_counter(); draw(d); ts.append((time.perf_counter() - t) * 1e3)
print(json.dumps({"renderer": which, "frames": len(ts), "median_ms": round(float(np.median(ts)), 2), "p95_ms": round(float(np.percentile(ts, 95)), 2)}))
