#!/usr/bin/env python3
"""Per-image latency of the Python package against the command line on the same images (issue 46).

Both sides run the same detector one image at a time on the same build profile: the command line
with `detect --sequential` (its per-image `time_ms`, the time around the detector's call), the
package with `Detector.detect` on the image as a NumPy array (the time around the Python call,
so it includes the array's checks, lending it to the detector and the results' conversion). Each
side's time of an image is its best of `--runs` runs, the two sides taking turns; the table gives
both medians and their ratio.

    python bench/python_latency.py --tagsmith target/release/tagsmith IMAGE_OR_DIR ...

Run it from a venv where `tagsmith` was built with `maturin develop --release` (or installed with
`pip install ./python`), or the package's dev build will be compared with a release CLI.
"""

import argparse
import json
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import tagsmith

SUFFIXES = {".png", ".jpg", ".jpeg"}


def images_of(inputs):
    paths = []
    for given in map(pathlib.Path, inputs):
        if given.is_dir():
            paths += sorted(p for p in given.iterdir() if p.suffix.lower() in SUFFIXES)
        else:
            paths.append(given)
    return [str(p) for p in paths]


def cli_pass(binary, families, images):
    with tempfile.TemporaryDirectory() as tmp:
        out = pathlib.Path(tmp) / "d.json"
        flags = [f for name in families for f in ("--family", name)]
        subprocess.run(
            [binary, "detect", "--sequential", *flags, "--json", str(out), *images],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        times = {e["file"]: e["time_ms"] for e in json.loads(out.read_text())["images"]}
    return [times[p] for p in images]


def python_pass(detector, arrays):
    times, found = [], []
    for array in arrays:
        start = time.perf_counter()
        found.append(len(detector.detect(array)))
        times.append((time.perf_counter() - start) * 1e3)
    return times, found


def best_of_alternating(binary, families, images, runs):
    """Each image's best time on each side, the two sides run in turn so that the machine's
    drift (a VM's speed wanders by a third within an hour) falls on both alike."""
    detector = tagsmith.Detector(families=families)
    arrays = [tagsmith.imread(p) for p in images]
    detector.detect(arrays[0])  # the thread pool and allocator warmed, as the CLI's first image
    cli = [float("inf")] * len(images)
    py = [float("inf")] * len(images)
    found = []
    for _ in range(runs):
        cli = list(map(min, cli, cli_pass(binary, families, images)))
        times, found = python_pass(detector, arrays)
        py = list(map(min, py, times))
    return cli, py, found


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("inputs", nargs="+")
    ap.add_argument("--tagsmith", required=True, help="the command line to compare with")
    ap.add_argument("--family", action="append", help="family (repeat); default: every shipped")
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    families = a.family or tagsmith.detectable_families()
    images = images_of(a.inputs)
    cli, py, found = best_of_alternating(a.tagsmith, families, images, a.runs)
    print(f"{len(images)} images, families {', '.join(families)}, best of {a.runs} per image\n")
    print("| image | markers | CLI `--sequential` (ms) | Python `detect` (ms) | Python / CLI |")
    print("|---|---|---|---|---|")
    for path, n, c, p in zip(images, found, cli, py):
        print(f"| {pathlib.Path(path).name} | {n} | {c:.1f} | {p:.1f} | {p / c:.3f} |")
    mc, mp = statistics.median(cli), statistics.median(py)
    ratios = [p / c for c, p in zip(cli, py)]
    print(f"| **median** | | **{mc:.1f}** | **{mp:.1f}** | **{statistics.median(ratios):.3f}** |")
    print(f"\nsum: CLI {sum(cli):.0f} ms, Python {sum(py):.0f} ms ({sum(py) / sum(cli):.3f})")
    if statistics.median(ratios) > 1.05:
        sys.exit("Python's median per-image time is over 5 % above the command line's")


if __name__ == "__main__":
    main()
