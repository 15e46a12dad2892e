#!/usr/bin/env python3
"""Peer timings for the detection bench: OpenCV SIFT and ORB detect+compute on the same
640x480 frame the Rust bench uses (centre crop of the image given), gray as OpenCV converts it.

Usage: python3 opencv_peer.py IMAGE [--repeats N]
Prints one line per detector: name, median ms, keypoints, OpenCV version and thread count.
Needs: pip install numpy opencv-contrib-python-headless
"""
import argparse, statistics, time

import cv2


def centre_crop(img, w=640, h=480):
    H, W = img.shape[:2]
    if W < w or H < h:
        raise SystemExit(f"image {W}x{H} is smaller than {w}x{h}")
    x0, y0 = (W - w) // 2, (H - h) // 2
    return img[y0:y0 + h, x0:x0 + w]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("image")
    ap.add_argument("--repeats", type=int, default=30)
    a = ap.parse_args()
    bgr = cv2.imread(a.image, cv2.IMREAD_COLOR)
    if bgr is None:
        raise SystemExit(f"cannot read {a.image}")
    gray = cv2.cvtColor(centre_crop(bgr), cv2.COLOR_BGR2GRAY)
    peers = {"opencv-sift": cv2.SIFT_create(), "opencv-orb": cv2.ORB_create(nfeatures=1000)}
    for name, det in peers.items():
        det.detectAndCompute(gray, None)  # warm-up
        times, n = [], 0
        for _ in range(a.repeats):
            t0 = time.perf_counter()
            kps, _ = det.detectAndCompute(gray, None)
            times.append((time.perf_counter() - t0) * 1e3)
            n = len(kps)
        print(f"{name}: median {statistics.median(times):.2f} ms, {n} keypoints "
              f"(OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads)")


if __name__ == "__main__":
    main()
