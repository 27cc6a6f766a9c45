#!/usr/bin/env bash
# Every detector on one benchmark set, scored by the same code: the baselines that know the set's
# family (AprilTag 3 for the AprilTag families it has, OpenCV ArUco for the dictionaries it has),
# Tagsmith's whole-image detector, each scored by `tagsmith eval score`, then Tagsmith against the
# family's own baseline marker by marker (`tagsmith eval compare`). Used by bench/difficult.sh,
# bench/foreign.sh and bench/families.sh.
#   bench/side_by_side.sh SET_DIR OUT_PREFIX
# writes OUT_PREFIX-{tagsmith,apriltag,opencv}.json and OUT_PREFIX-report-*; ROWS= 'normal|difficult'
# (the default) picks the scored rows printed; TAGSMITH=path/to/tagsmith runs another build.
set -euo pipefail
cd "$(dirname "$0")/.."
set_dir=${1:?usage: bench/side_by_side.sh SET_DIR OUT_PREFIX}
prefix=${2:?usage: bench/side_by_side.sh SET_DIR OUT_PREFIX}
rows="^\\| (${ROWS:-normal|difficult})"
T=${TAGSMITH:-target/release/tagsmith}
PY=bench/.venv/bin/python

family=$($PY -c 'import json, sys; print(json.load(open(sys.argv[1]))["family"])' "$set_dir/set.json")
# AprilTag 3 where it has the family, OpenCV otherwise; the first is the baseline compared with.
detectors=$($PY bench/baselines.py --detectors "$family")
base=${detectors%% *}
[ -n "$base" ] || { echo "$family: no baseline reads it (bench/baselines.py)" >&2; exit 2; }
for d in $detectors; do
  # To a log, not /dev/null: pupil-apriltags under this venv segfaults writing to /dev/null
  # (2026-12-02; the same run to a file is fine).
  $PY bench/baselines.py "$set_dir" --detector $d -o "$prefix-$d.json" >"$prefix-$d.log"
done
$T detect-set "$set_dir" --full -o "$prefix-tagsmith.json" >/dev/null
for d in tagsmith $detectors; do
  echo "== $(basename "$prefix")-$d"
  $T eval score "$set_dir" "$prefix-$d.json" -o "$prefix-report-$d" | grep -E "$rows" || true
done
echo "== Tagsmith (A) vs $base (B), the same markers"
$T eval compare "$set_dir" "$prefix-tagsmith.json" "$prefix-$base.json" | grep -E "$rows|^Pose errors" || true
