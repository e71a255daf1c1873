#!/usr/bin/env python3
"""A synthetic COLMAP text model for lifting benchmarks: N points in a 100 x 100 x 20 box, each
seen by 4 of 200 images (fixed seed). Usage: synthetic_colmap_model.py N OUT_DIR"""
import numpy as np, sys
rng = np.random.default_rng(1)
N = int(sys.argv[1]); I = 200; T = 4
out = sys.argv[2]
import os
os.makedirs(out, exist_ok=True)
pts = rng.uniform(-50, 50, (N, 3)); pts[:, 2] *= 0.2
imgs = rng.integers(1, I + 1, (N, T))
with open(os.path.join(out, 'cameras.txt'), 'w') as f:
    f.write('1 PINHOLE 1920 1080 1500 1500 960 540\n')
obs = [[] for _ in range(I + 1)]
tracks = np.zeros((N, T), dtype=np.int64)
for t in range(T):
    for k, im in enumerate(imgs[:, t]):
        tracks[k, t] = len(obs[im]); obs[im].append(k + 1)
with open(os.path.join(out, 'images.txt'), 'w') as f:
    for i in range(1, I + 1):
        c = rng.uniform(-60, 60, 3)
        f.write(f'{i} 1 0 0 0 {c[0]:.6f} {c[1]:.6f} {c[2]:.6f} 1 img{i:04d}.jpg\n')
        ids = np.array(obs[i]); xy = rng.uniform(0, 1000, (len(ids), 2))
        f.write(' '.join(f'{x:.2f} {y:.2f} {p}' for (x, y), p in zip(xy, ids)) + '\n')
with open(os.path.join(out, 'points3D.txt'), 'w') as f:
    for k in range(N):
        tr = ' '.join(f'{imgs[k,t]} {tracks[k,t]}' for t in range(T))
        f.write(f'{k+1} {pts[k,0]:.6f} {pts[k,1]:.6f} {pts[k,2]:.6f} 128 128 128 0.5 {tr}\n')
