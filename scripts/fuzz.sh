#!/usr/bin/env bash
# Runs Tandem's libFuzzer harnesses (fuzz/): builds them in build-fuzz/ with clang, ASan and UBSan
# if needed, then runs each for SECONDS (default 60) on its corpus, one at a time, and prints per
# harness the executions and what it found.
#
#   scripts/fuzz.sh [SECONDS] [HARNESS...]      HARNESS: scene config checkpoint mesh image volume vdb
#
# Each harness runs as one libFuzzer worker (fork mode with a single job, so that it goes on after a
# finding), with a 10 s timeout per input and a 2 GiB memory limit. New interesting inputs go to
# build-fuzz/corpus/HARNESS (the committed seeds, fuzz/corpus/HARNESS, are read, never written);
# findings (crash-*, timeout-*, oom-*) go to build-fuzz/findings/HARNESS, the log to
# build-fuzz/logs/HARNESS.log. Reproduce one: build-fuzz/fuzz/fuzz_HARNESS FILE (with
# TANDEM_FUZZ_VERBOSE=1 it prints why an input is rejected). Exits 1 if anything was found.
# Environment: CC, CXX (default clang-14, clang++-14), TANDEM_FUZZ_BUILD (default build-fuzz),
# TANDEM_FUZZ_FLAGS (more libFuzzer flags, after the script's).
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
duration=${1:-60}
[ $# -gt 0 ] && shift
harnesses=("$@")
[ ${#harnesses[@]} -eq 0 ] && harnesses=(scene config checkpoint mesh image volume vdb)
build=${TANDEM_FUZZ_BUILD:-$root/build-fuzz}

for h in "${harnesses[@]}"; do
    [ -f "$root/fuzz/fuzz_$h.cpp" ] || { echo "fuzz.sh: no harness '$h' (fuzz/fuzz_$h.cpp)" >&2; exit 2; }
done
if [ ! -f "$build/CMakeCache.txt" ]; then
    command -v "${CXX:-clang++-14}" >/dev/null || {
        echo "fuzz.sh: needs clang with libFuzzer (Debian 12: apt-get install clang-14 libclang-rt-14-dev)" >&2
        exit 2
    }
    CC=${CC:-clang-14} CXX=${CXX:-clang++-14} cmake -S "$root" -B "$build" \
        -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTANDEM_BUILD_FUZZERS=ON -DTANDEM_BUILD_TESTS=OFF \
        -DTANDEM_BUILD_PYTHON=OFF >/dev/null
fi
cmake --build "$build" -j2 --target "${harnesses[@]/#/fuzz_}" >/dev/null

mkdir -p "$build/logs"
found=0
printf '%-11s %8s %12s %8s %9s %6s %8s\n' harness seconds executions crashes timeouts ooms corpus
for h in "${harnesses[@]}"; do
    corpus="$build/corpus/$h" findings="$build/findings/$h" log="$build/logs/$h.log"
    # the harness's input files and libFuzzer's job folders; one folder per harness, so that
    # two runs of this script on different harnesses may share the build
    tmp="$build/fuzz-tmp/$h"
    mkdir -p "$tmp"
    mkdir -p "$corpus" "$findings"
    flags=() asan=${ASAN_OPTIONS:-}
    case $h in
    scene) flags=(-dict="$root/fuzz/dict/scene.dict") ;;
    config) flags=(-dict="$root/fuzz/dict/config.dict") ;;
    mesh) flags=(-dict="$root/fuzz/dict/mesh.dict") ;;
    # OpenImageIO's PNG reader leaks an error string on truncated files (libpng's longjmp): the
    # suppression needs full stacks, too slow here, so no leak checks for this one: neither
    # libFuzzer's (-detect_leaks) nor LeakSanitizer's at the exit of each fork-mode job
    # (ASAN_OPTIONS; they were counted as crashes, with empty inputs)
    image) flags=(-detect_leaks=0) asan=${asan:+$asan:}detect_leaks=0 ;;
    # OpenVDB 10.0.1's reader leaks the nodes it had read when it throws on a damaged tree (40 of
    # the 47 findings of its first 120 s, all inside libopenvdb): no leak checks here either; and
    # it allocates what a damaged header says, which a release build gets as std::bad_alloc (read_vdb
    # turns it into an error), so ASan returns null for those too instead of aborting
    vdb) flags=(-detect_leaks=0)
         asan=${asan:+$asan:}detect_leaks=0:allocator_may_return_null=1 ;;
    esac
    # extra libFuzzer flags: TANDEM_FUZZ_FLAGS="-detect_leaks=1 -seed=1"
    read -r -a extra <<<"${TANDEM_FUZZ_FLAGS:-}"
    flags+=("${extra[@]}")
    before=$(ls "$findings" | wc -l)
    # a copy: fork mode starts the binary again for every job, and a rebuild must not change it
    cp "$build/fuzz/fuzz_$h" "$tmp/fuzz_$h"
    # leaks inside Assimp and OpenImageIO on malformed files are not Tandem's (tests/lsan.supp)
    ASAN_OPTIONS="$asan" LSAN_OPTIONS=suppressions="$root/tests/lsan.supp" TMPDIR="$tmp" "$tmp/fuzz_$h" -fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
        -max_total_time="$duration" -timeout=10 -rss_limit_mb=2048 "${flags[@]}" \
        -artifact_prefix="$findings/" "$corpus" "$root/fuzz/corpus/$h" >"$log" 2>&1 || true
    # fork mode's status lines: "#EXECS: cov: N ft: N corp: N exec/s N oom/timeout/crash: O/T/C ..."
    status=$(grep -E '^#[0-9]+: cov:' "$log" | tail -1 || true)
    execs=$(sed -E 's/^#([0-9]+):.*/\1/' <<<"$status")
    read -r ooms timeouts crashes < <(sed -E 's|.*oom/timeout/crash: ([0-9]+)/([0-9]+)/([0-9]+).*|\1 \2 \3|' <<<"${status:-0/0/0}" | tr -c '0-9\n' ' ')
    files=$(( $(ls "$corpus" | wc -l) + $(ls "$root/fuzz/corpus/$h" | wc -l) ))
    printf '%-11s %8s %12s %8s %9s %6s %8s\n' "$h" "$duration" "${execs:-0}" "${crashes:-0}" \
        "${timeouts:-0}" "${ooms:-0}" "$files"
    [ "$(ls "$findings" | wc -l)" -gt "$before" ] && found=1
done
for h in "${harnesses[@]}"; do rm -rf "${build:?}/fuzz-tmp/$h"; done
if [ $found -eq 1 ]; then
    echo "findings in $build/findings/ (reproduce: $build/fuzz/fuzz_HARNESS FILE)"
    exit 1
fi
