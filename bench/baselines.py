#!/usr/bin/env python3
"""Runs established detectors on a Tagsmith benchmark set and writes their detections in the
format `tagsmith eval score` reads (see core/src/eval/mod.rs).

    bench/setup.sh                       # once: bench/.venv with opencv-contrib and pupil-apriltags
    bench/.venv/bin/python bench/baselines.py SET_DIR --detector opencv -o opencv.json
    bench/.venv/bin/python bench/baselines.py SET_DIR --detector apriltag -o apriltag.json
    tagsmith eval score SET_DIR opencv.json
    bench/.venv/bin/python bench/baselines.py --detectors FAMILY   # which of them read FAMILY

Conventions are normalised to Tagsmith's (= OpenCV's): corners are the outer black square's TL,
TR, BR, BL as OpenCV renders the marker, pixel centres at integer coordinates. OpenCV's ArUco
already reports that. AprilTag 3 reports corners 0.5 px off (its pixel-centre convention) and
starts them at a different corner because the AprilTag library draws each ID turned 180° from
OpenCV and lists them in the other winding; both are undone below with constants measured
against Tagsmith's ground truth (see APRILTAG_TO_TAGSMITH).
"""

import argparse
import json
import os
import sys
import time

import cv2
import numpy as np

# Tagsmith family name -> (OpenCV dictionary, AprilTag 3 family).
FAMILIES = {
    "apriltag-16h5": ("DICT_APRILTAG_16h5", "tag16h5"),
    "apriltag-25h9": ("DICT_APRILTAG_25h9", "tag25h9"),
    "apriltag-36h11": ("DICT_APRILTAG_36h11", "tag36h11"),
    "aruco-4x4_50": ("DICT_4X4_50", None),
    "aruco-5x5_100": ("DICT_5X5_100", None),
    "aruco-6x6_250": ("DICT_6X6_250", None),
    "aruco-mip-36h12": ("DICT_ARUCO_MIP_36h12", None),
    "apriltag-standard41h12": (None, "tagStandard41h12"),
    "apriltag-circle21h7": (None, "tagCircle21h7"),
}

# AprilTag corner k is Tagsmith corner APRILTAG_TO_TAGSMITH[k], and AprilTag's corners sit +0.5 px
# from the pixel-centre convention. Both measured on `tagsmith synth apriltag-36h11 --mode camera
# --no-augment` images against their ground truth: the same permutation on every tag, mean offset
# (+0.49, +0.50) px. (AprilTag lists the corners in the other winding.)
APRILTAG_TO_TAGSMITH = [1, 0, 3, 2]
APRILTAG_OFFSET_PX = 0.5


def opencv_detector(dictionary):
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)), params)

    def detect(gray):
        corners, ids, _ = detector.detectMarkers(gray)
        if ids is None:
            return []
        return [
            {"id": int(i), "corners": [[float(x), float(y)] for x, y in c.reshape(4, 2)]}
            for c, i in zip(corners, ids.flatten())
        ]

    return detect


def apriltag_detector(family):
    from pupil_apriltags import Detector

    detector = Detector(families=family, nthreads=1, quad_decimate=1.0, refine_edges=1)

    def detect(gray):
        out = []
        for d in detector.detect(gray):
            corners = [None] * 4
            for k, (x, y) in enumerate(d.corners):
                corners[APRILTAG_TO_TAGSMITH[k]] = [float(x) - APRILTAG_OFFSET_PX, float(y) - APRILTAG_OFFSET_PX]
            out.append({"id": int(d.tag_id), "corners": corners})
        return out

    return detect


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("set_dir")
    ap.add_argument("--detector", choices=["opencv", "apriltag"], required=True)
    ap.add_argument("-o", "--output", required=True)
    args = ap.parse_args()

    with open(os.path.join(args.set_dir, "set.json")) as f:
        manifest = json.load(f)
    family = manifest["family"]
    if family not in FAMILIES:
        sys.exit(f"{family}: no baseline detector knows this family (known: {', '.join(FAMILIES)})")
    dictionary, april = FAMILIES[family]
    if args.detector == "opencv":
        if dictionary is None:
            sys.exit(f"{family}: OpenCV has no such dictionary")
        detect, name = opencv_detector(dictionary), f"OpenCV {cv2.__version__} ArUco ({dictionary}, subpix)"
    else:
        if april is None:
            sys.exit(f"{family}: AprilTag 3 has no such family")
        detect, name = apriltag_detector(april), f"AprilTag 3 (pupil-apriltags, {april})"

    images = []
    for img in manifest["images"]:
        gray = cv2.imread(os.path.join(args.set_dir, img["file"]), cv2.IMREAD_GRAYSCALE)
        if gray is None:
            sys.exit(f"{img['file']}: cannot read the image")
        start = time.perf_counter()
        detections = detect(gray)
        elapsed = (time.perf_counter() - start) * 1e3
        images.append({"file": img["file"], "time_ms": elapsed, "detections": detections})

    tmp = args.output + ".tmp"
    with open(tmp, "w") as f:
        json.dump({"detector": name, "images": images}, f)
    os.replace(tmp, args.output)
    print(f"{name}: {sum(len(i['detections']) for i in images)} detections in {len(images)} images -> {args.output}")
    sys.stdout.flush()
    # pupil-apriltags sometimes crashes in its detector's destructor, after the results are
    # safely written; leave without running destructors so the exit status reports success.
    # Here, while `detect` still holds the detector: when main() returned, the detector was
    # freed first and the crash came before the exit below (2 segfaults in 8 runs, 2026-12-02).
    os._exit(0)


def detectors(family):
    """The baselines that read `family`, the first its own (AprilTag 3 where it has the family)."""
    if family not in FAMILIES:
        return []
    dictionary, april = FAMILIES[family]
    return (["apriltag"] if april else []) + (["opencv"] if dictionary else [])


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--detectors":
        print(" ".join(detectors(sys.argv[2])))
    else:
        main()
