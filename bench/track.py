#!/usr/bin/env python3
"""Tracking on a frame sequence (issue 47): a real photograph moved along a smooth camera path
(a homography per frame: drift, turn, zoom and tilt, each a slow sine), written as PNG frames,
then Tagsmith per frame with `detect --track` (stage 2 alone on the markers it follows; the whole
detector on the first frame, every `--redetect-every` frames and after a loss) and without it
(`--sequential`, the whole detector on every frame), beside OpenCV ArUco and AprilTag 3 where
they know the family, in one run. A marker counts as found when OpenCV's (or AprilTag 3's)
detection on the same frame has its ID and every corner within 3 px.

    bench/.venv/bin/python bench/track.py PHOTO FAMILY OUT_DIR --tagsmith target/release/tagsmith \
        [--frames 60] [--redetect-every 10]
"""

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from baselines import FAMILIES, apriltag_detector, opencv_detector  # noqa: E402
from realimages import matched  # noqa: E402


def frames(photo, count):
    h, w = photo.shape
    centre = np.array([w / 2, h / 2])
    out = []
    for k in range(count):
        t = k / max(count - 1, 1) * 2 * math.pi
        angle = 0.08 * math.sin(t)
        scale = 1.0 + 0.06 * math.sin(2 * t)
        shift = np.array([25 * math.sin(t), 15 * math.sin(1.5 * t)])
        c, s = math.cos(angle) * scale, math.sin(angle) * scale
        a = np.array([[c, -s], [s, c]])
        m = np.eye(3)
        m[:2, :2] = a
        m[:2, 2] = centre + shift - a @ centre
        m[2, :2] = [2e-5 * math.sin(t), 1e-5 * math.cos(t)]
        out.append(cv2.warpPerspective(photo, m, (w, h), flags=cv2.INTER_LINEAR,
                                       borderMode=cv2.BORDER_REPLICATE))
    return out


def tagsmith(binary, family, paths, extra):
    out = os.path.join(os.path.dirname(paths[0]), "..", f"tagsmith{'-'.join([''] + extra)}.json")
    subprocess.run([binary, "detect", "--family", family, *extra, *paths, "--json", out],
                   check=True, stdout=subprocess.DEVNULL)
    return json.load(open(out))["images"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("photo")
    ap.add_argument("family")
    ap.add_argument("out")
    ap.add_argument("--tagsmith", required=True)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--redetect-every", type=int, default=10)
    a = ap.parse_args()
    folder = os.path.join(a.out, "frames")
    os.makedirs(folder, exist_ok=True)
    photo = cv2.imread(a.photo, cv2.IMREAD_GRAYSCALE)
    paths = []
    for k, frame in enumerate(frames(photo, a.frames)):
        path = os.path.join(folder, f"{k:04d}.png")
        cv2.imwrite(path, frame)
        paths.append(path)
    dictionary, april = FAMILIES[a.family]
    baselines = [("OpenCV ArUco", opencv_detector(dictionary))]
    if april:
        baselines.append(("AprilTag 3", apriltag_detector(april)))
    rows = {}
    for label, detect in baselines:
        times, found = [], []
        for path in paths:
            gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
            start = time.perf_counter()
            dets = detect(gray)
            times.append((time.perf_counter() - start) * 1e3)
            found.append(dets)
        rows[label] = (times, found, None)
    reference = rows["OpenCV ArUco"][1] if not april else rows["AprilTag 3"][1]
    for label, extra in [("Tagsmith --track", ["--track", "--redetect-every", str(a.redetect_every)]),
                         ("Tagsmith, whole detector per frame", ["--sequential"])]:
        entries = tagsmith(a.tagsmith, a.family, paths, extra)
        rows[label] = ([e["time_ms"] for e in entries], [e["detections"] for e in entries],
                       [e.get("timings") or {} for e in entries])
    total = sum(len(r) for r in reference)
    print(f"{a.frames} frames of {os.path.basename(a.photo)} ({photo.shape[1]}×{photo.shape[0]}), "
          f"{a.family}; reference: {'AprilTag 3' if april else 'OpenCV ArUco'}, {total} markers")
    print("| detector | median ms / frame | p90 ms | max ms | whole-detector frames | reference markers found | markers reported |")
    print("|---|---|---|---|---|---|---|")
    for label, (times, found, timings) in rows.items():
        hit = sum(matched(r, dets) for ref, dets in zip(reference, found) for r in
                  [(d["id"], np.array(d["corners"])) for d in ref])
        fulls = "–"
        if timings and "tracked" in timings[0]:
            fulls = str(sum(not t["tracked"] for t in timings))
        elif timings:
            fulls = str(len(timings))
        p90 = sorted(times)[int(0.9 * (len(times) - 1))]
        print(f"| {label} | {statistics.median(times):.1f} | {p90:.1f} | {max(times):.1f} | {fulls} | "
              f"{hit} of {total} | {sum(len(f) for f in found)} |")
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
