"""The detector on NumPy arrays: the command line's detections, poses, array layouts, bad input."""

import json
import sys
import threading
import time

import numpy as np
import pytest

import tagsmith
from conftest import REPO, SAMPLES, cli_detections, scene


def test_detections_equal_the_command_lines(cli, shipped, tmp_path):
    assert len(SAMPLES) >= 3
    expected = cli_detections(cli, SAMPLES, tmp_path)
    for path, entry in zip(SAMPLES, expected):
        got = shipped.detect(tagsmith.imread(path))
        want = entry["detections"]
        assert [(d.family, d.tag_id) for d in got] == [
            (d["family"], d["id"]) for d in want
        ], path.name
        assert got, f"{path.name}: the sample shows markers"
        for d, w in zip(got, want):
            assert np.abs(d.corners - np.array(w["corners"])).max() < 1e-6
            assert np.abs(d.pose_t.ravel() - np.array(w["pose"]["translation_m"])).max() < 1e-9
            assert json.loads(d.to_json())["id"] == w["id"]


def test_a_marker_reads_with_its_corners_in_opencvs_order():
    frame = scene(tag_id=3, side=200, at=(100, 200))
    [d] = tagsmith.Detector(families=["apriltag-36h11"]).detect(frame)
    assert (d.family, d.tag_id, d.hamming) == ("apriltag-36h11", 3, 0)
    tl, tr, br, bl = d.corners
    assert tl[0] < tr[0] and tl[1] < bl[1] and br[0] > bl[0] and br[1] > tr[1]
    assert np.allclose(d.center, d.corners.mean(axis=0), atol=0.5)
    h = d.homography
    corner = h @ np.array([1.0, 1.0, 1.0])
    assert np.allclose(corner[:2] / corner[2], br, atol=1e-6)
    assert d.keypoints.shape == (64, 2) and d.keypoint_symbols.shape == (64,)
    assert set(d.timings) >= {"propose_ms", "verify_ms", "read_ms", "reconcile_ms"}


def test_pose_follows_the_camera_and_the_tag_size():
    frame = scene(tag_id=7, side=160, at=(160, 240))
    detector = tagsmith.Detector(families=["apriltag-36h11"])
    camera = (600.0, 600.0, 320.0, 240.0)
    [small] = detector.detect(frame, camera_params=camera, tag_size=0.05)
    [large] = detector.detect(frame, camera_params=camera, tag_size=0.10)
    r = small.pose_R
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-9)
    assert small.pose_t.shape == (3, 1) and small.pose_t[2, 0] > 0
    assert np.allclose(large.pose_t, 2 * small.pose_t, rtol=1e-9)
    assert np.allclose(large.pose_R, small.pose_R)
    # The ROI side spans about 160 px / 1.25 (the quiet zone) at f = 600: z ≈ 600·0.05/128.
    assert small.pose_t[2, 0] == pytest.approx(600 * 0.05 / (160 / 1.25), rel=0.1)
    assert small.reprojection_error < 1.0
    rotation_sigma_deg, translation_sigma_m = small.pose_err
    assert rotation_sigma_deg >= 0 and translation_sigma_m >= 0


def test_gray_rgb_and_bgr_read_alike():
    rng = np.random.default_rng(1)
    gray = scene(tag_id=11)
    tint = rng.integers(-20, 21, size=(3,))
    rgb = np.clip(gray[..., None].astype(int) + tint, 0, 255).astype(np.uint8)
    bgr = np.ascontiguousarray(rgb[..., ::-1])
    assert np.array_equal(tagsmith.to_gray(rgb), tagsmith.to_gray(bgr, channels="BGR"))
    assert np.array_equal(tagsmith.to_gray(np.repeat(gray[..., None], 3, axis=2)), gray)
    detector = tagsmith.Detector(families=["apriltag-36h11"])
    ids = lambda found: [(d.tag_id, d.corners.round(6).tolist()) for d in found]
    from_rgb = detector.detect(rgb)
    assert ids(from_rgb) == ids(detector.detect(bgr, channels="BGR"))
    assert ids(from_rgb) == ids(detector.detect(tagsmith.to_gray(rgb)))
    assert [d.tag_id for d in from_rgb] == [11]
    bgr_detector = tagsmith.Detector(families=["apriltag-36h11"], channels="BGR")
    assert ids(bgr_detector.detect(bgr)) == ids(from_rgb)


