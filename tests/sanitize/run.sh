#!/usr/bin/env bash
# The sanitizer lane: the unit and file-format tests built with AddressSanitizer and
# UndefinedBehaviorSanitizer, debug checks (CPVS_DCHECK) on, into build-asan/ (incremental),
# and run there. Any sanitizer report fails the test that made it.
#   bash tests/sanitize/run.sh           # the lane CI runs after the main suite
#   bash tests/sanitize/run.sh dag_test  # some of its tests only
#
# Left out, and why:
#   runtime_test, c_api_test, gpu_*     Mesa's lavapipe and the Vulkan loader are not built
#                                       with ASan: they leak at exit and LeakSanitizer
#                                       reports them as ours.
#   golden_bake_test                    runs the `cpvs` program (the main suite's build).
#   farm_test, farm_security_test,      processes, a coordinator and workers on loopback:
#   hardening_test, in_process_farm_test, track_test, cli_test, accuracy_test,
#   query_path_test, c_api_test         they test the processes and the farm, not a unit,
#                                       and under ASan they run past their time limits.
#   fuzz_short                          already an ASan + UBSan build (tests/fuzz).
set -euo pipefail
cd "$(dirname "$0")/../.."

TESTS=(base_test light_test spot_light_test light_bundle_test sun_test child_codes_test options_test
       dag_test dag_invariants_test must_fail_test sub_dag_file_test
       scene_test raster_test receivers_test camera_views_test amortized_test
       pipeline_test hard_cases_test net_test top_tree_test translucent_test tile_eta_test tile_cache_test
       dag_mh_test dag_mh_bake_test)
if [ $# -gt 0 ]; then TESTS=("$@"); fi

out=build-asan
if [ ! -f "$out/build.ninja" ]; then
  # RelWithDebInfo at -O1 without -DNDEBUG: the debug checks stay on, the tests stay quick.
  cmake -S . -B "$out" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCPVS_SANITIZE=ON \
        -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g" >/dev/null
fi
echo "sanitize: building ${#TESTS[@]} tests with ASan + UBSan into $out/"
ninja -C "$out" -j "${CPVS_JOBS:-2}" "${TESTS[@]}"

export ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:strict_string_checks=1:detect_stack_use_after_return=1"
export LSAN_OPTIONS="suppressions=$(pwd)/tests/sanitize/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
regex="^($(IFS='|'; echo "${TESTS[*]}"))\$"
ctest --test-dir "$out" --output-on-failure -j 2 --timeout 900 -R "$regex"
echo "sanitize: ${#TESTS[@]} tests passed under ASan + UBSan with debug checks on"
