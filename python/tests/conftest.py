"""Shared fixtures: the repository's sample photographs and the `tagsmith` command line built by
`cargo test --workspace` (or named by TAGSMITH_BIN), whose output the package must equal."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import tagsmith

REPO = pathlib.Path(__file__).resolve().parents[2]
SAMPLES = sorted((REPO / "assets" / "samples").glob("*.[jp][pn]g"))


def cli_binary() -> pathlib.Path:
    named = os.environ.get("TAGSMITH_BIN")
    if named:
        return pathlib.Path(named)
    for profile in ("debug", "release"):
        candidate = REPO / "target" / profile / "tagsmith"
        if candidate.exists():
            return candidate
    pytest.skip("no tagsmith binary: run `cargo build -p tagsmith-studio` or set TAGSMITH_BIN")


@pytest.fixture(scope="session")
def cli():
    return cli_binary()


def cli_detections(cli, images, tmp_path, *extra):
    """The command line's detections file for `images`, one image at a time."""
    out = tmp_path / "cli.json"
    subprocess.run(
        [str(cli), "detect", "--sequential", "--json", str(out), *extra, *map(str, images)],
        check=True,
        capture_output=True,
    )
    return json.loads(out.read_text())["images"]


@pytest.fixture(scope="session")
def shipped():
    """The default detector (every family with shipped weights), built once."""
    return tagsmith.Detector()


def scene(family="apriltag-36h11", tag_id=3, side=160, at=(200, 120), size=(480, 640)):
    """One upright marker pasted on a plain gray frame."""
    frame = np.full(size, 190, np.uint8)
    marker = tagsmith.Family.load(family).render(tag_id, side)
    y, x = at
    frame[y : y + marker.shape[0], x : x + marker.shape[1]] = marker
    return frame
