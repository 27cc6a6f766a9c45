#!/usr/bin/env bash
# Builds the studio for browsers into app/dist (static files: serve them with any web server).
#   scripts/build-web.sh            the `web` profile (Cargo.toml): LTO, size-optimised UI crates
#   scripts/build-web.sh --serve    build, then serve on http://127.0.0.1:8080
#   scripts/build-web.sh --names    keep the function names (1 MB) for the browser's profiler
# Needs: rustup target add wasm32-unknown-unknown; cargo install wasm-bindgen-cli --version <the
# wasm-bindgen version in Cargo.lock>. (cargo + wasm-bindgen is all trunk did for this one page.)
set -euo pipefail
serve=false
names=false
for arg in "$@"; do
  case "$arg" in
    --serve) serve=true ;;
    --names) names=true ;;
    *) echo "unknown option $arg (--serve, --names)" >&2; exit 2 ;;
  esac
done
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
want=$(awk '/^name = "wasm-bindgen"$/{getline; gsub(/"/,"",$3); print $3; exit}' Cargo.lock)
have=$(wasm-bindgen --version 2>/dev/null | awk '{print $2}' || true)
if [[ "$have" != "$want" ]]; then
  echo "wasm-bindgen-cli $want is needed (found: ${have:-none}):" >&2
  echo "  cargo install wasm-bindgen-cli --version $want" >&2
  exit 2
fi
# WebAssembly SIMD (every current browser has it: Chrome 91, Firefox 89, Safari 16.4): detection
# in the page is 1.27× faster with it (BENCHMARKS.md "Studio"). The flag is for the wasm32 target
# only, so host builds and the CI's wasm check keep their caches.
export CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_RUSTFLAGS="${CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_RUSTFLAGS:--C target-feature=+simd128}"
cargo build --profile web --target wasm32-unknown-unknown -p tagsmith-studio --bin tagsmith
target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')
rm -rf app/dist.tmp
# The name section only serves profilers and stack traces: users download 1 MB less without it.
strip_names=(--remove-name-section)
$names && strip_names=()
wasm-bindgen --target web --no-typescript "${strip_names[@]}" --out-dir app/dist.tmp \
  "$target_dir/wasm32-unknown-unknown/web/tagsmith.wasm"
# No wasm-opt pass: binaryen 132's -O2 took 1.5 MB more off but made detection 20 % slower, and
# Debian's binaryen 108 breaks wasm-bindgen's reference-type tables (BENCHMARKS.md, "Studio").
wasm_bytes=$(wc -c < app/dist.tmp/tagsmith_bg.wasm)
gzip_bytes=$(gzip -9 -c app/dist.tmp/tagsmith_bg.wasm | wc -c)
echo "tagsmith_bg.wasm: $wasm_bytes bytes, $gzip_bytes gzipped"
cp app/index.html app/worker.js app/dist.tmp/
# The data the module does not embed (core/src/assets.rs): the page and its worker fetch it.
mkdir -p app/dist.tmp/assets
cp -r assets/fonts assets/backgrounds assets/samples app/dist.tmp/assets/
# The shipped weights: those assets.rs lists (assets/models/ keeps older ones no build reads).
mkdir -p app/dist.tmp/assets/models
grep -o '"models/[^"]*"' core/src/assets.rs | tr -d '"' | while read -r model; do
  cp "assets/$model" app/dist.tmp/assets/models/
done
# Swap the finished folder in whole, so a failed build never leaves a half-written dist.
rm -rf app/dist && mv app/dist.tmp app/dist
echo "built: $root/app/dist ($(du -sh app/dist | cut -f1); open it through a web server, e.g. python3 -m http.server -d app/dist)"
if $serve; then
  echo "serving on http://127.0.0.1:8080 (Ctrl-C stops)"
  exec python3 -m http.server 8080 --bind 127.0.0.1 -d app/dist
fi
