#!/usr/bin/env python3
"""Tagsmith's full detector on real photographs, against reference detectors' outputs (there is
no hand-made ground truth): the AprilTag swarmathon JPEGs (AprilTag 36h11; reference: the AprilTag
C library's own regression outputs, `*.txt`) and the OpenCV ArUco tutorial photos (ArUco 6x6_250;
reference: OpenCV's ArucoDetector run here). A reference marker counts as found when Tagsmith
reports its ID with every corner within 3 px (AprilTag's +0.5 px pixel convention undone).

    bench/.venv/bin/python bench/realimages.py REALIMAGES_DIR --tagsmith target/release/tagsmith \
        --annotate docs/detections [--upsample]

`--upsample` passes `detect --upsample` (stage 1 also on the image enlarged twice, for markers
under about 20 px such as the swarmathon's 13-20 px tags).
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

TOLERANCE_PX = 3.0


def swarmathon_reference(txt):
    out = []
    for line in open(txt):
        parts = line.replace("(", " ").replace(")", " ").replace(",", " ").split()
        if len(parts) < 9:
            continue
        values = [float(p) for p in parts[:9]]
        corners = np.array(values[1:9]).reshape(4, 2) - 0.5
        out.append((int(values[0]), corners))
    return out


def opencv_reference(path):
    gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250), params)
    corners, ids, _ = det.detectMarkers(gray)
    if ids is None:
        return []
    return [(int(i), c.reshape(4, 2)) for c, i in zip(corners, ids.flatten())]


def matched(ref, found):
    """Whether a detection has the reference's ID and its corners (any starting corner, either
    winding) within the tolerance."""
    rid, rc = ref
    for d in found:
        if d["id"] != rid:
            continue
        c = np.array(d["corners"])
        for order in (c, c[::-1]):
            for k in range(4):
                if np.max(np.linalg.norm(np.roll(order, k, axis=0) - rc, axis=1)) <= TOLERANCE_PX:
                    return True
    return False


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("realimages")
    ap.add_argument("--tagsmith", required=True)
    ap.add_argument("--annotate", help="folder for annotated images")
    ap.add_argument("--upsample", action="store_true", help="detect --upsample")
    a = ap.parse_args()
    groups = [
        ("apriltag-36h11", sorted(glob.glob(os.path.join(a.realimages, "apriltag_swarmathon", "*.jpg"))),
         lambda p: swarmathon_reference(p[:-4] + ".txt")),
        ("aruco-6x6_250", [os.path.join(a.realimages, "opencv_aruco_tutorial", f) for f in
                           ["singlemarkersoriginal.jpg", "choriginal.jpg", "chocclusion_original.jpg",
                            "img_00.jpg", "img_01.jpg", "img_02.jpg", "img_03.jpg"]],
         opencv_reference),
    ]
    print("| image | family | reference markers | Tagsmith found (of them) | Tagsmith others | time ms |")
    print("|---|---|---|---|---|---|")
    totals = {}
    for family, images, reference in groups:
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "d.json")
            cmd = [a.tagsmith, "detect", *images, "--family", family, "--json", out]
            if a.annotate:
                cmd += ["--annotate", a.annotate]
            if a.upsample:
                cmd.append("--upsample")
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            result = json.load(open(out))
        for path, entry in zip(images, result["images"]):
            ref = reference(path)
            found = sum(matched(r, entry["detections"]) for r in ref)
            others = len(entry["detections"]) - found
            t = totals.setdefault(family, [0, 0, 0])
            t[0] += len(ref)
            t[1] += found
            t[2] += others
            print(f"| {os.path.basename(path)} | {family} | {len(ref)} | {found} | {others} | {entry['time_ms']:.0f} |")
    for family, (n, f, o) in totals.items():
        print(f"| **all** | {family} | {n} | {f} ({100 * f / max(n, 1):.0f} %) | {o} | |")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
