#!/usr/bin/env bash
# Sets up, builds, bakes the procedural closed city at 4K in this process, and renders
# it with the baked shadows next to exact ray-traced shadows.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/setup.sh
bash deploy/build.sh
mkdir -p out
./build/bin/cpvs bake city --sun-elevation 35 --sun-azimuth 30 --resolution 4K --out out/city.cpvs
./build/bin/cpvs verify out/city.cpvs city --samples 200000
./build/bin/cpvs render out/city.cpvs city --reference --out out/city.png
echo
echo "Output:  $(pwd)/out/city.cpvs"
echo "Picture: $(pwd)/out/city.png (exact shadows: out/city-reference.png, difference: out/city-diff.png)"
