#!/usr/bin/env python3
"""Photographs of 1 to 64 megapixels for bench/memory.sh: the AprilTag swarmathon sample
(assets/samples, 799×533, 44 tags of 13–20 px) tiled edge to edge to each size, so the clutter and
the markers per megapixel stay those of a real photograph while the size grows. JPEG, quality 92.

    bench/.venv/bin/python bench/memory.py OUT_DIR 1 4 16 24 64
"""

import os
import sys

import cv2
import numpy as np


def main():
    out = sys.argv[1]
    sizes = [float(s) for s in sys.argv[2:]] or [1, 4, 16, 24, 48, 64]
    here = os.path.dirname(os.path.abspath(__file__))
    photo = cv2.imread(os.path.join(here, "../assets/samples/apriltag-36h11-swarmathon.jpg"))
    h, w = photo.shape[:2]
    os.makedirs(out, exist_ok=True)
    for mp in sizes:
        # 3:2, the shape of most camera sensors.
        width = int(round((mp * 1e6 * 1.5) ** 0.5))
        height = int(round(mp * 1e6 / width))
        reps = (-(-height // h), -(-width // w), 1)
        image = np.tile(photo, reps)[:height, :width]
        name = os.path.join(out, f"{mp:g}mp.jpg")
        cv2.imwrite(name, image, [cv2.IMWRITE_JPEG_QUALITY, 92])
        print(name, f"{width}x{height}")


if __name__ == "__main__":
    main()
