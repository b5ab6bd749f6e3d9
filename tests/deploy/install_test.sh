#!/usr/bin/env bash
# `cmake --install` gives what the README says, and an engine can build against it alone:
# the three programs and their scene importer (and nothing else) in bin/, libcpvs_runtime.so, its C header and the
# shader include; the installed `cpvs` bakes, a C program compiled against the installed
# header and library answers on a device as on the CPU, and an engine's fragment shader
# compiles against the installed include.   install_test.sh BUILD SOURCE WORKDIR
set -euo pipefail
build=$1 source=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
prefix="$work/prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log"

fail() { echo "install_test: $*" >&2; exit 1; }
for f in bin/cpvs bin/cpvs-server bin/cpvs-worker bin/cpvs-import lib/libcpvs_runtime.so include/cpvs/runtime/cpvs_runtime.h \
         share/cpvs/shaders/cpvs_shadow.glsl; do
  [ -s "$prefix/$f" ] || fail "cmake --install did not install $f (installed: $(cd "$prefix" && find . -type f | sort | tr '\n' ' '))"
done
programs="$(cd "$prefix/bin" && ls | sort | tr '\n' ' ')"
[ "$programs" = "cpvs cpvs-import cpvs-server cpvs-worker " ] ||
  fail "bin/ holds '$programs', not the three programs and cpvs-import alone"
for p in cpvs cpvs-server cpvs-worker cpvs-import; do
  help="$("$prefix/bin/$p" --help)"
  grep -q "Usage" <<<"$help" || fail "the installed $p --help prints no usage"
done

# A scene file goes through the installed importer (cpvs-import beside cpvs).
timeout 60 "$prefix/bin/cpvs" plan "$source/docs/scenes/glass-city.glb" --sun-dir 0.3,-1,0.2 -r 256 >"$work/plan.txt" ||
  fail "the installed cpvs cannot import a scene file: $(cat "$work/plan.txt")"
timeout 60 "$prefix/bin/cpvs" bake city:4 --sun-elevation 30 --sun-azimuth 40 -r 1K -q -o "$work/city.cpvs" >/dev/null
cc -std=c11 -Wall -Werror -I"$prefix/include" "$source/tests/runtime/c_client.c" -L"$prefix/lib" -lcpvs_runtime \
   -Wl,-rpath,"$prefix/lib" -o "$work/c_client"
# Read whole before grep: grep -q stopping early would end ldd by SIGPIPE under pipefail.
loads="$(ldd "$work/c_client")"
grep -qF "$prefix/lib/libcpvs_runtime.so" <<<"$loads" || fail "the C client does not load the installed library: $loads"
timeout 60 "$work/c_client" "$work/city.cpvs" 40 0.5 40 || fail "the C client built against the install failed"

glslc --target-env=vulkan1.1 -I"$prefix/share/cpvs/shaders" "$source/tests/runtime/engine_lighting.frag" \
      -o "$work/engine_lighting.spv" || fail "the engine shader does not compile against the installed include"
echo "install_test: the install holds the programs, the runtime library, its header and the shader include; a C client and an engine shader build against it"
