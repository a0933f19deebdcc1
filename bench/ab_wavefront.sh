#!/usr/bin/env bash
# The wavefront renderer against the megakernel, side by side (docs/wavefront.md; the figures in
# docs/performance.md, "Wavefront against the megakernels").
#
#   bench/ab_wavefront.sh BINARY RES SPP ROUNDS SCENE...
#
# For each scene: one untimed 32² render per configuration (TANDEM_WAVEFRONT=0 and 1, each with its
# own kernel caches under a temporary folder, so no timed render compiles), then ROUNDS rounds
# alternating the two; prints, as a Markdown table for docs/performance.md ("Wavefront against the
# megakernels"; bench/update_performance.py wavefront FILE puts it there), the best kernel_seconds
# of each, the speed-up, and whether the last images store the same words (tandem-imgcmp, beside
# BINARY: bit for bit, NaN payloads and the sign of zero included).
set -euo pipefail
if [[ $# -lt 5 ]]; then
    echo "usage: $0 BINARY RES SPP ROUNDS SCENE..." >&2
    exit 2
fi
bin=$1 res=$2 spp=$3 rounds=$4
shift 4
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
run() { # CONFIG ARGS...: kernel seconds of `tandem render ARGS --json`
    local cfg=$1
    shift
    TANDEM_WAVEFRONT=$cfg TANDEM_CACHE_DIR=$work/cache$cfg POCL_CACHE_DIR=$work/pocl$cfg \
        "$bin" render "$@" --json 2>/dev/null |
        python3 -c 'import json,sys; print(json.load(sys.stdin)["kernel_seconds"])'
}
echo "$res², $spp spp, best of $rounds rounds, kernel seconds:"
echo
echo "| scene | megakernel s | wavefront s | megakernel ÷ wavefront | images |"
echo "|---|---|---|---|---|"
for scene in "$@"; do
    best=(1e30 1e30)
    for cfg in 0 1; do run $cfg "$scene" -D res=32 --spp 1 --out "$work/warm.exr" >/dev/null; done
    for ((r = 0; r < rounds; ++r)); do
        for cfg in 0 1; do
            t=$(run $cfg "$scene" -D res="$res" --spp "$spp" --out "$work/image$cfg.exr")
            best[cfg]=$(python3 -c "print(min(${best[cfg]}, $t))")
        done
    done
    same=DIFFER
    "$(dirname "$bin")/tandem-imgcmp" "$work/image0.exr" "$work/image1.exr" >/dev/null && same="same pixels"
    python3 -c "print('| %s | %.3f | %.3f | %.2f | %s |' % \
        ('$(basename "$scene" .xml)', ${best[0]}, ${best[1]}, ${best[0]} / ${best[1]}, '$same'))"
done