def test_strided_fortran_and_read_only_arrays_read_as_their_copies():
    frame = scene(tag_id=5)
    detector = tagsmith.Detector(families=["apriltag-36h11"])
    want = [(d.tag_id, d.corners.tolist()) for d in detector.detect(frame)]
    assert want
    wide = np.zeros((frame.shape[0], frame.shape[1] * 2), np.uint8)
    wide[:, ::2] = frame
    strided = wide[:, ::2]
    assert not strided.flags.c_contiguous
    fortran = np.asfortranarray(frame)
    read_only = frame.copy()
    read_only.flags.writeable = False
    for image in (strided, fortran, read_only):
        assert [(d.tag_id, d.corners.tolist()) for d in detector.detect(image)] == want


def test_a_contiguous_array_is_read_in_place_and_let_go():
    frame = scene(tag_id=5)
    detector = tagsmith.Detector(families=["apriltag-36h11"])
    before = sys.getrefcount(frame)
    found = detector.detect(frame)
    detector.detect_arrays(frame)
    detector.detect_batch([frame, frame])
    # The detector held the array while it read it in place, and holds it no longer: a leak
    # would keep every frame of a video alive.
    assert sys.getrefcount(frame) == before
    assert np.array_equal(frame, scene(tag_id=5)), "the caller's pixels are left as they were"
    assert [d.tag_id for d in found] == [5]


