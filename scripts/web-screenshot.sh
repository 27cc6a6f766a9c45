#!/usr/bin/env bash
# Screenshot of the web build (app/dist, from scripts/build-web.sh) in headless Chromium with
# software WebGL: proves the page loads and the studio draws.
#   scripts/web-screenshot.sh OUT.png [PORT]
# Needs Debian's chromium (apt-get install chromium) and python3 for the static server.
set -euo pipefail
out=$(realpath -m "${1:?usage: scripts/web-screenshot.sh OUT.png [PORT]}")
port=${2:-8765}
source "$(dirname "$0")/browser/serve.sh"
serve_dist "$port"
profile=$(mktemp -d)
chromium --headless --no-sandbox --disable-gpu --use-angle=swiftshader --enable-unsafe-swiftshader \
  --disable-quic --no-first-run --disable-background-networking --disable-component-update \
  --disable-sync --user-data-dir="$profile" --window-size=1400,900 \
  --virtual-time-budget=20000 --screenshot="$out" "http://127.0.0.1:$port/" 2>/dev/null
rm -rf "$profile"
[[ -s "$out" ]] || { echo "no screenshot was written" >&2; exit 1; }
echo "wrote $out"
