#!/usr/bin/env bash
# Builds the studio for browsers into app/dist (static files: serve them with any web server).
#   scripts/build-web.sh            release build
#   scripts/build-web.sh --serve    build, then serve on http://127.0.0.1:8080 (trunk serve)
# Needs: rustup target add wasm32-unknown-unknown; cargo install trunk --version 0.21.14 --locked;
# cargo install wasm-bindgen-cli --version <the wasm-bindgen version in Cargo.lock>.
set -euo pipefail
cd "$(dirname "$0")/../app"
want=$(awk '/^name = "wasm-bindgen"$/{getline; gsub(/"/,"",$3); print $3; exit}' ../Cargo.lock)
have=$(wasm-bindgen --version 2>/dev/null | awk '{print $2}' || true)
if [[ "$have" != "$want" ]]; then
  echo "wasm-bindgen-cli $want is needed (found: ${have:-none}):" >&2
  echo "  cargo install wasm-bindgen-cli --version $want" >&2
  exit 2
fi
if [[ "${1:-}" == "--serve" ]]; then
  exec trunk serve --release --offline --address 127.0.0.1 --port 8080
fi
trunk build --release --offline
echo "built: $(pwd)/dist (open it through a web server, e.g. python3 -m http.server -d app/dist)"
