#!/usr/bin/env python3
"""Why one real-light pair scores what it scores: every detector on img1 and imgK of a sequence,
under peers.py's protocol, with where its keypoints in the shared region fail.

For each detector (ours through `BIN features IMG --detector D --json`, at their defaults;
OpenCV SIFT, AKAZE and ORB at 1000 keypoints as peers.py's PEER@1000, and at OpenCV's defaults)
it prints m_1, m_K, C, R = C/m_K and R_sym = C/min(m_1, m_K), and splits imgK's keypoints in the
shared region that found no counterpart into
  * size: a mapped reference keypoint lies within 2 px but none within the size ratio 1.5;
  * too fine: its size is below what the smallest reference keypoint becomes after mapping
    (smallest img1 size x the homography's local scale there / 1.5): no reference keypoint of
    this detector can correspond to it at any position;
  * elsewhere: the rest (no mapped reference keypoint within 2 px);
and by where they lie: in imgK's bright pixels (gray >= --bright, e.g. lit windows and street
lights at night) or not. "Chance R" is R with imgK's keypoints (sizes kept) moved to uniformly
random positions in the region img1 shows (mean of 5 draws, seed 0): what a detector scores at its
density with no repeatable structure at all. It also prints the homography's local scale over the
shared region.

Usage: pair_trace.py --bin BIN --sequence DIR --pair K [--origin 1] [--bright 200]
Needs: pip install numpy scipy opencv-contrib-python-headless
"""
import argparse
import os
import sys

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peers  # noqa: E402  (the protocol, OpenCV factories)


def trace(name, ref, other, h, shape, gray_k):
    (p1, s1), (pk, sk) = ref, other
    q1, z1 = peers.project(h, p1), s1 * peers.local_scale(h, p1)
    in1 = peers.inside(q1, shape)
    ink = peers.inside(peers.project(np.linalg.inv(h), pk), shape)
    q1, z1, pk, sk = q1[in1], z1[in1], pk[ink], sk[ink]
    m1, mk = len(q1), len(pk)
    c = peers.correspondences(pk, sk, q1, z1)
    # Which of imgK's keypoints have a counterpart (one-to-one as the protocol, nearest first).
    near = cKDTree(q1).query_ball_point(pk, peers.DIST_TOL) if m1 and mk else [[] for _ in pk]
    sized = [any(1 / peers.SIZE_TOL <= sk[i] / max(z1[j], 1e-12) <= peers.SIZE_TOL for j in js)
             for i, js in enumerate(near)]
    finest = z1.min() / peers.SIZE_TOL if m1 else np.inf
    fails = {"size": 0, "too fine": 0, "elsewhere": 0}
    bright_all = bright_fail = 0
    for i in range(mk):
        x, y = np.clip(np.round(pk[i]).astype(int), 0, [shape[1] - 1, shape[0] - 1])
        bright = gray_k[y, x] >= ARGS.bright
        bright_all += bright
        if sized[i]:
            continue
        bright_fail += bright
        if sk[i] < finest:
            fails["too fine"] += 1
        elif near[i]:
            fails["size"] += 1
        else:
            fails["elsewhere"] += 1
    unmatched = mk - sum(sized)
    rng = np.random.default_rng(0)
    chance = []
    for _ in range(5):
        pts = np.zeros((0, 2))
        while len(pts) < mk:
            cand = rng.uniform([0, 0], [shape[1] - 1, shape[0] - 1], size=(4 * mk + 16, 2))
            pts = np.r_[pts, cand[peers.inside(peers.project(np.linalg.inv(h), cand), shape)]]
        chance.append(peers.correspondences(pts[:mk], sk, q1, z1))
    pct = lambda a, b: 100.0 * a / b if b else 0.0
    print(f"| {name} | {m1} | {mk} | {c} | {pct(c, mk):.1f} | {pct(c, min(m1, mk)):.1f} | "
          f"{np.median(sk) if mk else 0:.1f} | {finest:.1f} | {unmatched} | "
          + " / ".join(f"{pct(v, mk):.0f}" for v in fails.values())
          + f" | {pct(bright_all, mk):.0f} / {pct(bright_fail, max(unmatched, 1)):.0f} | {pct(np.mean(chance), mk):.1f} |")


def main():
    global ARGS
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--sequence", required=True)
    ap.add_argument("--pair", type=int, required=True, help="K of the pair 1-K")
    ap.add_argument("--origin", type=float, default=1.0, help="pixel origin of the homographies")
    ap.add_argument("--bright", type=float, default=200.0)
    ap.add_argument("--detectors", default=",".join(peers.OURS))
    ARGS = ap.parse_args()
    files, hs = peers.load_sequence(ARGS.sequence)
    k = ARGS.pair
    h = peers.with_origin(hs[k - 2], ARGS.origin)
    g1, gk = peers.gray(files[0]), peers.gray(files[k - 1])
    shape = g1.shape
    ys, xs = np.mgrid[0:shape[0]:8, 0:shape[1]:8]
    grid = np.c_[xs.ravel(), ys.ravel()].astype(float)
    seen = grid[peers.inside(peers.project(h, grid), shape)]
    scale = peers.local_scale(h, seen)
    print(f"pair 1-{k} of {ARGS.sequence}: img1's area seen by img{k} {100 * len(seen) / len(grid):.0f} %, "
          f"local scale there (img{k} px per img1 px) median {np.median(scale):.2f}, "
          f"{scale.min():.2f}-{scale.max():.2f}")
    print(f"| detector | m_1 | m_{k} | C | R | R_sym | median size img{k} | finest possible counterpart "
          f"| no counterpart | of m_{k}: size / too fine / elsewhere % | in bright px: all / of the unmatched % | chance R |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for d in [d for d in ARGS.detectors.split(",") if d]:
        trace(d, peers.ours_keypoints(ARGS.bin, d, files[0]), peers.ours_keypoints(ARGS.bin, d, files[k - 1]),
              h, shape, gk)
    for peer in ("SIFT", "AKAZE", "ORB"):
        for label, n in ((f"{peer}@1000", 1000), (peer, None)):
            det, _ = peers.make_peer(peer, n)
            f1, fk = peers.run_peer(det, g1, n), peers.run_peer(det, gk, n)
            trace(label, f1[:2], fk[:2], h, shape, gk)


if __name__ == "__main__":
    main()