@pytest.mark.parametrize(
    "image, message",
    [
        (np.zeros((40, 40), np.float32), "dtype float32 is not uint8"),
        (np.zeros((40, 40, 2), np.uint8), "shape [40, 40, 2]"),
        (np.zeros((40,), np.uint8), "shape [40]"),
        (np.zeros((0, 0), np.uint8), "has no pixels"),
    ],
)
def test_bad_arrays_are_value_errors(shipped, image, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        shipped.detect(image)


def test_a_list_is_a_type_error(shipped):
    with pytest.raises(TypeError, match="numpy.ndarray"):
        shipped.detect([[0, 1], [1, 0]])


def test_bad_settings_name_the_argument():
    with pytest.raises(ValueError, match="camera_params"):
        tagsmith.Detector(families=["apriltag-36h11"], camera=(0, 1, 2, 3))
    with pytest.raises(ValueError, match="tag_size"):
        tagsmith.Detector(families=["apriltag-36h11"]).detect(scene(), tag_size=-1.0)
    with pytest.raises(ValueError, match="refine"):
        tagsmith.Detector(families=["apriltag-36h11"], refine="sideways")
    with pytest.raises(ValueError, match="no weights are shipped"):
        tagsmith.Detector(families=["runetag-plus"])
    with pytest.raises(ValueError, match="no built-in family or file named"):
        tagsmith.Detector(families=["apriltag-99h1"])
    with pytest.raises(ValueError, match="channels"):
        tagsmith.to_gray(np.zeros((4, 4, 3), np.uint8), channels="HSV")
    with pytest.raises(ValueError, match="verifier_threshold"):
        tagsmith.Detector(families=["apriltag-36h11"], verifier_threshold=1.5)


def test_the_verifier_can_be_turned_off():
    """Without the verifier every candidate quad goes to stage 2: the same marker, more passes."""
    on = tagsmith.Detector(families=["apriltag-36h11"])
    off = tagsmith.Detector(families=["apriltag-36h11"], verifier_threshold=0.0)
    read_on, read_off = on.detect(scene()), off.detect(scene())
    assert [d.tag_id for d in read_on] == [d.tag_id for d in read_off] != []
    assert read_off[0].timings["turned_away"] == 0
    assert read_off[0].timings["passes"] >= read_on[0].timings["passes"]


def test_a_family_file_with_its_model_file(tmp_path):
    """A family and a model given by path, as a user's own design and training run are."""
    spec = json.loads((REPO / "families" / "apriltag-36h11.json").read_text())
    spec["title"] = "My copy of AprilTag 36h11"
    family_file = tmp_path / "mine.json"
    family_file.write_text(json.dumps(spec))
    model = REPO / "assets" / "models" / "apriltag-36h11.stage2.bin"
    detector = tagsmith.Detector(families=[str(family_file)], models={"apriltag-36h11": str(model)})
    assert detector.families == ["apriltag-36h11"]
    [d] = detector.detect(scene(tag_id=9))
    assert (d.family, d.tag_id) == ("apriltag-36h11", 9)
    with pytest.raises(FileNotFoundError, match="missing.bin"):
        tagsmith.Detector(
            families=[str(family_file)], models={"apriltag-36h11": str(tmp_path / "missing.bin")}
        )
    # Under another name the same layout reads with the same weights (the codebook decodes).
    spec["name"] = "my-36h11"
    family_file.write_text(json.dumps(spec))
    renamed = tagsmith.Detector(families=[str(family_file)], models={"my-36h11": str(model)})
    [d] = renamed.detect(scene(tag_id=9))
    assert (d.family, d.tag_id) == ("my-36h11", 9)
    # With no model named, the shipped model of its layout reads it: no training.
    [d] = tagsmith.Detector(families=[str(family_file)]).detect(scene(tag_id=9))
    assert (d.family, d.tag_id) == ("my-36h11", 9)
    # A ROI the weights never learned is refused, naming the family they were trained for; and
    # no shipped model has that layout.
    spec["roi"]["margin"] = 0.3
    family_file.write_text(json.dumps(spec))
    with pytest.raises(ValueError, match="no weights are shipped"):
        tagsmith.Detector(families=[str(family_file)])
    with pytest.raises(ValueError, match="trained for family \"apriltag-36h11\""):
        tagsmith.Detector(families=[str(family_file)], models={"my-36h11": str(model)})
    with pytest.raises(ValueError, match="none of the families"):
        tagsmith.Detector(families=["apriltag-36h11"], models={"aruco-6x6_250": str(model)})


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(FileNotFoundError):
        tagsmith.Family.load(str(tmp_path / "nowhere.json"))
    with pytest.raises(FileNotFoundError):
        tagsmith.imread(tmp_path / "nowhere.png")
    broken = tmp_path / "broken.json"
    spec = json.loads((REPO / "families" / "apriltag-36h11.json").read_text())
    spec["layout"] = {"kind": "grid", "size": "six"}
    broken.write_text(json.dumps(spec))
    with pytest.raises(ValueError, match="broken.json") as error:
        tagsmith.Family.load(str(broken))
    assert "layout" in str(error.value)
    not_an_image = tmp_path / "photo.png"
    not_an_image.write_text("hello")
    with pytest.raises(ValueError, match="photo.png"):
        tagsmith.imread(not_an_image)


def test_batch_and_array_forms_agree_with_detect(shipped):
    images = [tagsmith.imread(p) for p in SAMPLES]
    batch = shipped.detect_batch(images)
    for image, found in zip(images, batch):
        single = shipped.detect(image)
        assert [(d.tag_id, d.corners.tolist()) for d in found] == [
            (d.tag_id, d.corners.tolist()) for d in single
        ]
        arrays = shipped.detect_arrays(image, camera_params=(700, 700, 320, 240), tag_size=0.04)
        n = len(single)
        assert arrays["ids"].shape == (n,) and arrays["corners"].shape == (n, 4, 2)
        assert arrays["poses"].shape == (n, 7)
        assert list(arrays["ids"]) == [d.tag_id for d in single]
        quaternions = arrays["poses"][:, 3:]
        assert np.allclose(np.linalg.norm(quaternions, axis=1), 1.0)
    with pytest.raises(ValueError, match=r"images\[1\]"):
        shipped.detect_batch([images[0], np.zeros((3, 3), np.float64)])


def test_two_threads_detect_at_once(shipped):
    """The GIL is released while the detector works: Python code runs meanwhile, and two
    threads sharing one Detector read what one thread alone reads."""
    image = tagsmith.imread(SAMPLES[0])
    shipped.detect(image)
    ticks = 0
    done = threading.Event()

    def work():
        shipped.detect(image)
        done.set()

    worker = threading.Thread(target=work)
    worker.start()
    while not done.is_set():
        ticks += 1
    worker.join()
    assert ticks > 1000, "the interpreter stood still while the detector ran"

    # The detector already spreads one image over every core, so two threads need not finish
    # sooner on a small machine; what a caller relies on is that they may share one Detector.
    alone = [(d.tag_id, d.corners.tolist()) for d in shipped.detect(image)]
    results = [None, None]

    def detect_into(slot):
        results[slot] = [(d.tag_id, d.corners.tolist()) for d in shipped.detect(image)]

    threads = [threading.Thread(target=detect_into, args=(slot,)) for slot in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert alone and results == [alone, alone]


def test_tracker_follows_a_moving_marker():
    detector = tagsmith.Detector(families=["apriltag-36h11"])
    tracker = tagsmith.Tracker(detector, redetect_every=10)
    fulls = []
    for step in range(5):
        found = tracker.track(scene(tag_id=21, at=(120 + 3 * step, 200 + 5 * step)))
        assert [d.tag_id for d in found] == [21]
        assert found[0].corners[0][0] == pytest.approx(200 + 5 * step + 160 / 1.25 * 0.125 + 0.5, abs=3)
        fulls.append(tracker.last_full)
    assert fulls == [True, False, False, False, False]
