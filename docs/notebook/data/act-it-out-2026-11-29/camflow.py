"""Per clip: the camera's own motion, from background corners tracked frame to frame (person masked)."""
import sys, glob, csv
import numpy as np, cv2
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[4]))
from lab.bench.act_videos import pose_code_key
key = pose_code_key()
rows = list(csv.DictReader(open("/work/data/act_real/labels.csv")))
for r in rows:
    stem = r["file"][:-4]
    f = sorted(glob.glob(f"/work/data/act_real_cache/videos/{stem}-*-{key}.npz"))[-1]
    z = np.load(f); xy = z["image_xy"]; valid = z["valid"]
    cap = cv2.VideoCapture(f"/work/data/act_real/{r['file']}")
    prev = pmask = None; shifts = []; t = 0
    while True:
        ok, im = cap.read()
        if not ok: break
        g = cv2.cvtColor(im, cv2.COLOR_BGR2GRAY)
        s = 480 / max(g.shape); g = cv2.resize(g, None, fx=s, fy=s)
        mask = np.full(g.shape, 255, np.uint8)
        if t < len(valid) and valid[t]:
            p = xy[t] * s; x0, y0 = np.maximum(p.min(0) - 30, 0).astype(int); x1, y1 = (p.max(0) + 30).astype(int)
            mask[y0:y1, x0:x1] = 0
        if prev is not None:
            pts = cv2.goodFeaturesToTrack(prev, 150, 0.01, 8, mask=pmask)
            if pts is not None and len(pts) > 10:
                nxt, st, _ = cv2.calcOpticalFlowPyrLK(prev, g, pts, None)
                d = (nxt - pts)[st[:, 0] == 1, 0]
                shifts.append(np.median(d, axis=0) / s if len(d) > 5 else np.zeros(2))
            else:
                shifts.append(np.zeros(2))
        prev, pmask = g, mask; t += 1
    sh = np.array(shifts) if shifts else np.zeros((1, 2))
    np.save(f"{sys.argv[1]}/{stem}.npy", np.vstack([np.zeros((1, 2)), sh]))
    w = im.shape[1] if im is not None else 1
    tot = np.abs(np.cumsum(sh, 0)).max(0) if len(sh) else np.zeros(2)
    print(f"{stem:8s} frames {t:4d} median |shift| {np.median(np.linalg.norm(sh,axis=1)):.2f} px  max cumulative x,y {tot.round(0)} px of width {xy[valid][:, :, 0].max() if valid.any() else 0:.0f}")
