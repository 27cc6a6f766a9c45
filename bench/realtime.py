#!/usr/bin/env python3
"""Latency on real photographs, Tagsmith beside AprilTag 3 and OpenCV ArUco in one run (issue 47).

Each image is detected one at a time: Tagsmith with `detect --sequential` (its own per-phase times,
ROIs and stage-2 passes from `--json`), AprilTag 3 through pupil-apriltags (1 thread,
`quad_decimate=1`) and OpenCV's ArucoDetector, each baseline timed best of 3 in this process.
Recall counts the reference detections (the AprilTag C library's regression outputs for the
swarmathon photographs; OpenCV's detector for its tutorial photographs, as `realimages.py`) that a
detector reports with the same ID and every corner within 3 px.

    bench/.venv/bin/python bench/realtime.py REALIMAGES_DIR --tagsmith target/release/tagsmith \
        [--extra FAMILY:DIR ...]

`--extra FAMILY:DIR` adds a folder of photographs (JPEG/PNG) without reference detections: their
rows give latency and counts only. Prints one Markdown table per group and a per-source table
(what each proposal source cost and read).
"""

import argparse
import glob
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import cv2

sys.path.insert(0, os.path.dirname(__file__))
from baselines import FAMILIES, apriltag_detector, opencv_detector  # noqa: E402
from realimages import matched, opencv_reference, swarmathon_reference  # noqa: E402
from sources import print_tally  # noqa: E402

def best_of(detect, gray, runs=3):
    best, found = float("inf"), []
    for _ in range(runs):
        start = time.perf_counter()
        found = detect(gray)
        best = min(best, (time.perf_counter() - start) * 1e3)
    return best, found


def tagsmith(binary, family, images):
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "d.json")
        subprocess.run([binary, "detect", "--sequential", "--family", family, *images, "--json", out],
                       check=True, stdout=subprocess.DEVNULL)
        return json.load(open(out))["images"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("realimages")
    ap.add_argument("--tagsmith", required=True)
    ap.add_argument("--extra", action="append", default=[], help="FAMILY:DIR without references")
    a = ap.parse_args()
    groups = [
        ("swarmathon (AprilTag 36h11)", "apriltag-36h11",
         sorted(glob.glob(os.path.join(a.realimages, "apriltag_swarmathon", "*.jpg"))),
         lambda p: swarmathon_reference(p[:-4] + ".txt")),
        ("OpenCV tutorial (ArUco 6x6_250)", "aruco-6x6_250",
         [os.path.join(a.realimages, "opencv_aruco_tutorial", f) for f in
          ["singlemarkersoriginal.jpg", "choriginal.jpg", "chocclusion_original.jpg",
           "img_00.jpg", "img_01.jpg", "img_02.jpg", "img_03.jpg"]],
         opencv_reference),
    ]
    for extra in a.extra:
        family, folder = extra.split(":", 1)
        paths = sorted(p for ext in ("jpg", "jpeg", "png") for p in glob.glob(os.path.join(folder, f"*.{ext}")))
        groups.append((f"{os.path.basename(folder.rstrip('/'))} ({family})", family, paths, None))

    entries_all = []
    # Every baseline detector lives until os._exit: pupil-apriltags' destructor segfaults now
    # and then when a second detector replaces the first (realtime.sh's retries were for that).
    kept_alive = []
    print("| photographs | detector | median ms | min–max ms | ROIs / image | stage-2 passes / image | "
          "reference markers found | markers reported |")
    print("|---|---|---|---|---|---|---|---|")
    for name, family, images, reference in groups:
        refs = [reference(p) for p in images] if reference else None
        rows = {}
        entries = tagsmith(a.tagsmith, family, images)
        rows["Tagsmith"] = ([e["time_ms"] for e in entries], [e["detections"] for e in entries],
                            [e.get("timings") or {} for e in entries])
        entries_all += entries
        dictionary, april = FAMILIES[family]
        baselines = [("OpenCV ArUco", opencv_detector(dictionary))]
        if april:
            baselines.insert(0, ("AprilTag 3", apriltag_detector(april)))
        kept_alive.append(baselines)
        for label, detect in baselines:
            times, found = [], []
            for path in images:
                gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
                ms, dets = best_of(detect, gray)
                times.append(ms)
                found.append(dets)
            rows[label] = (times, found, None)
        for label, (times, found, timings) in rows.items():
            recall = "–"
            if refs:
                hit = sum(matched(r, dets) for ref, dets in zip(refs, found) for r in ref)
                total = sum(len(r) for r in refs)
                recall = f"{hit} of {total}"
            rois = passes = "–"
            if timings and all(timings):
                rois = f"{statistics.median(t['proposals'] for t in timings):.0f}"
                passes = f"{statistics.median(t['passes'] for t in timings):.0f}"
            print(f"| {name}, {len(images)} | {label} | {statistics.median(times):.1f} | "
                  f"{min(times):.1f}–{max(times):.1f} | {rois} | {passes} | {recall} | "
                  f"{sum(len(f) for f in found)} |")
    print()
    print("Tagsmith's phases and proposal sources over every photograph above:")
    print_tally(entries_all)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
