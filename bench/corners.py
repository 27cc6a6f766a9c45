#!/usr/bin/env python3
"""Corner accuracy on images that Tagsmith did not render: OpenCV draws an AprilTag 36h11 marker
(`cv2.aruco.generateImageMarker`) and warps it into a 1280×960 view (`cv2.warpPerspective`,
bilinear) with a known homography, so the true corners are exact. AprilTag 3 (pupil-apriltags)
detects each whole image; Tagsmith reads the marker from a ROI made of the true corners moved by
up to ±5 % of the side (standing in for stage 1, as `tagsmith detect-set` does), with each
`--refine` mode.

    bench/.venv/bin/python bench/corners.py --tagsmith target/release/tagsmith -o corners.json

Pixel convention (OpenCV's, Tagsmith's): pixel centres at integer coordinates. In the marker image
OpenCV draws, the marker's outer edge therefore lies at −0.5 and at side − 0.5; the warp maps
pixel centres through the homography, so the true corners are H applied to those points. AprilTag
reports corners 0.5 px further (its pixel centres sit at +0.5): they are moved back, and matched to
the truth in whichever of the four turns fits (AprilTag's IDs are drawn turned from OpenCV's).

Difficulties (20 images each, seeded): clean (marker 150–300 px across, tilt ≤ 45°), noisy
(Gaussian noise σ = 12 gray levels), blurred (Gaussian σ = 1.5 px), motion (7-px line kernel, any
direction), steep (tilt 60–70°), tiny (marker 28–40 px across).
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

from baselines import APRILTAG_OFFSET_PX

CELLS = 8  # black border + 6 × 6 data, as OpenCV draws DICT_APRILTAG_36h11
CELL_PX = 24
PAD_PX = 2 * CELL_PX  # white quiet zone around the drawn marker
W, H = 1280, 960
FOCAL = 1000.0
DIFFICULTIES = ["clean", "noisy", "blurred", "motion", "steep", "tiny"]


def marker_image(marker_id):
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    side = CELLS * CELL_PX
    m = cv2.aruco.generateImageMarker(dictionary, marker_id, side, borderBits=1)
    return cv2.copyMakeBorder(m, PAD_PX, PAD_PX, PAD_PX, PAD_PX, cv2.BORDER_CONSTANT, value=255), side


def rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def view(rng, difficulty, src_side, src_size):
    """Homography source pixels → image pixels for a random view of this difficulty."""
    tilt = math.radians(rng.uniform(60, 70) if difficulty == "steep" else rng.uniform(0, 45))
    across = rng.uniform(28, 40) if difficulty == "tiny" else rng.uniform(150, 300)
    axis_angle = rng.uniform(0, 2 * math.pi)
    r = rotation([math.cos(axis_angle), math.sin(axis_angle), 0], tilt) @ rotation([0, 0, 1], rng.uniform(0, 2 * math.pi))
    # Marker plane: source pixels scaled so the marker is 1 unit across, centred.
    scale = 1.0 / src_side
    centre = (src_size - 1) / 2.0
    a = np.array([[scale, 0, -centre * scale], [0, scale, -centre * scale], [0, 0, 1]])
    distance = FOCAL / across
    t = np.array([rng.uniform(-0.25, 0.25) * W / FOCAL * distance, rng.uniform(-0.25, 0.25) * H / FOCAL * distance, distance])
    k = np.array([[FOCAL, 0, (W - 1) / 2], [0, FOCAL, (H - 1) / 2], [0, 0, 1]])
    return k @ np.column_stack([r[:, 0], r[:, 1], t]) @ a


def apply(h, p):
    q = h @ np.array([p[0], p[1], 1.0])
    return [q[0] / q[2], q[1] / q[2]]


def degrade(rng, img, difficulty):
    img = img.astype(np.float32)
    if difficulty == "noisy":
        img += rng.normal(0, 12, img.shape)
    elif difficulty == "blurred":
        img = cv2.GaussianBlur(img, (0, 0), 1.5)
    elif difficulty == "motion":
        k = np.zeros((7, 7), np.float32)
        angle = rng.uniform(0, math.pi)
        for i in range(-30, 31):
            s = i / 10.0
            x, y = int(round(3 + s * math.cos(angle))), int(round(3 + s * math.sin(angle)))
            k[y, x] = 1
        img = cv2.filter2D(img, -1, k / k.sum())
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def corner_error(found, truth):
    """Mean corner distance in the best of the four turns (both lists TL, TR, BR, BL-like)."""
    best = math.inf
    for turn in range(4):
        for order in (1, -1):
            e = np.mean([np.hypot(*(np.array(found[(order * i + turn) % 4]) - truth[i])) for i in range(4)])
            best = min(best, e)
    return best


def tagsmith(binary, path, roi, refine):
    out = subprocess.run(
        [binary, "detect", path, "--family", "apriltag-36h11", "--refine", refine, "--roi", ",".join(f"{v:.4f}" for p in roi for v in p)],
        capture_output=True, text=True,
    )
    if out.returncode != 0:
        return None
    report = json.loads(out.stdout)
    return report.get("corners") if report.get("decoded") else None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tagsmith", required=True, help="the tagsmith binary")
    ap.add_argument("--per-difficulty", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("-o", "--output", required=True)
    args = ap.parse_args()

    from pupil_apriltags import Detector

    april = Detector(families="tag36h11", nthreads=1, quad_decimate=1.0, refine_edges=1)
    rng = np.random.default_rng(args.seed)
    modes = ["none", "full"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for difficulty in DIFFICULTIES:
            for n in range(args.per_difficulty):
                marker_id = int(rng.integers(0, 587))
                src, side = marker_image(marker_id)
                h = view(rng, difficulty, side, src.shape[0])
                background = np.full((H, W), 128, np.uint8)
                img = cv2.warpPerspective(src, h, (W, H), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_TRANSPARENT, dst=background)
                img = degrade(rng, img, difficulty)
                edge = [PAD_PX - 0.5, PAD_PX + side - 0.5]
                truth = np.array([apply(h, p) for p in [[edge[0], edge[0]], [edge[1], edge[0]], [edge[1], edge[1]], [edge[0], edge[1]]]])
                path = os.path.join(tmp, f"{difficulty}-{n}.png")
                cv2.imwrite(path, img)
                row = {"difficulty": difficulty, "id": marker_id, "truth": truth.tolist()}
                found = [d for d in april.detect(img) if d.tag_id == marker_id]
                row["apriltag"] = corner_error((found[0].corners - APRILTAG_OFFSET_PX).tolist(), truth) if found else None
                s = np.mean([np.hypot(*(truth[i] - truth[(i + 1) % 4])) for i in range(4)])
                roi = [[p[0] + rng.uniform(-0.05, 0.05) * s, p[1] + rng.uniform(-0.05, 0.05) * s] for p in truth]
                for mode in modes:
                    c = tagsmith(args.tagsmith, path, roi, mode)
                    row[f"tagsmith-{mode}"] = corner_error(c, truth) if c else None
                rows.append(row)

    detectors = ["apriltag"] + [f"tagsmith-{m}" for m in modes]
    summary = {}
    print("| difficulty | " + " | ".join(f"{d} found | {d} median / mean px" for d in detectors) + " |")
    for difficulty in DIFFICULTIES:
        line, summary[difficulty] = [], {}
        sub = [r for r in rows if r["difficulty"] == difficulty]
        for d in detectors:
            errors = [r[d] for r in sub if r[d] is not None]
            stats = {"found": len(errors), "of": len(sub), "median_px": float(np.median(errors)) if errors else None, "mean_px": float(np.mean(errors)) if errors else None}
            summary[difficulty][d] = stats
            line.append(f"{len(errors)}/{len(sub)} | " + (f"{stats['median_px']:.3f} / {stats['mean_px']:.3f}" if errors else "–"))
        print(f"| {difficulty} | " + " | ".join(line) + " |")
    tmp_out = args.output + ".tmp"
    with open(tmp_out, "w") as f:
        json.dump({"summary": summary, "rows": rows}, f, indent=1)
    os.replace(tmp_out, args.output)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
    os._exit(0)
