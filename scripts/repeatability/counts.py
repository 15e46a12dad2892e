#!/usr/bin/env python3
"""Keypoint counts across a sequence, whole image and inside the shared region (issue 22 target:
"the count stays within +-30 % across the sequence").

The whole-image count moves with what the photograph shows: a zoomed or cropped view (less of the
scene), a postcard's border. What the detector controls is the count inside the region both
images show: for pair 1-K, the keypoints of img1 whose centre maps inside imgK (`m_1`) and the
keypoints of imgK whose centre maps back inside img1 (`m_K`), the `m` of the protocol. This
script reports both, uncapped (`--max-keypoints 100000000`: every keypoint the threshold keeps),
for our detectors through `BIN features IMG --json`, and for OpenCV SIFT and AKAZE at their
default thresholds (ORB is a fixed count and is left out).

Usage: counts.py --bin BIN [--detector lsac-surf-nt ...] [--peers SIFT,AKAZE] [--origin 0.5]
                 DIR [DIR ...] [-- extra flags for `BIN features`]
Prints, per sequence and detector: the counts of img1..imgN, their ratio to img1 (min-max), and
per pair m_K / m_1 inside the shared region (min-max), and the same per unit of shared area (a
zoomed view shows the shared scene on more pixels); `--json FILE` writes every figure.
Needs: pip install numpy scipy opencv-contrib-python-headless
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peers  # noqa: E402  (sequence layout, projection, `inside`, OpenCV peers)


def ours(binary, detector, path, extra):
    args = [binary, "features", path, "--detector", detector, "--max-keypoints", "100000000", "--json"]
    r = subprocess.run(args + extra, capture_output=True, timeout=900)
    if r.returncode != 0:
        raise SystemExit(f"{detector} on {path}: {r.stderr.decode()[-400:]}")
    ks = [json.loads(line) for line in r.stdout.decode().splitlines() if line.startswith("{")]
    return np.array([[k["x"], k["y"]] for k in ks], float).reshape(-1, 2)


def shared_fraction(h, shape):
    """The fraction of an image's pixels (4 px grid) that `h` maps inside an image of `shape`."""
    hgt, wid = shape
    g = np.mgrid[0:wid:4, 0:hgt:4].reshape(2, -1).T.astype(float)
    return float(peers.inside(peers.project(h, g), shape).mean())


def counts(points, hs, shape):
    """Whole-image counts; per pair (m_1, m_K) inside the shared region, and the density ratio
    (m_K / area of the shared region in imgK) / (m_1 / its area in img1)."""
    whole = [len(p) for p in points]
    shared, density = [], []
    for k, h in enumerate(hs, start=1):
        p1, pk = points[0], points[k]
        hinv = np.linalg.inv(h)
        m1 = int(peers.inside(peers.project(h, p1), shape).sum()) if len(p1) else 0
        mk = int(peers.inside(peers.project(hinv, pk), shape).sum()) if len(pk) else 0
        shared.append((m1, mk))
        a1, ak = shared_fraction(h, shape), shared_fraction(hinv, shape)
        density.append((mk / max(ak, 1e-9)) / max(m1 / max(a1, 1e-9), 1e-9))
    return whole, shared, density


def main():
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[:argv.index("--")] if "--" in argv else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--detector", nargs="*", default=["lsac-surf-nt"])
    ap.add_argument("--peers", default="", help="e.g. SIFT,AKAZE at OpenCV's defaults")
    ap.add_argument("--origin", type=float, default=0.5, help="pixel origin of the H files")
    ap.add_argument("--json")
    ap.add_argument("sequences", nargs="+")
    a = ap.parse_args(argv)
    report = []
    for d in a.sequences:
        name = os.path.basename(os.path.normpath(d))
        files, hs = peers.load_sequence(d)
        hs = [peers.with_origin(h, a.origin) for h in hs]
        shape = peers.gray(files[0]).shape
        runs = [(det, [ours(a.bin, det, f, extra) for f in files]) for det in a.detector]
        for peer in [p for p in a.peers.split(",") if p]:
            det, _ = peers.make_peer(peer)
            runs.append((peer, [peers.run_peer(det, peers.gray(f))[0] for f in files]))
        for det, points in runs:
            whole, shared, density = counts(points, hs, shape)
            ratio = [w / max(whole[0], 1) for w in whole[1:]]
            pair = [mk / max(m1, 1) for m1, mk in shared]
            report.append({"sequence": name, "detector": det, "whole": whole, "shared": shared,
                           "whole_ratio": ratio, "shared_ratio": pair,
                           "shared_density_ratio": density})
            print(f"{name} {det}: whole {' '.join(map(str, whole))} ratio {min(ratio):.2f}-{max(ratio):.2f}; "
                  f"shared m_1/m_K {' '.join(f'{m1}/{mk}' for m1, mk in shared)} "
                  f"ratio {min(pair):.2f}-{max(pair):.2f}; density ratio "
                  f"{' '.join(f'{v:.2f}' for v in density)}", flush=True)
    if a.json:
        json.dump(report, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
