#!/usr/bin/env python3
"""Peers for `intellwheels repeatability --sequence`: OpenCV SIFT, AKAZE and ORB on the same real
sequences, under the same protocol, in the same run.

For every sequence folder (img1..imgN plus H1toKp) it
  1. runs `BIN repeatability --sequence DIR --out OUT/NAME` (our detectors, the reference
     implementation; it also finds the homographies' pixel origin, which is reused here);
  2. runs each OpenCV peer twice: with OpenCV's defaults (ORB: nfeatures 1000), and as `PEER@N`
     keeping the N strongest keypoints of every image, N = the count `--match` (lsac-surf-nt by
     default) finds on img1 -- the thesis's fairness rule (4.6: compare at matched keypoint
     counts; SIFT nfeatures N, AKAZE threshold 1e-4 then the N best responses, ORB nfeatures N);
  3. recomputes R for our detectors from `BIN features IMG --json` keypoints with this script's
     own protocol code, as a cross-check of the two implementations.

Protocol (as iw_features::sequence): keypoints count only when their centre maps inside the
other image; reference keypoints are mapped with H (read with the pixel origin found in step 1),
their size multiplied by sqrt|det J| of H there; a correspondence is a pair within 2 px and a size
ratio within 1.5, one-to-one, nearest pairs first. R = C / m_i, R_sym = C / min(m_1, m_i);
matching score = correct mutual-nearest-neighbour matches (ratio 0.8; L2 for SIFT, Hamming for
AKAZE and ORB) over min(m_1, m_i). Peers see the gray image 0.299 R + 0.587 G + 0.114 B, rounded.

Usage: peers.py --bin target/release/intellwheels --out OUT DIR [DIR ...]
Writes OUT/NAME/summary.json (ours), OUT/NAME/peers.json (`pairs`, `summary` by detector) and
prints one Markdown table per sequence. Needs: pip install numpy scipy opencv-contrib-python-headless
"""
import argparse
import json
import os
import re
import subprocess
import sys

import cv2
import numpy as np
from scipy.spatial import cKDTree

DIST_TOL, SIZE_TOL = 2.0, 1.5
OURS = ["surf", "ln-surf", "lsac-surf", "lsac-surf-nt"]


def load_sequence(d):
    files = {}
    for f in os.listdir(d):
        m = re.fullmatch(r"img(\d+)\.(png|jpe?g|ppm|pgm)", f, re.I)
        if m:
            files[int(m.group(1))] = os.path.join(d, f)
    n = len(files)
    if sorted(files) != list(range(1, n + 1)) or n < 2:
        raise SystemExit(f"{d}: expected img1..imgN, found {sorted(files)}")
    hs = []
    for k in range(2, n + 1):
        v = np.array(open(os.path.join(d, f"H1to{k}p")).read().split(), float)
        hs.append(v.reshape(3, 3))
    return [files[k] for k in range(1, n + 1)], hs


def gray(path):
    bgr = cv2.imread(path, cv2.IMREAD_COLOR)
    if bgr is None:
        raise SystemExit(f"cannot read image {path}")
    f = bgr.astype(np.float64)
    g = 0.299 * f[..., 2] + 0.587 * f[..., 1] + 0.114 * f[..., 0]
    return np.floor(np.clip(g, 0, 255) + 0.5).astype(np.uint8)


def with_origin(h, o):
    t = lambda s: np.array([[1, 0, s], [0, 1, s], [0, 0, 1]], float)
    return t(-o) @ h @ t(o)


def project(h, p):
    q = np.c_[p, np.ones(len(p))] @ h.T
    return q[:, :2] / q[:, 2:3]


def local_scale(h, p):
    w = p @ h[2, :2] + h[2, 2]
    return np.sqrt(np.abs(np.linalg.det(h) / w ** 3))


def inside(p, shape):
    hgt, wid = shape
    return (p[:, 0] >= 0) & (p[:, 1] >= 0) & (p[:, 0] <= wid - 1) & (p[:, 1] <= hgt - 1)


