"""Tagsmith: fiducial-marker families and their learned detector, on NumPy arrays.

The detector is the one ``tagsmith detect`` runs (stage 1 finds marker ROIs, stage 2 reads each
one's keypoints and ID, the pose comes from all keypoints); its detections equal the command
line's for the same pixels.

>>> import tagsmith, numpy as np
>>> detector = tagsmith.Detector(families=["apriltag-36h11"])
>>> for d in detector.detect(gray, camera_params=(fx, fy, cx, cy), tag_size=0.04):
...     print(d.family, d.tag_id, d.corners, d.pose_t.ravel())

Corners follow OpenCV's order: top-left, top-right, bottom-right, bottom-left of the upright
marker (clockwise in the image). Bad input raises ``ValueError``, ``TypeError`` or
``FileNotFoundError`` with the message the command line prints.
"""

from ._tagsmith import (
    Detection,
    Detector,
    Family,
    Tracker,
    __version__,
    detectable_families,
    families,
    imread,
    to_gray,
)

__all__ = [
    "Detection",
    "Detector",
    "Family",
    "Tracker",
    "__version__",
    "detectable_families",
    "families",
    "imread",
    "to_gray",
]
