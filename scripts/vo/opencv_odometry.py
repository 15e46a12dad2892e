#!/usr/bin/env python3
"""Peer for `intellwheels vo`: OpenCV's RGB-D odometry (cv2.Odometry, RGB_DEPTH) frame to frame on
the same TUM frames, same intrinsics, writing a TUM trajectory and printing frames per second.

Usage: opencv_odometry.py SEQ_DIR OUT.txt [--frames N] [--type rgb_depth|depth|rgb]
Needs: pip install numpy opencv-contrib-python-headless (5.x).
"""
import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

CAMERAS = {  # TUM intrinsics, as in iw-vo
    "freiburg1": (517.3, 516.5, 318.6, 255.3),
    "freiburg2": (520.9, 521.0, 325.1, 249.7),
    "freiburg3": (535.4, 539.2, 320.1, 247.6),
}


def pairs(seq: Path):
    """Associated (t_rgb, rgb, depth) from associations.txt (the folders here all have it)."""
    out = []
    for n, line in enumerate((seq / "associations.txt").read_text().splitlines(), 1):
        f = line.split()
        if not f or f[0].startswith("#"):
            continue
        if len(f) != 4:
            sys.exit(f"{seq / 'associations.txt'}:{n}: expected 4 fields")
        out.append((float(f[0]), seq / f[1], seq / f[3]))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("seq", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--frames", type=int)
    ap.add_argument("--type", default="rgb_depth", choices=["rgb_depth", "depth", "rgb"])
    a = ap.parse_args()
    cam = next((v for k, v in CAMERAS.items() if k in a.seq.resolve().name), CAMERAS["freiburg1"])
    fx, fy, cx, cy = cam
    settings = cv2.OdometrySettings()
    settings.setCameraMatrix(np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=np.float32))
    kind = {"rgb_depth": cv2.OdometryType_RGB_DEPTH, "depth": cv2.OdometryType_DEPTH, "rgb": cv2.OdometryType_RGB}[a.type]
    odo = cv2.Odometry(kind, settings, cv2.OdometryAlgoType_COMMON)
    frames = pairs(a.seq)[: a.frames]
    pose = np.eye(4)
    poses = []
    prev = None
    failures = 0
    start = time.perf_counter()
    for t, rgb_path, depth_path in frames:
        gray = cv2.imread(str(rgb_path), cv2.IMREAD_GRAYSCALE)
        depth = cv2.imread(str(depth_path), cv2.IMREAD_UNCHANGED).astype(np.float32) / 5000.0
        frame = cv2.OdometryFrame(depth=depth, image=gray)
        odo.prepareFrame(frame)
        if prev is not None:
            # Rt * src = dst with src = previous frame: Rt = T_current_previous.
            ok, rt = odo.compute(prev, frame)
            if ok:
                pose = pose @ np.linalg.inv(rt)
            else:
                failures += 1
        poses.append((t, pose.copy()))
        prev = frame
    elapsed = time.perf_counter() - start
    with a.out.open("w") as f:
        for t, p in poses:
            q = Rotation.from_matrix(p[:3, :3]).as_quat()  # x y z w
            f.write(f"{t:.6f} {p[0,3]:.7f} {p[1,3]:.7f} {p[2,3]:.7f} {q[0]:.7f} {q[1]:.7f} {q[2]:.7f} {q[3]:.7f}\n")
    n = len(frames)
    print(f"opencv {cv2.__version__} Odometry {a.type}: {n} frames in {elapsed:.2f} s, "
          f"{1e3 * elapsed / max(n, 1):.1f} ms/frame, {n / elapsed:.1f} frames/s, {failures} failures; wrote {a.out}")


if __name__ == "__main__":
    main()
