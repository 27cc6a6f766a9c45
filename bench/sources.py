#!/usr/bin/env python3
"""What each of the detector's proposal sources cost and read, summed over the images of one or
more detections files that carry Tagsmith's per-image `timings` (`tagsmith detect --json`,
`tagsmith detect-set --full`). The sources run in order and each skips what the ones before it
read, so a source's "markers read" are markers no earlier source read (before the reconcile
phase): what the detector would lose without it, unless a later source picked them up.

    python3 bench/sources.py DETECTIONS.json [...]
"""

import json
import sys

SOURCES = ["stage1", "rings", "outline", "traced", "close-look", "stretched-look", "corner-quads",
           "edge-refits", "cell-reads"]


def print_tally(entries):
    """The per-phase line and the per-source table for detections-file `images` entries."""
    totals = {s: [0.0, 0, 0, 0] for s in SOURCES}
    phases = [0.0, 0.0, 0.0, 0.0]
    images = passes = rois = 0
    for image in entries:
        t = image.get("timings")
        if not t:
            continue
        images += 1
        passes += t["passes"]
        rois += t["proposals"]
        for k, key in enumerate(["propose_ms", "verify_ms", "read_ms", "reconcile_ms"]):
            phases[k] += t[key]
        for s, tally in zip(SOURCES, t["sources"]):
            acc = totals[s]
            acc[0] += tally["propose_ms"] + tally["read_ms"]
            acc[1] += tally["proposals"]
            acc[2] += tally["reads"]
            acc[3] += tally["found"]
    if not images:
        return False
    n = images
    print(f"{images} images: per image propose {phases[0] / n:.1f} ms, verify {phases[1] / n:.1f} ms, "
          f"read {phases[2] / n:.1f} ms, reconcile {phases[3] / n:.2f} ms; {rois / n:.1f} ROIs, "
          f"{passes / n:.1f} stage-2 passes")
    print("| proposal source | ms per image | quads proposed | stage-2 reads | markers read |")
    print("|---|---|---|---|---|")
    for s, (ms, proposed, reads, found) in totals.items():
        print(f"| {s} | {ms / n:.1f} | {proposed} | {reads} | {found} |")
    return True


def main():
    entries = [image for path in sys.argv[1:] for image in json.load(open(path))["images"]]
    if not print_tally(entries):
        sys.exit("no image with Tagsmith's timings in " + " ".join(sys.argv[1:]))


if __name__ == "__main__":
    main()
