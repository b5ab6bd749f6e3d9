#!/usr/bin/env bash
# The query-path program answers exactly as `cpvs query`, and its binary loads none of
# the baker's libraries.  run.sh CPVS QUERY_PATH WORKDIR
set -euo pipefail
cpvs=$1 lookup=$2 dir=$3
mkdir -p "$dir"
forbidden='libembree|libassimp|libOpenEXR|libpng'
if ldd "$lookup" | grep -E "$forbidden"; then
  echo "query_path links a baker library (above)" >&2
  exit 1
fi
"$cpvs" bake city:2 --sun-dir 0.3,-1,0.2 -r 256 --tile-size 64 -q -o "$dir/city.cpvs" >/dev/null
# Points on a lattice through the city's volume, half of them with a normal.
python3 - "$dir/points.csv" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    for i in range(400):
        x, y, z = (i * 7 % 97) - 10.0, (i * 13 % 31) * 1.5, (i * 29 % 89) - 8.0
        f.write(f"{x},{y},{z}" + (",0,1,0\n" if i % 2 else "\n"))
PY
for pcf in 1 5 9; do
  "$cpvs" query "$dir/city.cpvs" --points "$dir/points.csv" --pcf $pcf > "$dir/cli-$pcf.csv"
  "$lookup" "$dir/city.cpvs" $pcf < "$dir/points.csv" > "$dir/lookup-$pcf.csv"
  cmp "$dir/cli-$pcf.csv" "$dir/lookup-$pcf.csv"
  # The lattice meets both lit and shadowed points, so the comparison means something.
  for value in 0 1; do
    if ! grep -q ",$value\$" "$dir/lookup-$pcf.csv"; then
      echo "query_path: no point of the lattice answered $value at PCF $pcf" >&2
      exit 1
    fi
  done
done
echo "query_path: same answers as cpvs query at PCF 1, 5, 9; no baker library loaded"