def correspondences(pa, sa, pb, sb):
    """One-to-one pairs within the tolerances, nearest first (as iw_features::experiment)."""
    if len(pa) == 0 or len(pb) == 0:
        return 0
    m = cKDTree(pa).sparse_distance_matrix(cKDTree(pb), DIST_TOL, output_type="ndarray")
    i, j, d = m["i"], m["j"], m["v"]
    ratio = sa[i] / np.maximum(sb[j], 1e-12)
    ok = (ratio >= 1 / SIZE_TOL) & (ratio <= SIZE_TOL)
    i, j, d = i[ok], j[ok], d[ok]
    used_a, used_b, n = set(), set(), 0
    for k in np.lexsort((j, i, d)):
        if i[k] not in used_a and j[k] not in used_b:
            used_a.add(i[k]); used_b.add(j[k]); n += 1
    return n


def score(ref, other, h, shape, matches):
    """ref/other: (points Nx2, sizes N); matches: (ref index, other index) pairs."""
    (p1, s1), (pi, si) = ref, other
    q1 = project(h, p1) if len(p1) else np.zeros((0, 2))
    z1 = s1 * local_scale(h, p1) if len(p1) else np.zeros(0)
    in1 = inside(q1, shape) if len(p1) else np.zeros(0, bool)
    ini = inside(project(np.linalg.inv(h), pi), shape) if len(pi) else np.zeros(0, bool)
    m1, mi = int(in1.sum()), int(ini.sum())
    c = correspondences(pi[ini], si[ini], q1[in1], z1[in1])
    pct = lambda a, b: 100.0 * a / b if b else 0.0
    good = [(a, b) for a, b in matches if in1[a] and ini[b]]
    correct = sum(
        1 for a, b in good
        if np.hypot(*(q1[a] - pi[b])) <= DIST_TOL and 1 / SIZE_TOL <= si[b] / max(z1[a], 1e-12) <= SIZE_TOL
    )
    return {
        "reference_keypoints": m1, "keypoints": mi,
        "reference_keypoints_total": len(p1), "keypoints_total": len(pi),
        "correspondences": c, "repeatability": pct(c, mi), "repeatability_symmetric": pct(c, min(m1, mi)),
        "matches": len(good), "correct_matches": correct, "matching_score": pct(correct, min(m1, mi)),
    }


def factory(name):
    """`NAME_create` from cv2 or, in OpenCV 5, cv2.xfeatures2d (where AKAZE moved)."""
    for mod in (cv2, getattr(cv2, "xfeatures2d", None)):
        if mod is not None and hasattr(mod, f"{name}_create"):
            return getattr(mod, f"{name}_create")
    raise SystemExit(f"OpenCV {cv2.__version__} has no {name}")


def make_peer(name, count=None):
    """The detector and its descriptor norm: OpenCV's defaults (ORB: nfeatures 1000) or, with
    `count`, a low threshold so that at least `count` candidates exist (then cut to the best)."""
    create = factory(name)
    if name == "SIFT":
        return create(**({} if count is None else {"nfeatures": count})), cv2.NORM_L2
    if name == "AKAZE":
        return create(**({} if count is None else {"threshold": 1e-4})), cv2.NORM_HAMMING
    if name == "ORB":
        return create(nfeatures=1000 if count is None else count), cv2.NORM_HAMMING
    raise SystemExit(f"unknown peer {name}")


def run_peer(det, g, count=None):
    kps = det.detect(g, None)
    if count is not None:
        kps = sorted(kps, key=lambda k: -k.response)[:count]
    kps, desc = det.compute(g, kps)
    p = np.array([k.pt for k in kps], float).reshape(-1, 2)
    s = np.array([k.size for k in kps], float)
    return p, s, desc


def mutual_ratio_matches(d1, d2, norm):
    if d1 is None or d2 is None or len(d1) < 2 or len(d2) < 2:
        return []
    bf = cv2.BFMatcher(norm)
    fwd = bf.knnMatch(d1, d2, k=2)
    back = {m.queryIdx: m.trainIdx for m in bf.match(d2, d1)}
    out = []
    for pair in fwd:
        if len(pair) < 2:
            continue
        a, b = pair
        if a.distance < 0.8 * b.distance and back.get(a.trainIdx) == a.queryIdx:
            out.append((a.queryIdx, a.trainIdx))
    return out


