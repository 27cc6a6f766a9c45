"""Type stubs for ``tagsmith._tagsmith``, the Rust (pyo3) extension module.

The detector on NumPy arrays, marker families, rendering and printable sheets. The ``tagsmith``
package re-exports everything here.

Conventions:

* Images are ``numpy.ndarray`` of ``uint8``: H×W (gray), H×W×1, H×W×3 or H×W×4 (colour, in the
  ``channels`` order, "RGB" or "BGR"; alpha is composited over white paper). Contiguous,
  strided, Fortran-ordered and read-only arrays are all accepted. A C-contiguous gray array is
  read in place, without a copy (do not write to it while a detector reads it); other layouts
  are copied once, and colour is converted to gray.
* Pixel coordinates are (x, y) with the origin at the top-left pixel's corner, x right, y down.
* Corners follow OpenCV's order: top-left, top-right, bottom-right, bottom-left of the upright
  marker (clockwise in the image).
* ``camera_params`` is ``(fx, fy, cx, cy)`` in pixels (pinhole, no distortion); ``tag_size`` is
  the marker side (ROI corner to corner) in metres.
* Bad input raises ``ValueError`` (``TypeError`` for an image that is not a ``numpy.ndarray``,
  ``FileNotFoundError`` for a path that does not exist) with the message the command line
  prints; an internal fault raises ``RuntimeError``, never a crash.
"""

from __future__ import annotations

import os
import pathlib
from typing import (
    Any,
    Dict,
    Iterable,
    List,
    Mapping,
    Optional,
    Sequence,
    Tuple,
    TypedDict,
    Union,
    final,
)

import numpy as np
from numpy.typing import NDArray

_StrPath = Union[str, "os.PathLike[str]"]
_Image = NDArray[np.uint8]
_CameraParams = Tuple[float, float, float, float]

__version__: str
"""The package's version (the Rust crate's)."""

class _Scores(TypedDict):
    """``Detection.scores``: how sure the detector is of a marker."""

    roi: float
    """Stage 1's ROI score (mean corner confidence × mask cover), 0–1."""
    keypoints: float
    """Mean confidence of the keypoints stage 2 matched to the template, 0–1."""
    corrected_errors: int
    """Symbols the codebook corrected (the Hamming distance)."""
    reprojection_rms_px: Optional[float]
    """RMS reprojection error of the pose, pixels; ``None`` without a pose."""
    cell_read: bool
    """Whether the code was read from the cells straight off the image rather than by stage 2."""

class _DetectionArrays(TypedDict):
    """``Detector.detect_arrays``: one image's N detections as arrays, in the same order."""

    ids: NDArray[np.int64]
    """(N,) int64: each marker's ID."""
    families: List[str]
    """N family names."""
    corners: NDArray[np.float64]
    """(N, 4, 2) float64, pixels: corners in OpenCV's order (see ``Detection.corners``)."""
    poses: NDArray[np.float64]
    """(N, 7) float64: translation x, y, z (metres, camera frame) then the rotation's quaternion
    x, y, z, w; a row of NaN where a marker has no pose."""
    hamming: NDArray[np.int64]
    """(N,) int64: symbols the codebook corrected."""

