#!/usr/bin/env bash
# Configures and builds the project into build/ (incremental; -j2 by default).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -f build/build.ninja ]; then
  cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
fi
ninja -C build -j "${CPVS_JOBS:-2}"
