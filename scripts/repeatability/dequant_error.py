#!/usr/bin/env python3
"""How far the LCC relit image is from its unrounded truth, as stored and after de-quantisation
(`DetectorConfig::dequantise_iterations`; docs/results/repeatability.md, tenth round).

LCC multiplies red and green by a and rounds to 8 bits; the truth is a x the reference, in float.
Per photograph and channel (red, green) it prints the RMS error against the truth of the rounded
channel and of the de-quantised one (ROUNDS rounds of the binomial [1, 2, 1] / 4 both ways, border
repeated, then a clamp into [v - 0.5, v + 0.5], as the detector does), raw and after a Gaussian of
sigma 0.8 input px (the detector's blur of its doubled image, 1.6 doubled px), and the medians.

Usage: dequant_error.py IMAGES_DIR [--rounds 16] [--gains 0.2,0.5]
Needs: pip install numpy scipy opencv-contrib-python-headless
"""
import argparse
import glob
import os

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter


def dequantise(q, rounds):
    x = q.copy()
    for _ in range(rounds):
        p = np.pad(x, 1, mode="edge")
        h = 0.25 * (p[:, :-2] + p[:, 2:]) + 0.5 * p[:, 1:-1]
        x = np.clip(0.25 * (h[:-2, :] + h[2:, :]) + 0.5 * h[1:-1, :], q - 0.5, q + 0.5)
    return x


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("images")
    ap.add_argument("--rounds", type=int, default=16)
    ap.add_argument("--gains", default="0.2,0.5")
    a = ap.parse_args()
    files = sorted(glob.glob(os.path.join(a.images, "*.png")) + glob.glob(os.path.join(a.images, "*.jpg")))
    if not files:
        raise SystemExit(f"{a.images}: no .png or .jpg images")
    rms = lambda e: float(np.sqrt(np.mean(e ** 2)))
    blur = lambda x: gaussian_filter(x, 0.8, mode="nearest")
    print("gain photograph channel: rounded, de-quantised | after sigma 0.8: rounded, de-quantised")
    for gain in [float(g) for g in a.gains.split(",")]:
        rows = []
        for f in files:
            im = cv2.imread(f, cv2.IMREAD_UNCHANGED)
            if im is None:
                raise SystemExit(f"cannot read image {f}")
            if im.ndim == 2:
                im = np.repeat(im[:, :, None], 3, axis=2)
            rgb = im[:, :, :3][:, :, ::-1].astype(np.float64)
            for c, name in ((0, "R"), (1, "G")):
                truth = rgb[..., c] * gain
                q = np.floor(np.clip(truth, 0.0, 255.0) + 0.5)
                d = dequantise(q, a.rounds)
                row = (rms(q - truth), rms(d - truth), rms(blur(q) - blur(truth)), rms(blur(d) - blur(truth)))
                rows.append(row)
                print(f"{gain:g} {os.path.basename(f)} {name}: {row[0]:.3f}, {row[1]:.3f} | {row[2]:.3f}, {row[3]:.3f}")
        m = np.median(np.array(rows), axis=0)
        print(f"{gain:g} median over {len(rows)}: {m[0]:.3f}, {m[1]:.3f} | {m[2]:.3f}, {m[3]:.3f}")


if __name__ == "__main__":
    main()