@final
class Detection:
    """A marker the detector read (pupil-apriltags' fields, plus keypoints, scores and timings).

    Made by ``Detector.detect``, ``Detector.detect_batch`` and ``Tracker.track``; not
    constructible from Python. Immutable; each array property returns a fresh copy.
    """

    @property
    def family(self) -> str:
        """The family's name, e.g. ``"apriltag-36h11"``."""
    @property
    def tag_id(self) -> int:
        """The marker's ID in its family's codebook."""
    @property
    def corners(self) -> NDArray[np.float64]:
        """4×2 float64, pixels: the marker's ROI corners in OpenCV's order (top-left, top-right,
        bottom-right, bottom-left of the upright marker; clockwise in the image)."""
    @property
    def center(self) -> NDArray[np.float64]:
        """(2,) float64, pixels: the ROI's centre, where its homography maps the square's centre
        (the corners' mean for a degenerate quad)."""
    @property
    def hamming(self) -> int:
        """Symbols the codebook corrected (0: read exactly)."""
    @property
    def scores(self) -> _Scores:
        """A new dict: ``roi`` (stage 1's score, 0–1), ``keypoints`` (mean keypoint confidence,
        0–1), ``corrected_errors`` (int), ``reprojection_rms_px`` (float or ``None``) and
        ``cell_read`` (bool)."""
    @property
    def keypoints(self) -> NDArray[np.float64]:
        """N×2 float64, pixels (x, y): every keypoint stage 2 matched to the family's template."""
    @property
    def keypoint_symbols(self) -> NDArray[np.int64]:
        """(N,) int64: each keypoint's code symbol, −1 for a fixed (non-code) pattern."""
    @property
    def keypoint_indices(self) -> NDArray[np.int64]:
        """(N,) int64: each keypoint's index in the family's keypoint list."""
    @property
    def keypoint_confidences(self) -> NDArray[np.float64]:
        """(N,) float64: each keypoint's confidence, 0–1."""
    @property
    def homography(self) -> Optional[NDArray[np.float64]]:
        """3×3 float64 (normalised so that ``H[2, 2] == 1``): maps the square (−1, −1), (1, −1),
        (1, 1), (−1, 1) onto ``corners`` (AprilTag's convention); ``None`` for a degenerate
        quad."""
    @property
    def pose_R(self) -> Optional[NDArray[np.float64]]:
        """3×3 float64: the rotation from the marker's frame (origin at its centre, x to the right
        and y up along the upright marker, z out of it towards the camera) to the camera's
        (OpenCV's: x right, y down, z forward); ``None`` without a pose (no ``camera_params``)."""
    @property
    def pose_t(self) -> Optional[NDArray[np.float64]]:
        """3×1 float64, metres: the marker's centre in the camera's frame (scaled to
        ``tag_size`` when given); ``None`` without a pose."""
    @property
    def pose_err(self) -> Optional[Tuple[float, float]]:
        """The pose's 1σ from the reprojection residuals: (rotation in degrees, translation in
        metres); ``None`` without a pose."""
    @property
    def pose_ambiguity(self) -> Optional[float]:
        """The other planar pose's reprojection RMS over this one's (near 1: the tilt's sign is
        uncertain); ``None`` when there is one minimum or no pose."""
    @property
    def reprojection_error(self) -> Optional[float]:
        """RMS reprojection error of the pose over all keypoints, pixels; ``None`` without a
        pose."""
    @property
    def timings(self) -> Dict[str, Any]:
        """A new dict of the image's per-phase times and counts (shared by its detections):
        ``propose_ms``, ``verify_ms``, ``read_ms``, ``reconcile_ms`` (milliseconds),
        ``proposals``, ``turned_away`` (quads the verifier sent to no stage-2 read), ``reads``,
        ``passes`` and ``sources`` (one dict per proposal source)."""
    def to_json(self) -> str:
        """The detection as one JSON object, the record ``tagsmith detect --json`` writes (the
        evaluation harness's format)."""
    def __repr__(self) -> str: ...

