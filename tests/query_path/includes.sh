#!/usr/bin/env bash
# No public header of query/ reaches a header of bake/, raytrace/ or scene/, directly or
# through others: the compiler lists every header each one includes. bake/options.h is the
# options layer, a leaf the file formats name (cpvs_options), not the bake.
#   includes.sh CXX SRC
set -euo pipefail
cxx=$1 src=$2
status=0
for header in "$src"/core/include/cpvs/query/*.h; do
  deps=$("$cxx" -std=c++20 -MM -I "$src/core/include" -x c++ "$header" | sed 's|[^ ]*cpvs/bake/options\.h||g')
  if grep -qE 'cpvs/(bake|raytrace|scene)/' <<<"$deps"; then
    echo "$(basename "$header") includes: $(grep -oE 'cpvs/(bake|raytrace|scene)/[a-z_]+\.h' <<<"$deps" | sort -u | tr '\n' ' ')"
    status=1
  fi
done
[ $status = 0 ] && echo "query headers: no bake, raytrace or scene header reached"
exit $status
