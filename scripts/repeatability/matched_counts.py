#!/usr/bin/env python3
"""Repeatability on the synthetic light collections (LIC, LCC, LIS) at matched keypoint counts:
the thesis's fairness rule (4.6), applied per image pair, for our detectors and OpenCV peers in
one run.

R rewards losing keypoints: a detector that keeps only its few strongest points on a relit image
is scored over those few. Here every pair is scored at one common count instead:
  1. every detector detects on the reference and on the relit image with its threshold only, no
     count cap (ours: `BIN features IMG --detector D --max-keypoints 100000000 --json`, which
     prints the keypoints in the order the detector's own cap ranks them; OpenCV's: the detector
     at its defaults, ORB left out since its count is a parameter);
  2. N = the smallest of those counts over every compared detector and both images of the pair
     (`--max-common K`: at most K as well); a detector with no keypoint in either image scores
     R = 0 on that pair (as the shared checker scores it) and N is the smallest among the others;
  3. every detector keeps its N best keypoints in both images, then R = C / N.
With `--also-n-from PEER` the same run also scores every detector at that one detector's count
(N = the smallest of PEER's counts on the two images, the others not lowering it; where PEER
finds none, N = the smallest count of the others), with the detectors' own ranking: how the
detectors compare at AKAZE's count, not pulled down by a detector that keeps few keypoints. A
detector with fewer than N keypoints keeps all it has (R = C over them).
"Best" is reported two ways, both in one run, the same rule for every detector:
  * `own`: the detector's own ranking (ours: the cap's order: lsac-surf-nt ranks by
    signal-to-noise, size-discounted, with its 2 px spacing; the others by response; OpenCV's by
    `KeyPoint.response`, as OpenCV's own retainBest);
  * `response`: every detector by its reported response alone.
The protocol is the shared checker's (relit RGB in float, clipped, rounded to 8 bits; LIC: all
channels x a, LCC: R and G x a, LIS: all + b; correspondence within 2 px and a size ratio of 1.5,
one-to-one, nearest first; ours see the RGB PNG, OpenCV's the gray 0.299 R + 0.587 G + 0.114 B).
Beside the matched R, the R each detector gets uncapped (its threshold's full count) is printed.

A detector of ours may carry `features` flags, `NAME+FLAG=VALUE[+...]` (e.g.
`lsac-surf-nt+dequantise-iterations=32`), to measure a variant beside its default in one run.

Usage: matched_counts.py --bin BIN --images DIR [--detectors lsac-surf-nt,lsac-surf]
                         [--peers AKAZE] [--collections LCC,LIC,LIS] [--also-n-from AKAZE]
                         [--json OUT]
       matched_counts.py --from-json OUT   (reprint the medians of a saved run)
Prints the medians over the (image, parameter) pairs per collection and detector, with the number
of pairs where some detector found no keypoint (it scores 0 there).
Needs: pip install numpy scipy opencv-contrib-python-headless
"""
import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peers  # noqa: E402  (the protocol's correspondences, OpenCV factories)

COLLECTIONS = {
    "LIC": [1 / 2.0, 1 / 1.5, 1 / 1.2, 1 / 1.1, 1.1, 1.2, 1.5, 2.0],
    "LIS": [-20, -15, -10, -5, 5, 10, 15, 20],
    "LCC": [0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9],
}
UNCAPPED = "100000000"


def to_u8(x):
    return np.floor(np.clip(x, 0.0, 255.0) + 0.5).astype(np.uint8)


def load_rgb(path):
    im = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if im is None:
        raise SystemExit(f"cannot read image {path}")
    if im.ndim == 2:
        im = np.repeat(im[:, :, None], 3, axis=2)
    return im[:, :, :3][:, :, ::-1].astype(np.float64)


def relight(rgb, coll, p):
    out = rgb.copy()
    if coll == "LIC":
        out *= p
    elif coll == "LIS":
        out += p
    elif coll == "LCC":
        out[..., :2] *= p
    return to_u8(out)


def gray_u8(rgb_u8):
    f = rgb_u8.astype(np.float64)
    return to_u8(0.299 * f[..., 0] + 0.587 * f[..., 1] + 0.114 * f[..., 2])


class Keypoints:
    """Points, sizes and responses in the detector's own ranking order (best first)."""

    def __init__(self, pts, sizes, responses):
        self.pts, self.sizes, self.responses = pts, sizes, responses

    def best(self, n, rank):
        order = np.arange(len(self.pts)) if rank == "own" else np.argsort(-self.responses, kind="stable")
        keep = order[:n]
        return self.pts[keep], self.sizes[keep]


