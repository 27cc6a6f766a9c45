#!/usr/bin/env bash
# Tagsmith, AprilTag 3 and OpenCV ArUco on scenes that Tagsmith's synthesiser did not draw
# (bench/foreign.py: OpenCV draws the markers and the scene: clutter, distractor markers of other
# dictionaries, shadows, colour, JPEG), for AprilTag 36h11 and ArUco 6x6_250.
# Needs bench/.venv (bench/setup.sh) and a release build:
#   cargo build --release && bench/foreign.sh /tmp/foreign 7 300
# (SEED: pick one nobody has tuned on; IMAGES per family. TAGSMITH=path/to/tagsmith runs another
# build, ROWS= picks the rows printed, as in bench/side_by_side.sh.)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: bench/foreign.sh OUT_DIR SEED [IMAGES]}
seed=${2:?usage: bench/foreign.sh OUT_DIR SEED [IMAGES]}
images=${3:-300}
mkdir -p "$out"
for family in apriltag-36h11 aruco-6x6_250; do
  [ -f "$out/$family/set.json" ] ||
    bench/.venv/bin/python bench/foreign.py "$family" "$out/$family" --images "$images" --seed "$seed"
  bench/side_by_side.sh "$out/$family" "$out/$family"
done