@final
class Detector:
    """Finds and reads markers of the given families in images: the command line's detector
    (stage 1 proposes marker ROIs, stage 2 reads each one's keypoints and ID, the pose comes
    from all keypoints), built once. Immutable and thread-safe; detection releases the GIL.
    """

    def __init__(
        self,
        families: Optional[Sequence[str]] = None,
        models: Optional[Mapping[str, _StrPath]] = None,
        stage1: Optional[_StrPath] = None,
        camera: Optional[_CameraParams] = None,
        channels: str = "RGB",
        iterations: int = 2,
        refine: str = "full",
        corner_threshold: Optional[float] = None,
        verifier_threshold: Optional[float] = None,
        upsample: bool = False,
        image_searches: bool = True,
        cell_reads: bool = True,
        edge_fits: bool = True,
    ) -> None:
        """Loads the networks and families.

        Args:
            families: built-in family names or family JSON file paths (as ``tagsmith
                --family``); default: ``apriltag-36h11``, ``apriltag-xo-36h11`` and
                ``aruco-6x6_250``, as the CLI; any other of ``detectable_families()`` (such as
                ``artoolkitplus-bch``) when named.
            models: a dict from family name to its stage-2 model file, for families without
                shipped weights or to replace them.
            stage1: a stage-1 model file; default: the shipped one.
            camera: default ``camera_params`` (fx, fy, cx, cy), pixels, for every call.
            channels: the default order of a colour image's last axis, ``"RGB"`` or ``"BGR"``
                (``"RGBA"``/``"BGRA"`` alike; case-insensitive).
            iterations: stage-2 passes per ROI, 1 to 10.
            refine: ``"none"`` (the network's keypoints as they are), ``"keypoints"`` (re-fitted
                with the family's geometry) or ``"full"`` (aligned with the rendering of the
                decoded ID).
            corner_threshold: stage 1's corner confidence for grouping quads, in (0, 1)
                (default 0.3).
            verifier_threshold: the learned verifier's threshold, in [0, 1) (default 0.5):
                candidate quads it scores below this get no stage-2 read (families whose
                markers sit on a dark frame); 0 sends every quad to stage 2.
            upsample: also run stage 1 on the image enlarged twice (one more level, four times
                the first level's cost), for markers down to about 10 px wide.
            image_searches: run the searches for quads the network's grouping misses (outlined
                and traced quads, closer and stretched looks).
            cell_reads: read the cells of ROIs stage 2 reads nothing from straight off the image
                (flat-celled families only).
            edge_fits: read quads whose corners the image's edges confirm, and re-read ROIs
                once their sides are fitted to those edges.

        Raises:
            ValueError: an empty ``families``, an unknown family, a family without shipped
                weights and no model, a malformed family or model file, a ``models`` key that
                names none of the families, non-positive or non-finite ``camera``, a bad
                ``channels``, ``refine``, ``iterations``, ``corner_threshold`` or
                ``verifier_threshold``.
            FileNotFoundError: a family, model or stage-1 file that does not exist.
            TypeError: an argument of the wrong type (e.g. ``families`` given as one ``str``).
        """
    @property
    def families(self) -> List[str]:
        """The names of the families this detector reads."""
    def detect(
        self,
        image: _Image,
        camera_params: Optional[_CameraParams] = None,
        tag_size: Optional[float] = None,
        channels: Optional[str] = None,
    ) -> List[Detection]:
        """The markers in one image (the GIL is released while the detector works).

        Args:
            image: ``uint8`` H×W gray, or H×W×3 / H×W×4 colour in ``channels`` order.
            camera_params: (fx, fy, cx, cy), pixels; default: the detector's ``camera``. Without
                either, detections have no pose.
            tag_size: the marker side (ROI corner to corner), metres; scales ``pose_t``.
                Default: each family's printed ``marker_side_mm``.
            channels: ``"RGB"`` or ``"BGR"`` for this call; default: the detector's.

        Raises:
            TypeError: ``image`` is not a ``numpy.ndarray``.
            ValueError: a dtype other than ``uint8``, a bad shape, an empty or too large image
                (over 64 M pixels), bad ``camera_params``, a non-positive ``tag_size`` or a bad
                ``channels``.
            RuntimeError: an internal error.
        """
    def detect_batch(
        self,
        images: Iterable[_Image],
        camera_params: Optional[_CameraParams] = None,
        tag_size: Optional[float] = None,
        channels: Optional[str] = None,
    ) -> List[List[Detection]]:
        """The markers in each of several images, in their order, detected on every core in
        parallel (the GIL released); arguments as ``detect``, applied to every image.

        Raises:
            TypeError: ``images`` is not iterable, or one of them is not a ``numpy.ndarray``.
            ValueError: as ``detect``; an image's message starts with ``images[i]:``.
            RuntimeError: an internal error.
        """
    def detect_arrays(
        self,
        image: _Image,
        camera_params: Optional[_CameraParams] = None,
        tag_size: Optional[float] = None,
        channels: Optional[str] = None,
    ) -> _DetectionArrays:
        """The detections of one image as arrays (arguments and errors as ``detect``): a new
        dict with ``ids`` (N,) int64, ``families`` (list of N names), ``corners`` (N, 4, 2)
        float64 pixels in OpenCV's order, ``poses`` (N, 7) float64 (translation x, y, z in
        metres, then the rotation's quaternion x, y, z, w; NaN without a pose) and ``hamming``
        (N,) int64.

        Raises:
            TypeError: ``image`` is not a ``numpy.ndarray``.
            ValueError: bad image or arguments, as ``detect``.
            RuntimeError: an internal error.
        """
    def __repr__(self) -> str: ...

@final
class Tracker:
    """Follows markers through the frames of one video: each marker of the last frame is read
    again from where its motion puts it, by its family's stage 2 alone; the whole detector runs
    on the first frame, every ``redetect_every`` frames and whenever a marker is lost.

    Keeps state: use one tracker per video stream, from one thread at a time.
    """

    def __init__(self, detector: Detector, redetect_every: int = 10) -> None:
        """A tracker that reads with ``detector`` (its families, options, ``camera`` and
        ``channels``).

        Raises:
            ValueError: ``redetect_every`` is 0.
            TypeError: ``detector`` is not a ``Detector``.
        """
    def track(
        self,
        image: _Image,
        camera_params: Optional[_CameraParams] = None,
        tag_size: Optional[float] = None,
        channels: Optional[str] = None,
    ) -> List[Detection]:
        """The markers of the next frame (arguments as ``Detector.detect``).

        Raises:
            TypeError: ``image`` is not a ``numpy.ndarray``.
            ValueError: bad image or arguments, as ``Detector.detect``.
            RuntimeError: an internal error, or the tracker is in use by another thread.
        """
    @property
    def last_full(self) -> bool:
        """Whether the last frame ran the whole detector (rather than following its markers)."""

