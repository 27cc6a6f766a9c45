#!/usr/bin/env python3
"""Rotation-error percentiles (pose flips show here, not in means) of a detections file against a
Tagsmith benchmark set, for the protocol's Normal and Difficult images.

    bench/.venv/bin/python bench/percentiles.py SET_DIR DETECTIONS.json
"""

import json
import math
import os
import sys

import numpy as np


def rotation_errors(set_dir, detections, normal):
    with open(os.path.join(set_dir, "set.json")) as f:
        truth = {im["file"]: im for im in json.load(f)["images"]}
    errors = []
    for im in detections["images"]:
        t = truth[im["file"]]
        g = t["group"]
        if g.get("kind") != "protocol" or bool(g.get("normal")) != normal:
            continue
        for det in im["detections"]:
            for m in t["truth"]["markers"]:
                if m["id"] != det["id"] or "pose" not in det:
                    continue
                r = np.array(det["pose"]["rotation"]).T @ np.array(m["pose"]["rotation"])
                errors.append(math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(r) - 1) / 2)))))
    return errors


def main():
    set_dir, path = sys.argv[1], sys.argv[2]
    with open(path) as f:
        detections = json.load(f)
    for label, normal in (("normal", True), ("difficult", False)):
        e = rotation_errors(set_dir, detections, normal)
        if not e:
            print(f"{label}: no poses in the file (the scorer solves them from the corners)")
            continue
        print(f"{label}: rotation error p99 {np.percentile(e, 99):.3f}°, max {max(e):.3f}° over {len(e)}")


if __name__ == "__main__":
    main()