def ours(binary, spec, tmp):
    """`spec`: a detector name, optionally with `features` flags: `lsac-surf-nt+dequantise-iterations=32`."""
    name, *flags = spec.split("+")
    extra = []
    for flag in flags:
        key, sep, value = flag.partition("=")
        if not (key and sep and value):
            raise SystemExit(f"--detectors {spec}: expected NAME+FLAG=VALUE")
        extra += [f"--{key}", value]

    def detect(rgb_u8):
        path = os.path.join(tmp, "img.png")
        cv2.imwrite(path, rgb_u8[..., ::-1])
        args = [binary, "features", path, "--detector", name, *extra, "--max-keypoints", UNCAPPED, "--json"]
        r = subprocess.run(args, capture_output=True, timeout=900)
        if r.returncode != 0:
            raise SystemExit(f"{name}: features --json failed: {r.stderr.decode()[-400:]}")
        ks = [json.loads(line) for line in r.stdout.decode().splitlines() if line.startswith("{")]
        return Keypoints(np.array([[k["x"], k["y"]] for k in ks], float).reshape(-1, 2),
                         np.array([k["size"] for k in ks], float),
                         np.array([k["response"] for k in ks], float))
    return detect


def opencv(name, akaze_threshold=None):
    det = peers.factory(name)(**({"threshold": akaze_threshold} if name == "AKAZE" and akaze_threshold else {}))

    def detect(rgb_u8):
        kps = sorted(det.detect(gray_u8(rgb_u8), None), key=lambda k: -k.response)
        return Keypoints(np.array([k.pt for k in kps], float).reshape(-1, 2),
                         np.array([k.size for k in kps], float),
                         np.array([k.response for k in kps], float))
    return detect


def r_percent(relit, ref):
    (pi, si), (pr, sr) = relit, ref
    return 100.0 * peers.correspondences(pi, si, pr, sr) / len(pi) if len(pi) else 0.0


