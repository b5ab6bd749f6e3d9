#!/usr/bin/env bash
# libcpvs_runtime.so exports the C API and nothing else, and a C program linked to it
# alone answers on a device as on the CPU.   c_api_test.sh CPVS C_CLIENT LIBRARY WORKDIR
set -euo pipefail
cpvs=$1 client=$2 library=$3 work=$4
rm -rf "$work" && mkdir -p "$work"
others=$(nm -D --defined-only "$library" | awk '{print $3}' | grep -v '^cpvs' || true)
if [ -n "$others" ]; then
  echo "c_api_test: $library exports more than the C API:"; echo "$others" | head -20
  exit 1
fi
linked=$(ldd "$client" | grep -cE 'libembree|libassimp|libOpenEXR|libpng' || true)
if [ "$linked" != 0 ]; then echo "c_api_test: the C client pulls in the baker's libraries"; ldd "$client"; exit 1; fi
timeout 60 "$cpvs" bake city:4 --sun-elevation 30 --sun-azimuth 40 -r 1K -o "$work/city.cpvs" >/dev/null
timeout 60 "$client" "$work/city.cpvs" 40 0.5 40
