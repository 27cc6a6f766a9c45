#!/usr/bin/env bash
# Creates bench/.venv with the baseline detectors from PyPI: OpenCV's ArUco (contrib, headless)
# and AprilTag 3 (pupil-apriltags).
set -euo pipefail
cd "$(dirname "$0")"
python3 -m venv .venv
.venv/bin/pip install --quiet --upgrade pip
.venv/bin/pip install --quiet "opencv-contrib-python-headless>=4.8" "pupil-apriltags>=1.0.4" numpy
.venv/bin/python -c "import cv2, pupil_apriltags; print('opencv', cv2.__version__, '| pupil-apriltags ok')"
