"""Throwaway: DeepMimic humanoid3d motions -> BVH (our Motion model) for a feasibility bench."""
import json, subprocess, sys, numpy as np
from pathlib import Path
sys.path.insert(0, '/work/main')
from retrieval.motion import Joint, Skeleton, Motion
from retrieval.library.bundle import write_clip
GIT = '/work/.mirror/xbpeng+DeepMimic/repo'
# name, parent, offset (m), kind: 'root' | 'sph' | 'rev' | 'end'
J = [('root', -1, (0, 0, 0), 'root'), ('chest', 0, (0, 0.236151, 0), 'sph'), ('neck', 1, (0, 0.223894, 0), 'sph'),
     ('head', 2, (0, 0.175, 0), 'end'),
     ('right_hip', 0, (0, 0, 0.084887), 'sph'), ('right_knee', 4, (0, -0.421546, 0), 'rev'), ('right_ankle', 5, (0, -0.40987, 0), 'sph'),
     ('right_toe', 6, (0.1335, -0.05, 0), 'end'),
     ('right_shoulder', 1, (-0.02405, 0.2435, 0.18311), 'sph'), ('right_elbow', 8, (0, -0.274788, 0), 'rev'), ('right_wrist', 9, (0, -0.258947, 0), 'end'),
     ('left_hip', 0, (0, 0, -0.084887), 'sph'), ('left_knee', 11, (0, -0.421546, 0), 'rev'), ('left_ankle', 12, (0, -0.40987, 0), 'sph'),
     ('left_toe', 13, (0.1335, -0.05, 0), 'end'),
     ('left_shoulder', 1, (-0.02405, 0.2435, -0.18311), 'sph'), ('left_elbow', 15, (0, -0.274788, 0), 'rev'), ('left_wrist', 16, (0, -0.258947, 0), 'end')]
# order of the values in a frame after duration and root position
ORDER = ['root', 'chest', 'neck', 'right_hip', 'right_knee', 'right_ankle', 'right_shoulder', 'right_elbow',
         'left_hip', 'left_knee', 'left_ankle', 'left_shoulder', 'left_elbow']
def qmat(w, x, y, z):
    n = np.sqrt(w*w+x*x+y*y+z*z); w, x, y, z = w/n, x/n, y/n, z/n
    return np.array([[1-2*(y*y+z*z), 2*(x*y-z*w), 2*(x*z+y*w)], [2*(x*y+z*w), 1-2*(x*x+z*z), 2*(y*z-x*w)], [2*(x*z-y*w), 2*(y*z+x*w), 1-2*(x*x+y*y)]])
def rz(a):
    c, s = np.cos(a), np.sin(a); return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
def load(text, name):
    d = json.loads(text); F = np.array(d['Frames'], float)
    joints = [Joint(n, p, np.array(o, float), (['Xposition','Yposition','Zposition'] if k == 'root' else []) + ['Zrotation','Yrotation','Xrotation'], 'ZYX') for n, p, o, k in J]
    tips = {'head': (0, 0.1, 0), 'right_wrist': (0, -0.08, 0), 'left_wrist': (0, -0.08, 0), 'right_toe': (0.05, 0, 0), 'left_toe': (0.05, 0, 0)}
    ends = [Joint(n + '_tip', [j.name for j in joints].index(n), np.array(o, float), [], 'ZYX') for n, o in tips.items()]
    joints = joints + ends
    sk = Skeleton(joints, metres_per_unit=1.0, up_axis='y', name='deepmimic-humanoid3d')
    T = len(F); R = np.tile(np.eye(3), (T, len(joints), 1, 1)); idx = {n: i for i, (n, *_ ) in enumerate(J)}
    kinds = {n: k for n, _, _, k in J}
    for t in range(T):
        c = 4
        for n in ORDER:
            if kinds[n] == 'rev':
                R[t, idx[n]] = rz(F[t, c]); c += 1
            else:
                R[t, idx[n]] = qmat(*F[t, c:c+4]); c += 4
        assert c == F.shape[1]
    fps = 1.0 / float(np.median(F[:, 0]))
    return Motion(sk, R, F[:, 1:4].copy(), fps, name)
out = Path(sys.argv[1]); out.mkdir(parents=True, exist_ok=True)
rows = []
for m, label in [(a.split(':')[0], a.split(':')[1]) for a in sys.argv[2:]]:
    text = subprocess.run(['git', '--git-dir', GIT, 'show', f'HEAD:data/motions/humanoid3d_{m}.txt'], capture_output=True, text=True).stdout
    mo = load(text, f'dm_{m}')
    w = write_clip(mo, out / f'dm_{m}.bvh', f'dm_{m}', 30.0, 10.0, 4)
    print(m, mo.n_frames, round(mo.fps, 2), w.n_frames)
    rows.append((f'dm_{m}', label))
print(rows)