@final
class Family:
    """A marker family: its layout, pattern categories, keypoints, ROI and codebook.

    Made by ``Family.load``; immutable.
    """

    @staticmethod
    def load(name_or_path: str) -> Family:
        """A built-in family by name (see ``families()``) or a family JSON file by path.

        Raises:
            ValueError: no built-in family of that name, or a malformed family file.
            FileNotFoundError: the family file does not exist.
        """
    @property
    def name(self) -> str:
        """The family's name, e.g. ``"apriltag-36h11"``."""
    @property
    def title(self) -> str:
        """The family's human-readable title."""
    @property
    def size(self) -> int:
        """How many IDs the codebook holds (IDs run from 0 to ``size - 1``)."""
    @property
    def keypoint_count(self) -> int:
        """How many keypoints the family's template has."""
    @property
    def marker_side_mm(self) -> float:
        """The printed marker's side (ROI corner to corner) the family is posed at by default,
        millimetres."""
    @property
    def has_shipped_weights(self) -> bool:
        """Whether stage-2 weights that read this family ship with Tagsmith: a built-in's
        own, or those of its layout for a family file of yours (so ``Detector`` can read it
        without ``models``)."""
    def render(
        self, id: int, px: int = 256, quiet_zone: Optional[float] = None
    ) -> NDArray[np.uint8]:
        """Marker ``id``, upright, as a gray ``uint8`` H×W array ``px`` pixels wide (quiet zone
        included; black 0, white 255).

        Args:
            id: the marker's ID, 0 to ``size - 1``.
            px: the image's width, 1 to 20000 pixels.
            quiet_zone: the white margin in the family's layout units (cells for a grid
                family, outer-ring radii for a ring family), ≥ 0; default: the family's.

        Raises:
            ValueError: an ID outside the codebook, a bad ``px`` or ``quiet_zone``.
            RuntimeError: an internal error.
        """
    def sheet(
        self,
        ids: Sequence[int],
        path: _StrPath,
        page: str = "A4",
        marker_side_mm: Optional[float] = None,
        spacing_mm: Optional[float] = None,
        margin_mm: Optional[float] = None,
        labels: Optional[bool] = None,
        cut_marks: bool = False,
    ) -> List[pathlib.Path]:
        """Lays ``ids`` out on printable pages at the exact physical size and writes them to
        ``path``: a PDF (one file) or SVG (``STEM.svg``, or ``STEM-1.svg``, … for several
        pages), each written whole or not at all. Returns the files written.

        Args:
            ids: 1 to 10000 marker IDs.
            path: a ``.pdf`` or ``.svg`` file.
            page: ``"A4"``, ``"A3"``, ``"letter"`` or ``"WxH"`` in millimetres (10–5000 each),
                with ``"-landscape"`` appended to turn it.
            marker_side_mm: the marker's side (ROI corner to corner), mm; default: the
                family's ``marker_side_mm``.
            spacing_mm: the gap between neighbouring markers' quiet zones, mm (default 6).
            margin_mm: the page margin, mm (default 10).
            labels: print each marker's ID under it; default: the family's setting.
            cut_marks: draw cut marks around each marker.

        Raises:
            ValueError: no IDs or too many, an ID outside the codebook, a bad page, sizes that
                do not fit, or a path that is neither ``.pdf`` nor ``.svg``.
            OSError: a file cannot be written.
        """
    def validate(self) -> List[str]:
        """What the family's checks warn about (it loaded, so nothing is an error); empty when
        all is well."""
    def __repr__(self) -> str: ...

def families() -> List[str]:
    """The built-in families' names."""

def detectable_families() -> List[str]:
    """The families whose stage-2 weights ship with Tagsmith (``Detector``'s default)."""

def to_gray(image: _Image, channels: str = "RGB") -> NDArray[np.uint8]:
    """The gray ``uint8`` H×W image the detector sees for ``image`` (colour by Rec. 709
    luminance in ``channels`` order, alpha composited over white); a new array.

    Raises:
        TypeError: ``image`` is not a ``numpy.ndarray``.
        ValueError: a dtype other than ``uint8``, a bad shape, an empty or too large image, or
            a ``channels`` other than ``"RGB"``/``"BGR"``.
    """

def imread(path: _StrPath) -> NDArray[np.uint8]:
    """An image file as the command line reads it: gray ``uint8`` H×W (colour by Rec. 709
    luminance, alpha over white), within the same decoding limits.

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: the file is not a readable image, or is larger than the limits.
    """
