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
sizes=${SIZES:-25 15 10}
T=${TAGSMITH:-target/release/tagsmith}
PY=bench/.venv/bin/python
mkdir -p "$out"

for side in $sizes; do
  for family in apriltag-36h11 aruco-6x6_250; do
    set_dir="$out/$side/$family"
    [ -f "$set_dir/set.json" ] ||
      $T eval generate "$family" --side-mm "$side" --seed "$seed" --per-cell "$per_cell" \
        -o "$set_dir" >/dev/null
    detectors="opencv"
    [ "$family" = apriltag-36h11 ] && detectors="apriltag opencv"
    for d in $detectors; do
      # To a log, not /dev/null (see bench/detector.sh).
      $PY bench/baselines.py "$set_dir" --detector $d -o "$out/$side/$family-$d.json" \
        >"$out/$side/$family-$d.log"
    done
    $T detect-set "$set_dir" --full -o "$out/$side/$family-tagsmith.json" >/dev/null
    for f in "$out/$side/$family"-*.json; do
      name=$(basename "$f" .json)
      echo "== $side mm: $name"
      $T eval score "$set_dir" "$f" -o "$out/$side/report-$name" |
        grep -E '^\| (normal|difficult|noise|motion)' || true
    done
    # Paired, marker by marker: Tagsmith against the baseline of the family's own detector.
    base=opencv
    [ "$family" = apriltag-36h11 ] && base=apriltag
    echo "== $side mm: Tagsmith (A) vs $base (B), the same markers"
    $T eval compare "$set_dir" "$out/$side/$family-tagsmith.json" "$out/$side/$family-$base.json" |
      grep -E '^\| (normal|difficult|noise|motion)' || true
  done
done
