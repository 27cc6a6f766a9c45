#!/usr/bin/env python3
"""How many of a benchmark set's markers any cell-sampling detector could read.

For each protocol marker, an oracle that knows every data cell's true centre and its true bit
samples the image there (bilinear) and picks the one threshold that misclassifies the fewest cells.
A marker whose best threshold still leaves more bit errors than the family corrects (`--limit`) is
not readable by thresholding its cells: this bounds what recall a detector can reach on the
Difficult subset (a detector that deblurs could do better, none of the three here does).

Optionally crosses the oracle with detection files (`name=file.json`): which detector read which
marker (same ID, corners within 5 px mean).

    bench/.venv/bin/python bench/readability.py SET_DIR --limit 5 [apriltag=at.json tagsmith=ts.json]
"""
import argparse
import json
import os

import cv2
import numpy as np


def sample(image, x, y):
    # Bilinear, in pixel-centre coordinates, as the synthesiser's truth is.
    patch = cv2.getRectSubPix(image, (1, 1), (float(x), float(y)))
    return float(patch[0, 0])


def best_threshold_errors(values, bits):
    order = np.argsort(values)
    v, b = np.asarray(values)[order], np.asarray(bits)[order]
    ones_total = int(b.sum())
    best = len(v)
    ones_below = 0
    # Threshold between position i-1 and i: below = 0 (dark), above = 1; either polarity.
    for i in range(len(v) + 1):
        zeros_above = (len(v) - i) - (ones_total - ones_below)
        errors = ones_below + zeros_above
        best = min(best, errors, len(v) - errors)
        if i < len(v):
            ones_below += int(b[i])
    return best


def widths(roi):
    pts = np.asarray(roi, dtype=float)
    sides = [np.linalg.norm(pts[(i + 1) % 4] - pts[i]) for i in range(4)]
    return min(sides), max(sides)


def found(dets, marker):
    truth = np.asarray(marker["roi"][:4], dtype=float)
    for d in dets:
        if d.get("id") != marker["id"]:
            continue
        corners = np.asarray(d["corners"][:4], dtype=float)
        if np.linalg.norm(corners - truth, axis=1).mean() < 5.0:
            return True
    return False


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("set_dir")
    ap.add_argument("--limit", type=int, required=True, help="bit errors the family corrects")
    ap.add_argument("detections", nargs="*", help="name=detections.json")
    args = ap.parse_intermixed_args()
    bench = json.load(open(os.path.join(args.set_dir, "set.json")))
    runs = {}
    for item in args.detections:
        name, path = item.split("=", 1)
        runs[name] = {i["file"]: i["detections"] for i in json.load(open(path))["images"]}

    rows = []
    for img in bench["images"]:
        group = img["group"]
        if group["kind"] != "protocol":
            continue
        image = cv2.imread(os.path.join(args.set_dir, img["file"]), cv2.IMREAD_GRAYSCALE)
        image = image.astype(np.float32)
        for m in img["truth"]["markers"]:
            cells = [k for k in m["keypoints"] if k.get("symbol") is not None]
            values = [sample(image, k["x"], k["y"]) for k in cells]
            bits = [k["symbol"] for k in cells]
            errors = best_threshold_errors(values, bits)
            narrow, long = widths(m["roi"])
            read = {n: found(r.get(img["file"], []), m) for n, r in runs.items()}
            rows.append((group, errors, narrow, long, read, img["file"]))

    for subset, normal in (("normal", True), ("difficult", False)):
        sub = [r for r in rows if r[0]["normal"] == normal]
        ok = sum(r[1] <= args.limit for r in sub)
        line = f"{subset}: {len(sub)} markers, oracle-readable {ok} ({100 * ok / max(len(sub), 1):.1f} %)"
        for n in runs:
            line += f"; {n} {sum(r[4][n] for r in sub)}"
        print(line)
    print("markers the oracle cannot read or some detector missed:")
    for group, errors, narrow, long, read, file in rows:
        if errors > args.limit or not all(read.values()):
            got = " ".join(f"{n}={'y' if v else 'n'}" for n, v in read.items())
            print(
                f"  {file}: {group['distance_cm']} cm {group['angle_deg']}°, ROI sides "
                f"{narrow:.0f}–{long:.0f} px, oracle bit errors {errors} {got}"
            )


if __name__ == "__main__":
    main()
