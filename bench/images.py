#!/usr/bin/env python3
"""Runs AprilTag 3 and OpenCV ArUco on a folder of images (no benchmark set needed): detections
per image and the median time, in the detections format `tagsmith detect --json` writes. Used by
detector.sh for marker-free images (false positives) and for speed on plain folders.

    bench/.venv/bin/python bench/images.py DIR --detector apriltag --family apriltag-36h11 -o out.json
"""

import argparse
import glob
import json
import os
import statistics
import sys

import cv2

sys.path.insert(0, os.path.dirname(__file__))
from baselines import FAMILIES, apriltag_detector, opencv_detector  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("folder")
    ap.add_argument("--detector", choices=["apriltag", "opencv"], required=True)
    ap.add_argument("--family", required=True)
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args()
    dictionary, april = FAMILIES[a.family]
    if a.detector == "apriltag":
        detect, name = apriltag_detector(april), f"AprilTag 3 ({april})"
    else:
        detect, name = opencv_detector(dictionary), f"OpenCV ArUco ({dictionary})"
    images = []
    paths = [p for ext in ("png", "jpg") for p in glob.glob(os.path.join(a.folder, f"[0-9]*.{ext}"))]
    for path in sorted(paths):
        gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        start = cv2.getTickCount()
        found = detect(gray)
        ms = (cv2.getTickCount() - start) / cv2.getTickFrequency() * 1e3
        images.append({"file": path, "time_ms": ms, "detections": found})
    with open(a.output, "w") as f:
        json.dump({"detector": name, "images": images}, f)
    times = [i["time_ms"] for i in images]
    count = sum(len(i["detections"]) for i in images)
    print(f"{name}: {len(images)} images, {count} detections, median {statistics.median(times):.1f} ms")
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