def ours_keypoints(binary, detector, path):
    r = subprocess.run([binary, "features", path, "--detector", detector, "--json"],
                       capture_output=True, timeout=600)
    if r.returncode != 0:
        raise SystemExit(f"{detector} on {path}: {r.stderr.decode()[-400:]}")
    ks = [json.loads(line) for line in r.stdout.decode().splitlines() if line.startswith("{")]
    return (np.array([[k["x"], k["y"]] for k in ks], float).reshape(-1, 2),
            np.array([k["size"] for k in ks], float))


def summarise(rows):
    out = {}
    for name in dict.fromkeys(r["detector"] for r in rows):
        rs = [r for r in rows if r["detector"] == name]
        ref = rs[0]["reference_keypoints_total"]
        ratios = [r["keypoints_total"] / max(ref, 1) for r in rs]
        st = lambda key: {"mean": float(np.mean([r[key] for r in rs])),
                          "median": float(np.median([r[key] for r in rs])), "n": len(rs)}
        out[name] = {"repeatability": st("repeatability"),
                     "repeatability_symmetric": st("repeatability_symmetric"),
                     "matching_score": st("matching_score"), "reference_keypoints_total": ref,
                     "count_ratio_min": min(ratios), "count_ratio_max": max(ratios)}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--peers", default="SIFT,AKAZE,ORB")
    ap.add_argument("--match", default="lsac-surf-nt", help="detector whose img1 count the matched peers copy")
    ap.add_argument("sequences", nargs="+")
    a = ap.parse_args()
    for d in a.sequences:
        name = os.path.basename(os.path.normpath(d))
        out = os.path.join(a.out, name)
        os.makedirs(out, exist_ok=True)
        r = subprocess.run([a.bin, "repeatability", "--sequence", d, "--out", out])
        if r.returncode != 0:
            raise SystemExit(f"{a.bin} repeatability --sequence {d} failed")
        ours = json.load(open(os.path.join(out, "summary.json")))
        origin = ours["pixel_convention"]["origin_px"]
        files, hs = load_sequence(d)
        hs = [with_origin(h, origin) for h in hs]
        grays = [gray(f) for f in files]
        shape = grays[0].shape
        rows = []
        count = ours["summary"][a.match]["reference_keypoints_total"]
        for peer in [p for p in a.peers.split(",") if p]:
            for label, n in ((peer, None), (f"{peer}@{count}", count)):
                det, norm = make_peer(peer, n)
                feats = [run_peer(det, g, n) for g in grays]
                for k in range(1, len(files)):
                    m = mutual_ratio_matches(feats[0][2], feats[k][2], norm)
                    row = score(feats[0][:2], feats[k][:2], hs[k - 1], shape, m)
                    row.update(detector=label, image=os.path.basename(files[k]))
                    rows.append(row)
                print(f"{name}: {label} done", file=sys.stderr)
        check = {}
        for det in OURS:
            kp = [ours_keypoints(a.bin, det, f) for f in files]
            check[det] = float(np.mean([score(kp[0], kp[k], hs[k - 1], shape, [])["repeatability"]
                                        for k in range(1, len(files))]))
        summary = summarise(rows)
        json.dump({"sequence": name, "pixel_origin_px": origin, "pairs": rows, "summary": summary,
                   "cross_check_repeatability_mean": check},
                  open(os.path.join(out, "peers.json"), "w"), indent=1)
        print(f"\n{name} ({len(files)} images, homography origin {origin} px), mean over pairs")
        print("| detector | R = C/m_i | R = C/min | matching score | keypoints img1 | count ratio min-max |")
        print("|---|---|---|---|---|---|")
        for det, s in list(ours["summary"].items()) + list(summary.items()):
            print(f"| {det} | {s['repeatability']['mean']:.1f} | {s['repeatability_symmetric']['mean']:.1f}"
                  f" | {s['matching_score']['mean']:.1f} | {s['reference_keypoints_total']}"
                  f" | {s['count_ratio_min']:.2f}-{s['count_ratio_max']:.2f} |")
        print("cross-check, R = C/m_i from `features --json` with this script's protocol: "
              + ", ".join(f"{k} {v:.1f}" for k, v in check.items()))


if __name__ == "__main__":
    main()
