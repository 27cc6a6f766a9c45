#!/usr/bin/env bash
# The harness's protocol (Normal, Difficult, noise and motion-blur rows) with smaller markers: the
# harness prints 50 mm markers (35–1100 px across); at 25, 15 and 10 mm the same cells hold
# markers down to 17, 10 and 7 px, the range of a photograph's far tags. Tagsmith, AprilTag 3 and
# OpenCV ArUco read the same images, so the comparison covers the sizes stage 1 and stage 2 see
# least in training, not only the harness's.
# Needs bench/.venv (bench/setup.sh) and a release build:
#   cargo build --release && bench/scales.sh /tmp/scales 61 2
# (SIZES="25 15" picks the marker sides in mm; TAGSMITH=path/to/tagsmith runs another build.)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: bench/scales.sh OUT_DIR [SEED] [PER_CELL]}
seed=${2:-61}
per_cell=${3:-2}

for side in ${SIZES:-25 15 10}; do
  echo "=== marker side $side mm"
  SIDE_MM=$side ROWS='normal|difficult|noise|motion' bench/difficult.sh "$out/$side" "$seed" "$per_cell"
done
