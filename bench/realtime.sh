#!/usr/bin/env bash
# Latency on real photographs (issue 47): Tagsmith (`detect --sequential`, its phases, ROIs and
# stage-2 passes per image), AprilTag 3 (1 thread, decimate 1) and OpenCV ArUco on the same images
# in one run, with recall against the reference detections; then what each proposal source cost
# and read. Needs bench/.venv (bench/setup.sh) and a release build:
#   cargo build --release && bench/realtime.sh [FAMILY:DIR ...]
# Each FAMILY:DIR adds a folder of photographs without references (latency and counts only), e.g.
# a set `bench/foreign.sh` drew: apriltag-36h11:/tmp/foreign/apriltag-36h11.
# TAGSMITH=path/to/tagsmith runs another build; SHARED= the shared data folder (../shared).
set -euo pipefail
cd "$(dirname "$0")/.."
T=${TAGSMITH:-target/release/tagsmith}
shared=${SHARED:-../shared}
extra=()
for e in "$@"; do extra+=(--extra "$e"); done
# To a file first: pupil-apriltags under this venv segfaults writing to a closed pipe, and its
# detector's destructor did now and then (realtime.py keeps every detector alive since; the
# faulthandler showed it on 2026-12-07), so a crashed run is still tried again.
out=$(mktemp)
for try in 1 2 3; do
  if bench/.venv/bin/python -X faulthandler bench/realtime.py "$shared/realimages" --tagsmith "$T" \
      ${extra[@]+"${extra[@]}"} >"$out"; then
    break
  fi
  echo "realtime.py crashed (try $try of 3)" >&2
done
cat "$out"
rm -f "$out"
