#!/usr/bin/env bash
# Peak memory and time of `tagsmith detect` on photographs of 1 to 64 megapixels (bench/memory.py
# tiles the swarmathon sample to each size), one image per process, as /usr/bin/time reports it.
# Needs bench/.venv (bench/setup.sh) and a release build:
#   cargo build --release && bench/memory.sh /tmp/memory
# (SIZES="1 4 16 24 48 64" in megapixels; TAGSMITH=path/to/tagsmith runs another build; EXTRA=
# adds detect options, e.g. EXTRA=--upsample.)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: bench/memory.sh OUT_DIR}
sizes=${SIZES:-1 4 16 24 48 64}
tagsmith=${TAGSMITH:-target/release/tagsmith}
mkdir -p "$out"
# shellcheck disable=SC2086
bench/.venv/bin/python bench/memory.py "$out" $sizes >/dev/null
printf '%-8s %-12s %10s %10s %12s %8s\n' "MP" "size" "peak MB" "MB per MP" "wall s" "tags"
for mp in $sizes; do
  image="$out/${mp}mp.jpg"
  log="$out/${mp}mp.time"
  # shellcheck disable=SC2086
  /usr/bin/time -v "$tagsmith" detect "$image" --sequential --family apriltag-36h11 \
    --max-pixels 256000000 ${EXTRA:-} --json "$out/${mp}mp.json" >"$out/${mp}mp.out" 2>"$log"
  peak_kb=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$log")
  wall=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$log")
  size=$(bench/.venv/bin/python -c "import cv2,sys; i=cv2.imread(sys.argv[1], 0); print(f'{i.shape[1]}x{i.shape[0]}')" "$image")
  tags=$(bench/.venv/bin/python -c "import json,sys; print(sum(len(i['detections']) for i in json.load(open(sys.argv[1]))['images']))" "$out/${mp}mp.json")
  awk -v mp="$mp" -v size="$size" -v kb="$peak_kb" -v wall="$wall" -v tags="$tags" 'BEGIN {
    n = split(wall, t, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + t[i];
    printf "%-8s %-12s %10.0f %10.1f %12.1f %8s\n", mp, size, kb / 1024, kb / 1024 / mp, s, tags }'
done
