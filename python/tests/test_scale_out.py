"""The Ray and Dask examples on a local cluster give the command line's detections."""

import json
import pathlib
import shutil
import subprocess
import sys

import pytest

from conftest import SAMPLES, cli_detections

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"
sys.path.insert(0, str(EXAMPLES))


@pytest.fixture(scope="module")
def twenty_images(cli, tmp_path_factory):
    """The three sample photographs and 17 synthesised camera scenes."""
    folder = tmp_path_factory.mktemp("images")
    synth = folder / "synth"
    subprocess.run(
        [str(cli), "synth", "apriltag-36h11", "--mode", "camera", "--width", "640",
         "--height", "480", "-n", "17", "--seed", "46", "-o", str(synth)],
        check=True,
        capture_output=True,
    )
    for sample in SAMPLES:
        shutil.copy(sample, folder / sample.name)
    paths = sorted(str(p) for p in folder.iterdir() if p.is_file())
    paths += sorted(str(p) for p in synth.glob("*.png") if not p.name.startswith("contact"))
    assert len(paths) == 20, paths
    return paths


def by_file(entries):
    return {
        pathlib.Path(e["file"]).name: [(d["family"], d["id"], d["corners"]) for d in e["detections"]]
        for e in entries
    }


def assert_same(got, want):
    assert set(got) == set(want)
    for name, found in want.items():
        assert [(f, i) for f, i, _ in got[name]] == [(f, i) for f, i, _ in found], name
        for (_, _, a), (_, _, b) in zip(got[name], found):
            assert max(abs(p - q) for pa, pb in zip(a, b) for p, q in zip(pa, pb)) < 1e-6


def test_ray_example_equals_the_command_line(cli, twenty_images, tmp_path):
    ray = pytest.importorskip("ray")
    pytest.importorskip("ray.data")
    import ray_detect

    want = by_file(cli_detections(cli, twenty_images, tmp_path))
    assert sum(len(v) for v in want.values()) >= 20
    output = tmp_path / "ray.jsonl"
    ray_detect.main([*twenty_images, "-o", str(output), "--workers", "2", "--batch-size", "4"])
    assert not ray.is_initialized()
    entries = [json.loads(line) for line in output.read_text().splitlines()]
    assert [e["file"] for e in entries] == twenty_images
    assert_same(by_file(entries), want)


def test_dask_example_equals_the_command_line(cli, twenty_images, tmp_path):
    pytest.importorskip("dask.bag")
    import dask_detect

    want = by_file(cli_detections(cli, twenty_images, tmp_path))
    output = tmp_path / "dask.json"
    dask_detect.main([*twenty_images, "-o", str(output), "--workers", "2"])
    written = json.loads(output.read_text())
    assert written["failed"] == []
    assert_same(by_file(written["images"]), want)
