"""Detect markers in a folder (or list) of images on Ray: one detector per worker, many images
per call, results in the harness's detections format.

    python ray_detect.py PHOTOS/ -o detections.jsonl --workers 2
    python ray_detect.py a.jpg b.png -o detections.json   # one file `tagsmith eval score` reads

On a cluster, start Ray there and pass its address (`--address ray://head:10001`, or `auto` on a
node of it); the images must be readable at the same paths on every node (a shared file system),
since each worker reads its own. GPU actors are not handled: the detector runs on CPU cores.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
from typing import Any

import ray

import tagsmith
from batch_io import image_paths, write

class Detect:
    """A Ray actor's callable: builds its detector once, then reads every batch it is given."""

    def __init__(self, families: list[str] | None = None, models: dict[str, str] | None = None):
        self.detector = tagsmith.Detector(families=families, models=models)

    def __call__(self, batch: dict[str, Any]) -> dict[str, list]:
        files, records = [], []
        for path in batch["path"]:
            path = str(path)
            start = time.perf_counter()
            try:
                found = self.detector.detect(tagsmith.imread(path))
                entry = {
                    "file": path,
                    "time_ms": (time.perf_counter() - start) * 1e3,
                    "detections": [json.loads(d.to_json()) for d in found],
                }
            except (ValueError, FileNotFoundError) as error:
                entry = {"file": path, "error": str(error)}
            files.append(path)
            records.append(json.dumps(entry))
        return {"path": files, "record": records}


def detect(paths: list[str], workers: int, batch_size: int, families=None, models=None):
    """The harness entry of every image (in the order given; `error` instead of detections for
    an image that could not be read)."""
    # Workers import `tagsmith` from their own environment, but not this script: send its
    # callable by value, so the same code runs from a notebook, a test or another folder.
    if __name__ != "__main__":
        ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    dataset = ray.data.from_items([{"path": p} for p in paths])
    results = dataset.map_batches(
        Detect,
        fn_constructor_kwargs={"families": families, "models": models},
        concurrency=workers,
        batch_size=batch_size,
        batch_format="numpy",
    )
    by_path = {row["path"]: json.loads(row["record"]) for row in results.iter_rows()}
    return [by_path[p] for p in paths]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="+", help="images or folders of images")
    parser.add_argument("-o", "--output", type=pathlib.Path, required=True, help=".jsonl or .json")
    parser.add_argument("--family", action="append", help="family name or file (repeat)")
    parser.add_argument("--workers", type=int, default=2, help="detector actors (one core each)")
    parser.add_argument("--batch-size", type=int, default=8, help="images per call of an actor")
    parser.add_argument("--address", help="an existing Ray cluster (default: start one here)")
    args = parser.parse_args(argv)
    paths = image_paths(args.inputs)
    # One core per actor: Ray scales by actors, and each detector's own thread pool would
    # otherwise spread over every core of its node and contend with its neighbours.
    runtime_env = {"env_vars": {"RAYON_NUM_THREADS": "1"}}
    if args.address:
        ray.init(address=args.address, runtime_env=runtime_env)
    else:
        ray.init(num_cpus=args.workers, include_dashboard=False, runtime_env=runtime_env)
    try:
        start = time.perf_counter()
        entries = detect(paths, args.workers, args.batch_size, families=args.family)
        elapsed = time.perf_counter() - start
    finally:
        ray.shutdown()
    families = args.family or tagsmith.detectable_families()
    write(entries, args.output, f"Tagsmith ({', '.join(families)})")
    print(f"{len(paths)} images in {elapsed:.1f} s on {args.workers} workers -> {args.output}")


if __name__ == "__main__":
    main()
