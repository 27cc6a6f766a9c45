#!/usr/bin/env bash
# A square family stage 1 never saw (bench/unseen/bardot-7x7.json: a black frame around 5×5 data
# cells, bit 0 a bar, bit 1 a dot — glyphs none of stage 1's training families or random designs
# use), given only its own stage-2 model, as a user who designs a family would: train stage 2
# (7000 steps, about 30 minutes on two cores), generate the family's harness set, run the full
# detector (the shipped stage 1 + the new stage 2) and score it.
#   bench/unseen.sh OUT        (needs target/release/tagsmith: cargo build --release)
set -euo pipefail
out=${1:?usage: bench/unseen.sh OUT}
root=$(cd "$(dirname "$0")/.." && pwd)
T="$root/target/release/tagsmith"
family="$root/bench/unseen/bardot-7x7.json"
mkdir -p "$out"
[ -f "$out/run/model.bin" ] || "$T" train "$family" --stage keypoints --steps 7000 --out "$out/run" \
  $( [ -f "$out/run/checkpoint.bin" ] && echo --resume )
[ -d "$out/set" ] || "$T" eval generate "$family" -o "$out/set"
"$T" detect-set "$out/set" --full --model "$out/run/model.bin" -o "$out/full.json"
"$T" eval score "$out/set" "$out/full.json" -o "$out/report"
