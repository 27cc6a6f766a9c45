"""What the scale-out examples share: the images to read and the detections files they write."""

from __future__ import annotations

import json
import pathlib

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm", ".pnm"}


def image_paths(inputs: list[str]) -> list[str]:
    """Every image named or inside a named folder, sorted within each folder."""
    paths: list[str] = []
    for given in inputs:
        path = pathlib.Path(given)
        if path.is_dir():
            paths += sorted(str(p) for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        else:
            paths.append(given)
    return paths


def write(entries: list[dict], output: pathlib.Path, detector_name: str) -> None:
    """JSON lines (one image per line) for `.jsonl`, else one detections file with a `failed` list."""
    if output.suffix == ".jsonl":
        text = "".join(json.dumps(e) + "\n" for e in entries)
    else:
        text = json.dumps(
            {
                "detector": detector_name,
                "images": [e for e in entries if "error" not in e],
                "failed": [e for e in entries if "error" in e],
            },
            indent=2,
        )
    temporary = output.with_name(output.name + ".partial")
    temporary.write_text(text)
    temporary.replace(output)
