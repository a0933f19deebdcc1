#!/usr/bin/env bash
# The checks that need a GPU, as one prepared script for a lent GPU machine (the figures it gives:
# docs/performance.md, "GPU"). With the default parts it takes about four minutes on an H200.
#
#   bench/gpu_check.sh TANDEM OUT_DIR [BUILTIN_KERNELS [OLD_KERNELS]]
#
# TANDEM is the tandem binary. The device is $TANDEM_DEVICE (e.g. NVIDIA). BUILTIN_KERNELS is
# optional: a copy of kernels/ whose shared/det_math.h takes the built-ins, made with
#   cp -r kernels K && sed -i 's/^#if TANDEM_DEVICE && defined(DET_MATH) && DET_MATH == 0$/#if TANDEM_DEVICE/' K/shared/det_math.h
# OLD_KERNELS is optional too: kernels/ of an earlier commit (git archive COMMIT kernels), whose
# renders are timed beside the current ones (what the kernels' changes since then cost or saved).
# $GPU_CHECK_PARTS picks what runs, in its order (default "outputs renders grad cv optimize"; "peer" adds
# bench/peer_mitsuba.py against Mitsuba 3's cuda_ad_rgb, with $GPU_CHECK_MITSUBA_PYTHON, a Python
# that imports mitsuba, and $GPU_CHECK_PEER_ARGS, more of its options, e.g. --skip-render). It
# writes into OUT_DIR:
#   outputs/           scripts/record-outputs.sh on the device. Compare it with a PoCL record:
#                      scripts/compare-outputs.sh POCL_DIR OUT_DIR/outputs
#   renders.txt        kernel seconds of forward renders, 512², 256 spp, per scene, two rounds:
#                      the default tree, and with BUILTIN_KERNELS and OLD_KERNELS; with
#                      GPU_CHECK_LAYOUTS=1 also per BVH layout (width and leaf format) and without
#                      the leaf repacking (TANDEM_BVH_REPACK=0)
#   grad_S_sR_hH_N.json  tandem bench grad (128² to 1024²) of scene S, round N, with the adjoint's
#                      record (kernels/path/record.h) of shadow rays on (R = 1) or off
#                      (TANDEM_SHADOW_RECORD=0) and of the hits of H bounces (TANDEM_HIT_RECORD),
#                      for each R:H in $GPU_CHECK_RECORDS (default "0:0 1:0 1:1 1:2 1:32"), on the
#                      two-wide tree that gradient work takes
#   cv_W.json          tandem bench cv (indirect-room, 1024², the fused kernel's cost), W-wide tree
#   optimize.txt       seconds per iteration of tandem optimize with CV-PS at 512², 40 iterations,
#                      per tree: what decides the layout of gradient work (core/render/policy.h)
#   peer.json          bench/peer_mitsuba.py --json (part "peer"): renders at 512², 64 spp, and
#                      gradient steps at 128² to 1024², against cuda_ad_rgb
# Kernel copies must lie outside the build's source folder: the device-pack script's unpack.sh
# restores the packed kernels/ over it, which on a device machine can be the working tree's copy.
# GPU_CHECK_RES, GPU_CHECK_SPP, GPU_CHECK_SIZES and GPU_CHECK_CV_SIZE shrink it (to try the script
# on a CPU): the resolution of renders and optimization (512), their spp (256), the sizes of bench
# grad ("128 256 512 1024") and of bench cv (1024).
set -uo pipefail
if [[ $# -lt 2 ]]; then
    echo "usage: $0 TANDEM OUT_DIR [BUILTIN_KERNELS [OLD_KERNELS]]" >&2
    exit 2
fi
tandem=$(realpath "$1")
mkdir -p "$2"
out=$(realpath "$2")
builtin=${3:-}
old=${4:-}
parts=${GPU_CHECK_PARTS:-outputs renders grad cv optimize}
res=${GPU_CHECK_RES:-512}
spp=${GPU_CHECK_SPP:-256}
sizes=${GPU_CHECK_SIZES:-"128 256 512 1024"}
cv_size=${GPU_CHECK_CV_SIZE:-1024}
root=$(cd "$(dirname "$0")/.." && pwd)
scenes=$root/scenes
start=$(date +%s)
say() { echo "[$(($(date +%s) - start)) s] $*"; }
kernel_seconds() { python3 -c 'import json, sys; print(json.load(sys.stdin)["kernel_seconds"])'; }

part_outputs() {
    timeout 150 bash "$root/scripts/record-outputs.sh" "$tandem" "$out/outputs" >"$out/record.log" 2>&1
    say "record-outputs: exit $?"
}

render() { # SCENE: kernel seconds of one render
    "$tandem" render "$scenes/$1.xml" -D res=$res --spp $spp --seed 1 --out "$out/render.exr" --json |
        kernel_seconds
}
part_renders() {
    {
        for round in 1 2; do
            for s in cbox cbox-wall indirect-room gallery-lights three-spheres env-probe; do
                echo "render $round $s default $(render "$s")"
                [[ -n $old ]] && echo "render $round $s old $(TANDEM_KERNEL_DIR=$old render "$s")"
                [[ -n $builtin ]] &&
                    echo "render $round $s builtins $(TANDEM_KERNEL_DIR=$builtin render "$s")"
                [[ ${GPU_CHECK_LAYOUTS:-0} == 1 ]] || continue
                for layout in 2:records 4:records 8:records 8:tri4; do
                    echo "render $round $s $layout $(TANDEM_BVH_WIDTH=${layout%:*} \
                        TANDEM_BVH_LEAVES=${layout#*:} render "$s")"
                done
                echo "render $round $s default-unrepacked $(TANDEM_BVH_REPACK=0 render "$s")"
            done
        done
    } >"$out/renders.txt" 2>"$out/renders.err"
    say "renders"
}

part_grad() {
    for round in 1 2; do
        for sp in cbox-wall:wall.reflectance cbox:white.reflectance; do
            for record in ${GPU_CHECK_RECORDS:-0:0 1:0 1:1 1:2 1:32}; do
                TANDEM_SHADOW_RECORD=${record%:*} TANDEM_HIT_RECORD=${record#*:} timeout 60 \
                    "$tandem" bench grad --scene "$scenes/${sp%%:*}.xml" --param "${sp#*:}" \
                    --sizes $sizes --json \
                    >"$out/grad_${sp%%:*}_s${record%:*}_h${record#*:}_$round.json" 2>>"$out/bench.err"
            done
        done
    done
    say "bench grad"
}

part_cv() {
    for w in 2 8; do
        TANDEM_BVH_WIDTH=$w timeout 60 "$tandem" bench cv --size $cv_size --repeats 5 --steady-size 8 \
            --steady-runs 2 --iterations 2 --reference-spp 1 --cv-variance consistent --json \
            >"$out/cv_$w.json" 2>>"$out/bench.err"
    done
    say "bench cv"
}

part_optimize() {
    cat >"$out/optimize.json" <<EOF
{
  "scene": "$scenes/cbox-wall.xml", "defines": {"res": $res},
  "target": {"scene": "$scenes/cbox-wall.xml", "defines": {"res": $res}, "spp": $spp},
  "params": {"wall.reflectance": {"lr": 0.02, "init": 0.5}},
  "optimizer": "adam", "iterations": 40, "spp": 4, "spp_grad": 4, "loss": "l2", "seed": 0,
  "checkpoint_every": 40, "image_error_spp": 4, "cv": "ps"
}
EOF
    {
        for round in 1 2; do
            for w in 2 8; do
                rm -rf "$out/optimize-$w"
                TANDEM_BVH_WIDTH=$w timeout 60 "$tandem" optimize "$out/optimize.json" \
                    --out "$out/optimize-$w" >/dev/null 2>>"$out/optimize.err"
                # metrics.csv: iteration, cumulative seconds, ...; the mean of iterations 11 to 40
                python3 - "$out/optimize-$w/metrics.csv" "$round" "$w" <<'PY'
import csv, sys
rows = [r for r in csv.reader(open(sys.argv[1])) if r and r[0].isdigit()]
t = {int(r[0]): float(r[1]) for r in rows}
print(f"optimize {sys.argv[2]} width {sys.argv[3]} s/iteration {(t[40] - t[10]) / 30:.6f}")
PY
            done
        done
    } >"$out/optimize.txt"
    say "optimize"
}

part_peer() {
    timeout 300 python3 "$root/bench/peer_mitsuba.py" --python "${GPU_CHECK_MITSUBA_PYTHON:-python3}" \
        --variant cuda_ad_rgb --tandem "$tandem" --res $res --spp 64 --seeds 2 --scalar-repeats 0 \
        --grad-sizes "$(echo $sizes | tr ' ' ,)" --grad-warmup 3 --grad-iterations 5 --json \
        ${GPU_CHECK_PEER_ARGS:-} >"$out/peer.json" 2>"$out/peer.err"
    say "peer: exit $?"
}

for p in $parts; do
    if ! declare -F "part_$p" >/dev/null; then
        echo "$0: no part '$p' (outputs renders grad cv optimize peer)" >&2
        exit 2
    fi
done
for p in $parts; do "part_$p"; done
