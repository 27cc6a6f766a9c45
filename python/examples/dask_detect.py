"""The same on Dask: a bag of paths, one detector per partition.

    python dask_detect.py PHOTOS/ -o detections.jsonl --workers 2
"""

from __future__ import annotations

import argparse
import json
import pathlib

import dask.bag as db

import tagsmith
from batch_io import image_paths, write


def detect_partition(paths, families=None):
    detector = tagsmith.Detector(families=families)  # once per partition, not per image
    return [
        {"file": p, "detections": [json.loads(d.to_json()) for d in detector.detect(tagsmith.imread(p))]}
        for p in paths
    ]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="+")
    parser.add_argument("-o", "--output", type=pathlib.Path, required=True)
    parser.add_argument("--family", action="append")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    paths = image_paths(args.inputs)
    bag = db.from_sequence(paths, npartitions=max(1, args.workers * 2))
    entries = bag.map_partitions(detect_partition, families=args.family).compute(
        scheduler="processes", num_workers=args.workers
    )
    families = args.family or tagsmith.detectable_families()
    write(entries, args.output, f"Tagsmith ({', '.join(families)})")
    print(f"{len(paths)} images -> {args.output}")


if __name__ == "__main__":
    main()
