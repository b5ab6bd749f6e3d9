#!/usr/bin/env bash
# Sets up, builds and runs the whole test suite. Tests on the real scenes in
# ../shared/scenes run when that folder is there and say so when they skip.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/setup.sh
bash deploy/build.sh
ctest --test-dir build --output-on-failure -j 2 --timeout 900
