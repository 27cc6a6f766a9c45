#!/usr/bin/env bash
# The Python package's tests: builds the module into a venv of its own (target/python-venv, made on
# first use), then runs pytest against the `tagsmith` binary `cargo test --workspace` built.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/python-venv
if [ ! -x "$venv/bin/python" ] || ! cmp -s python/requirements-test.txt "$venv/requirements-test.txt"; then
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check -r python/requirements-test.txt
    cp python/requirements-test.txt "$venv/requirements-test.txt"
fi
# `cargo test --workspace` builds the binary with the test dependencies' features; building it on
# its own would rebuild the studio with others, so only a missing one is built.
[ -x target/debug/tagsmith ] || cargo build -p tagsmith-studio --bin tagsmith
(cd python && VIRTUAL_ENV="$PWD/../$venv" ../"$venv"/bin/maturin develop --quiet)
TAGSMITH_BIN="$PWD/target/debug/tagsmith" RAY_DISABLE_USAGE_STATS=1 \
    "$venv/bin/python" -m pytest python/tests -q -p no:cacheprovider "$@"