def summarise(rows, images):
    """Medians per collection over the pairs where some detector found keypoints; "a detector
    found none": pairs where one scored 0 for it. "N set by": the pairs where a detector's smaller
    count is N (ties count for each; a pair that `--max-common` capped counts for none)."""
    dets = list(rows[0]["detectors"])
    print(f"{images} images; median over pairs: R at the common count N, own ranking "
          "[by response] {uncapped R, median count ratio relit/ref}")
    print("| collection | pairs (a detector found none) | median N | N set by | " + " | ".join(dets) + " |")
    print("|---|---|---|---|" + "---|" * len(dets))
    for coll in dict.fromkeys(r["collection"] for r in rows):
        every = [r for r in rows if r["collection"] == coll]
        rs = [r for r in every if r["common_count"] > 0]
        none = sum(1 for r in rs if any(min(v["reference_keypoints"], v["keypoints"]) == 0
                                        for v in r["detectors"].values()))
        setter = {n: 0 for n in dets}
        for r in rs:
            for n, v in r["detectors"].items():
                if min(v["reference_keypoints"], v["keypoints"]) == r["common_count"]:
                    setter[n] += 1
        cells = []
        for n in dets:
            v = lambda key: float(np.median([r["detectors"][n][key] for r in rs]))
            ratio = float(np.median([r["detectors"][n]["keypoints"] / max(r["detectors"][n]["reference_keypoints"], 1)
                                     for r in rs]))
            cells.append(f"{v('repeatability_matched_own'):.1f} [{v('repeatability_matched_response'):.1f}]"
                         f" {{{v('repeatability_uncapped'):.1f}, {ratio:.2f}}}")
        print(f"| {coll} | {len(rs)} ({none}) | {np.median([r['common_count'] for r in rs]):.0f} | "
              + ", ".join(f"{n} {c}" for n, c in setter.items() if c) + " | " + " | ".join(cells) + " |")
    source = rows[0].get("n_from")
    if source:
        print(f"\nAt {source}'s count (own ranking; [pairs where the detector had fewer than N]):")
        print("| collection | median N | " + " | ".join(dets) + " |")
        print("|---|---|" + "---|" * len(dets))
        for coll in dict.fromkeys(r["collection"] for r in rows):
            rs = [r for r in rows if r["collection"] == coll and r["n_from_count"] > 0]
            cells = []
            for n in dets:
                med = float(np.median([r["detectors"][n]["repeatability_at_n_from"] for r in rs]))
                short = sum(1 for r in rs if min(r["detectors"][n]["reference_keypoints"],
                                                 r["detectors"][n]["keypoints"]) < r["n_from_count"])
                cells.append(f"{med:.1f} [{short}]")
            print(f"| {coll} | {np.median([r['n_from_count'] for r in rs]):.0f} | " + " | ".join(cells) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin")
    ap.add_argument("--images")
    ap.add_argument("--detectors", default="lsac-surf-nt,lsac-surf")
    ap.add_argument("--peers", default="AKAZE")
    ap.add_argument("--collections", default="LCC,LIC")
    ap.add_argument("--akaze-threshold", type=float,
                    help="AKAZE's detector threshold (OpenCV's default 0.001; peers.py's AKAZE@N uses 1e-4)")
    ap.add_argument("--max-common", type=int,
                    help="cap the common count N as well (e.g. 1000, lsac-surf-nt's own cap)")
    ap.add_argument("--also-n-from", help="also score every detector at this detector's count (e.g. AKAZE)")
    ap.add_argument("--json", help="write every pair's counts and R here")
    ap.add_argument("--from-json", help="print the medians of a saved --json run (no detection)")
    a = ap.parse_args()
    if a.from_json:
        saved = json.load(open(a.from_json))
        summarise(saved["pairs"], saved["images"])
        return
    if not (a.bin and a.images):
        ap.error("--bin and --images are needed (or --from-json)")
    colls = [c for c in a.collections.split(",") if c]
    for c in colls:
        if c not in COLLECTIONS:
            raise SystemExit(f"--collections: unknown {c!r} (expected LIC, LIS, LCC)")
    tmp = tempfile.mkdtemp()
    dets = {n: ours(a.bin, n, tmp) for n in a.detectors.split(",") if n}
    dets.update({(f"{n}(t={a.akaze_threshold:g})" if n == "AKAZE" and a.akaze_threshold else n):
                 opencv(n, a.akaze_threshold) for n in a.peers.split(",") if n})
    if a.also_n_from and a.also_n_from not in dets:
        raise SystemExit(f"--also-n-from {a.also_n_from}: not among the detectors {list(dets)}")
    files = sorted(glob.glob(os.path.join(a.images, "*.png")) + glob.glob(os.path.join(a.images, "*.jpg")))
    if not files:
        raise SystemExit(f"{a.images}: no .png or .jpg images")
    rows = []
    for f in files:
        rgb = load_rgb(f)
        ref = {n: d(to_u8(rgb)) for n, d in dets.items()}
        for coll in colls:
            for p in COLLECTIONS[coll]:
                relit = {n: d(relight(rgb, coll, p)) for n, d in dets.items()}
                counts = {n: min(len(ref[n].pts), len(relit[n].pts)) for n in dets}
                found = [c for c in counts.values() if c > 0]
                n_common = min(found) if found else 0
                if a.max_common is not None:
                    n_common = min(n_common, a.max_common)
                row = {"image": os.path.basename(f), "collection": coll, "parameter": p,
                       "common_count": n_common, "detectors": {}}
                if a.also_n_from:
                    own = counts[a.also_n_from]
                    others = [c for n, c in counts.items() if n != a.also_n_from and c > 0]
                    row["n_from"] = a.also_n_from
                    row["n_from_count"] = own if own > 0 else (min(others) if others else 0)
                for n in dets:
                    full = lambda k: (k.pts, k.sizes)
                    # No keypoint in either image: nothing repeats (0, as the shared checker scores it).
                    if counts[n] == 0:
                        row["detectors"][n] = {"reference_keypoints": len(ref[n].pts), "keypoints": len(relit[n].pts),
                                               "repeatability_uncapped": 0.0, "repeatability_matched_own": 0.0,
                                               "repeatability_matched_response": 0.0}
                        if a.also_n_from:
                            row["detectors"][n]["repeatability_at_n_from"] = 0.0
                        continue
                    row["detectors"][n] = {
                        "reference_keypoints": len(ref[n].pts), "keypoints": len(relit[n].pts),
                        "repeatability_uncapped": r_percent(full(relit[n]), full(ref[n])),
                        "repeatability_matched_own": r_percent(relit[n].best(n_common, "own"),
                                                               ref[n].best(n_common, "own")),
                        "repeatability_matched_response": r_percent(relit[n].best(n_common, "response"),
                                                                    ref[n].best(n_common, "response")),
                    }
                    if a.also_n_from:
                        k = row["n_from_count"]
                        row["detectors"][n]["repeatability_at_n_from"] = r_percent(relit[n].best(k, "own"),
                                                                                   ref[n].best(k, "own"))
                rows.append(row)
                print(f"{os.path.basename(f)} {coll} {p:.3g}: N {n_common}; " + ", ".join(
                    f"{n} {v['repeatability_matched_own']:.1f}" for n, v in row["detectors"].items()),
                    file=sys.stderr, flush=True)
    if a.json:
        json.dump({"images": len(files), "max_common": a.max_common, "pairs": rows}, open(a.json, "w"), indent=1)
    summarise(rows, len(files))


if __name__ == "__main__":
    main()
