#!/usr/bin/env python3
"""Tuning set for LSAC-SURF-NT's noise factor (issue 22): synthetic dimming sequences, kept apart
from the real-light sequences, which stay the held-out test.

`make`: each photograph of --images becomes a sequence folder (img1..img5 plus H1toKp, the
layout `intellwheels repeatability --sequence` reads): img1 is the photograph; imgK is it warped
by a known homography (rotation 4-8 deg, scale 0.92-1.08, a little perspective; OpenCV's
0-based pixel centres), darkened by a gain of 1/2, 1/4, 1/8, 1/16, with shot noise (0.25 DN^2 per
DN) and read noise (1.5 DN), rounded to 8 bits. Seeded: the same files every time.

`sweep`: for each noise factor K, LSAC-SURF-NT's keypoints through `BIN features IMG --detector
lsac-surf-nt --noise-factor K --json` (capped at its 1000, and uncapped), scored with peers.py's
protocol: mean R = C/m_i per gain over the sequences, and the uncapped count of imgK over img1.

Usage: noise_tuning.py make --images ../shared/data/images/skimage --out OUT
       noise_tuning.py sweep --bin BIN --origin 0 OUT/* -k 4 8 11 16 64
Needs: pip install numpy scipy opencv-contrib-python-headless
"""
import argparse
import json
import os
import subprocess
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peers  # noqa: E402  (the protocol code: projection, inside, correspondences)

PHOTOS = ["astronaut.png", "coffee.png", "chelsea.png", "rocket.jpg", "camera.png", "ihc.png", "brick.png"]
GAINS = [0.5, 0.25, 0.125, 0.0625]
ANGLE_DEG = [4, -6, 8, -3]
SCALE = [0.92, 1.08, 0.95, 1.05]
SHIFT = [(5, -3), (-7, 4), (3, 6), (-4, -5)]
PERSPECTIVE = [(1e-5, -1e-5), (-2e-5, 1e-5), (1.5e-5, 2e-5), (-1e-5, -1.5e-5)]


def homography(k, w, h):
    a, s = np.deg2rad(ANGLE_DEG[k]), SCALE[k]
    c = np.array([[1, 0, w / 2], [0, 1, h / 2], [0, 0, 1.0]])
    r = np.array([[s * np.cos(a), -s * np.sin(a), SHIFT[k][0]], [s * np.sin(a), s * np.cos(a), SHIFT[k][1]], [0, 0, 1.0]])
    p = np.array([[1, 0, 0], [0, 1, 0], [PERSPECTIVE[k][0], PERSPECTIVE[k][1], 1.0]])
    return c @ p @ r @ np.linalg.inv(c)


def make(images, out):
    rng = np.random.default_rng(22)
    for name in PHOTOS:
        im = cv2.imread(os.path.join(images, name), cv2.IMREAD_COLOR)
        if im is None:
            raise SystemExit(f"cannot read image {os.path.join(images, name)}")
        im = im.astype(np.float64)
        h, w = im.shape[:2]
        d = os.path.join(out, os.path.splitext(name)[0])
        os.makedirs(d, exist_ok=True)
        cv2.imwrite(os.path.join(d, "img1.png"), im.astype(np.uint8))
        for k, gain in enumerate(GAINS):
            hk = homography(k, w, h)
            x = cv2.warpPerspective(im, hk, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT) * gain
            x = x + rng.normal(0, 1, x.shape) * np.sqrt(0.25 * x + 1.5 ** 2)
            cv2.imwrite(os.path.join(d, f"img{k + 2}.png"), np.floor(np.clip(x, 0, 255) + 0.5).astype(np.uint8))
            np.savetxt(os.path.join(d, f"H1to{k + 2}p"), hk)
        print(d)


def keypoints(binary, path, k, cap):
    args = [binary, "features", path, "--detector", "lsac-surf-nt", "--noise-factor", str(k), "--json"]
    if not cap:
        args += ["--max-keypoints", "100000000"]
    r = subprocess.run(args, capture_output=True, timeout=600)
    if r.returncode != 0:
        raise SystemExit(f"{path}: {r.stderr.decode()[-400:]}")
    rows = [line for line in r.stdout.decode().splitlines() if line.startswith("{")]
    if not cap:
        return len(rows)
    ks = [json.loads(line) for line in rows]
    return np.array([[q["x"], q["y"]] for q in ks], float).reshape(-1, 2), np.array([q["size"] for q in ks], float)


def sweep(binary, origin, dirs, factors):
    for k in factors:
        rates, ratios = [], []
        for d in dirs:
            files, hs = peers.load_sequence(d)
            hs = [peers.with_origin(h, origin) for h in hs]
            shape = peers.gray(files[0]).shape
            kp = [keypoints(binary, f, k, True) for f in files]
            rates.append([peers.score(kp[0], kp[i], hs[i - 1], shape, [])["repeatability"] for i in range(1, len(files))])
            counts = [keypoints(binary, f, k, False) for f in files]
            ratios.append([c / max(counts[0], 1) for c in counts[1:]])
        r, q = np.mean(rates, axis=0), np.array(ratios)
        print(f"K={k}: R per pair {' '.join(f'{v:.1f}' for v in r)}, mean {r.mean():.1f}; uncapped count "
              f"ratio, median per pair {' '.join(f'{v:.2f}' for v in np.median(q, axis=0))}, "
              f"range {q.min():.2f}-{q.max():.2f}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("make")
    m.add_argument("--images", required=True)
    m.add_argument("--out", required=True)
    s = sub.add_parser("sweep")
    s.add_argument("--bin", required=True)
    s.add_argument("--origin", type=float, default=0.0, help="pixel origin of the H files (0 for `make`'s)")
    s.add_argument("-k", nargs="+", type=float, required=True)
    s.add_argument("dirs", nargs="+")
    a = ap.parse_args()
    if a.cmd == "make":
        make(a.images, a.out)
    else:
        sweep(a.bin, a.origin, a.dirs, a.k)


if __name__ == "__main__":
    main()
