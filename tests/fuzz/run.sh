#!/usr/bin/env bash
# Builds the fuzz targets with clang (libFuzzer + ASan + UBSan) into build/fuzz and runs
# each for SECONDS (default 15). Seeds: small .cpvs and .dmh files made by the main build's `cpvs`
# (the current format version, one with translucent casters) when it exists, and version 1 and 2 files from tests/io/data. A crash or sanitizer report fails the run and leaves the
# input in build/fuzz/artifacts/.
#   bash tests/fuzz/run.sh 15      # the bounded run of the test suite
#   bash tests/fuzz/run.sh 3600    # a longer run
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds="${1:-15}"
out=build/fuzz
if ! command -v clang++ >/dev/null; then
  echo "fuzz: clang++ is missing (deploy/setup.sh installs it)" >&2
  exit 1
fi
if [ ! -f "$out/build.ninja" ]; then
  CXX=clang++ cmake -S tests/fuzz -B "$out" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
fi
ninja -C "$out" -j "${CPVS_JOBS:-2}" >/dev/null
mkdir -p "$out/corpus-cpvs" "$out/corpus-scene" "$out/artifacts"
cli=build/bin/cpvs
# Named by the packed layout they hold (3), so that a corpus from before gets them too.
if [ -x "$cli" ] && [ ! -f "$out/corpus-cpvs/seed-l3-city64.cpvs" ]; then
  "$cli" bake city:1 --sun-dir 0.3,-1,0.2 -r 64 --tile-size 64 -q -o "$out/corpus-cpvs/seed-l3-city64.cpvs" >/dev/null
  "$cli" bake city:1 --sun-dir 0,-1,0 -r 32 --no-zstd -q -o "$out/corpus-cpvs/seed-l3-city32-raw.cpvs" >/dev/null
  "$cli" bake city:1 --sun-dir 0.1,-1,0.5 -r 8 --no-zstd -q -o "$out/corpus-cpvs/seed-l3-city8-raw.cpvs" >/dev/null
fi
if [ -x "$cli" ] && [ ! -f "$out/corpus-cpvs/seed-city64.dmh" ]; then
  # DAG-MH files: a one-treelet map, one with inner nodes and a skip list.
  "$cli" bake city:1 --format dagmh --sun-dir 0.3,-1,0.2 -r 8 --no-zstd -q -o "$out/corpus-cpvs/seed-city8-raw.dmh" >/dev/null
  "$cli" bake city:1 --format dagmh --receivers surfaces --sun-dir 0.3,-1,0.2 -r 256 --no-zstd -q \
    -o "$out/corpus-cpvs/seed-city256-raw.dmh" >/dev/null
  "$cli" bake city:1 --format dagmh --sun-dir 0.1,-1,0.5 -r 64 -q -o "$out/corpus-cpvs/seed-city64.dmh" >/dev/null
fi
if [ -x "$cli" ] && [ ! -f "$out/corpus-cpvs/seed-lamps-raw.cpvs" ]; then
  # A light bundle: a spot light and a point light's cube, small grids.
  "$cli" bake city:1 --spot 10,15,10:0.2,-1,0.1:40 --point 12,6,8:20 --footprint 2 --no-zstd -q \
    -o "$out/corpus-cpvs/seed-lamps-raw.cpvs" >/dev/null
fi
if [ -x "$cli" ] && [ ! -f "$out/corpus-cpvs/seed-glass-raw.cpvs" ]; then
  # A sun artifact with translucent casters: two glass panes (an OBJ's dissolve) over a floor.
  glass=$(mktemp -d)
  printf 'newmtl glass\nd 0.4\nnewmtl floor\nd 1\n' >"$glass/glass.mtl"
  printf 'mtllib glass.mtl\nv -4 0 -4\nv 4 0 -4\nv 4 0 4\nv -4 0 4\nv -2 2 -2\nv 2 2 -2\nv 2 2 2\nv -2 2 2\nv -1 3 -1\nv 3 3 -1\nv 3 3 3\nv -1 3 3\no floor\nusemtl floor\nf 1 3 2\nf 1 4 3\no panes\nusemtl glass\nf 5 7 6\nf 5 8 7\nf 9 11 10\nf 9 12 11\n' >"$glass/glass.obj"
  "$cli" bake "$glass/glass.obj" --sun-dir 0.2,-1,0.1 -r 16 --no-zstd -q -o "$out/corpus-cpvs/seed-glass-raw.cpvs" >/dev/null
  rm -rf "$glass"
fi
# Older files: format 1, and format 2 holding packed layout 1.
cp -n tests/io/data/city-256-v1.cpvs "$out/corpus-cpvs/seed-city256-v1.cpvs"
cp -n tests/io/data/city-256-v2.cpvs "$out/corpus-cpvs/seed-city256-v2.cpvs"
for target in fuzz_cpvs_reader fuzz_scene_input; do
  corpus="$out/corpus-${target#fuzz_}"
  [ "$target" = fuzz_cpvs_reader ] && corpus="$out/corpus-cpvs"
  [ "$target" = fuzz_scene_input ] && corpus="$out/corpus-scene"
  echo "fuzz: $target for ${seconds}s"
  "$out/$target" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
    -artifact_prefix="$out/artifacts/" -print_final_stats=0 "$corpus" 2>"$out/$target.log" || {
    echo "fuzz: $target FAILED; last lines of $out/$target.log:" >&2
    tail -40 "$out/$target.log" >&2
    exit 1
  }
  grep -E "^(#[0-9]+ +DONE|Done)" "$out/$target.log" | tail -1 || true
done
echo "fuzz: no crash, no sanitizer report"
