#!/usr/bin/env bash
# Records the outputs that a pure restructure must leave bit-identical: a render of every bundled
# scene at a fixed seed, `tandem grad` of several parameters (loss, gradients and a texture
# gradient image), and 20 iterations of `tandem optimize` with the fused control variate (the
# loss, param_error, image_error and alpha_mean columns, the final parameters, and every image);
# shape gradients per vertex, and a short shape recovery with its meshes.
#
#   scripts/record-outputs.sh TANDEM_BINARY OUT_DIR
#   scripts/compare-outputs.sh DIR_A DIR_B        # exits nonzero when any output differs
#
# Run it with the build of one revision, then with another, and compare the two folders, e.g.
#   git worktree add /tmp/base <rev> && cmake -S /tmp/base -B /tmp/base/build && cmake --build ...
#   scripts/record-outputs.sh /tmp/base/build/tandem /tmp/out-base
#   scripts/record-outputs.sh build/tandem /tmp/out-new
#   scripts/compare-outputs.sh /tmp/out-base /tmp/out-new
# Timings (seconds columns and fields) are left out: they are the only outputs allowed to differ.
# Both runs must use the same OpenCL device (the default, or $TANDEM_DEVICE).
set -euo pipefail

if [[ $# -ne 2 ]]; then
    echo "usage: $0 TANDEM_BINARY OUT_DIR" >&2
    exit 2
fi
tandem=$(realpath "$1")
out=$2
root=$(cd "$(dirname "$0")/.." && pwd)
scenes=$root/scenes
tests=$root/tests/scenes
mkdir -p "$out"
out=$(realpath "$out")

# Strips timing fields (and the output path) from `tandem grad --json` output.
strip_times() {
    python3 -c 'import json,sys
d = json.load(sys.stdin)
for k in ("primal_seconds", "adjoint_seconds", "restir_seconds", "out_grad"): d.pop(k, None)
print(json.dumps(d, indent=1, sort_keys=True))'
}

# 1. Renders: every bundled scene, 64x64, 16 spp, seed 7.
for s in cbox cbox-wall three-spheres indirect-room env-probe gallery-lights; do
    "$tandem" render "$scenes/$s.xml" -D res=64 --spp 16 --seed 7 --out "$out/render-$s.exr" >/dev/null
done

# 2. Gradients: rgb, scalar, specular and emitter parameters, and a texture with its image.
# every parameter but the meshes' vertex positions (their own cases are in 4)
"$tandem" grad "$tests/grad-rough.xml" -D res=16 --spp 4 --seed 3 --json \
    $(for p in $("$tandem" params "$tests/grad-rough.xml" -D res=16 --json |
                 python3 -c 'import json,sys; print(" ".join(p["name"] for p in json.load(sys.stdin) if p["kind"] != "vertices"))'); do
          echo --param "$p"; done) | strip_times >"$out/grad-rough.json"
"$tandem" grad "$tests/grad-delta.xml" -D res=16 --spp 4 --seed 5 --json \
    $(for p in $("$tandem" params "$tests/grad-delta.xml" -D res=16 --json |
                 python3 -c 'import json,sys; print(" ".join(p["name"] for p in json.load(sys.stdin) if p["kind"] != "vertices"))'); do
          echo --param "$p"; done) | strip_times >"$out/grad-delta.json"
"$tandem" render "$scenes/cbox-wall.xml" -D res=32 --spp 64 --seed 11 --out "$out/ref-cbox-wall-32.exr" >/dev/null
"$tandem" grad "$scenes/cbox-wall.xml" -D res=32 --spp 4 --seed 9 --param wall.reflectance \
    --loss l2 --ref "$out/ref-cbox-wall-32.exr" --out-grad "$out/grad-wall.exr" --json |
    strip_times >"$out/grad-cbox-wall.json"

# 3. Optimization: 20 iterations of the main job's setup at 32x32, checkpoint every 10: with the
# fused control variate (ps), with CV-PSS and SGD, and without a control variate on the rl2 loss;
# and the ps run again, interrupted after iteration 10 and resumed.
optimize() { # NAME CV OPTIMIZER LOSS [tandem optimize options...]
    local name=$1 cv=$2 optimizer=$3 loss=$4
    shift 4
    cat >"$out/$name.json" <<EOF
{
  "scene": "$scenes/cbox-wall.xml", "defines": {"res": 32},
  "target": {"scene": "$scenes/cbox-wall.xml", "defines": {"res": 32}, "spp": 64},
  "params": {"wall.reflectance": {"lr": 0.02, "init": 0.5}, "red.reflectance": {"lr": 0.02}},
  "optimizer": "$optimizer", "iterations": 20, "spp": 2, "spp_grad": 2, "loss": "$loss", "seed": 4,
  "checkpoint_every": 10, "image_error_spp": 16, "cv": "$cv"
}
EOF
    "$tandem" optimize "$out/$name.json" --out "$out/$name" "$@" >/dev/null 2>&1
}
# NAME: the metrics' iteration, loss, param_error, image_error and alpha_mean (not the seconds,
# nor inputs_changed, a run's history rather than an output); no checkpoint, lock file or plot
finish() {
    cut -d, -f1,3-6 "$out/$1/metrics.csv" >"$out/$1-metrics.csv"
    rm -f "$out/$1/metrics.csv" "$out/$1/checkpoint.bin" "$out/$1/checkpoint.prev.bin" \
        "$out/$1/.tandem.lock" "$out/$1/convergence.png"
}
rm -rf "$out/optimize" "$out/optimize-pss" "$out/optimize-none" "$out/optimize-resume"
optimize optimize ps adam l2 && finish optimize
optimize optimize-pss pss sgd l2 && finish optimize-pss
optimize optimize-none none adam rl2 && finish optimize-none
optimize optimize-resume ps adam l2 --until 10 && optimize optimize-resume ps adam l2 --resume &&
    finish optimize-resume
# 4. Shapes: per-vertex gradients (interior, primary and secondary boundary terms) of the occluder
# between a light and a wall, of two surfaces at a right angle under a point light, and of a
# textured plane; and 20 iterations of a square light's recovery with Large Steps (the device
# scene refitting its BVH as the light moves), its meshes at each checkpoint.
# shape_grad NAME SCENE PARAM [ARGS...]: `tandem grad` of one vertex_positions parameter at res 16,
# 4 spp and seed 3 (ARGS: defines and budgets), its per-vertex gradient NAME.npy and JSON NAME.json
shape_grad() {
    local name=$1 scene=$2 param=$3
    shift 3
    "$tandem" grad "$tests/$scene" -D res=16 --spp 4 --seed 3 "$@" --param "$param" \
        --out-grad "$out/$name.npy" --json 2>/dev/null | strip_times >"$out/$name.json"
}
shape_grad grad-shape-shadow shape-shadow.xml occluder.vertex_positions
"$tandem" grad "$tests/shape-selfshadow.xml" -D res=16 --spp 4 --seed 3 --param floor.vertex_positions \
    --param wall.vertex_positions --json | strip_times >"$out/grad-shape-selfshadow.json"
shape_grad grad-shape-textured shape-textured.xml plane.vertex_positions
# a glossy receiver: the secondary term's guide (its training and the guided directions)
shape_grad grad-shape-glossy shape-glossy.xml object.vertex_positions --spp-grad 64
# glossy moving shapes: a rough plastic plane; a diffuse card before a gold floor
shape_grad grad-shape-plastic shape-plane.xml plane.vertex_positions -D bsdf=plastic
shape_grad grad-shape-reflector shape-reflector.xml card.vertex_positions
# a shadow seen only through a bounce, and creases (the secondary term at max_depth 3)
shape_grad grad-shape-bounce shape-bounce.xml occluder.vertex_positions
# the secondary term's walk: a shadow relayed through two bounces (tilted shading normals), the
# same under unbounded max_depth with roulette from the first bounce, a shadow on a tilted-normal
# wall, and a shadow cast through glass
shape_grad grad-shape-relay shape-relay.xml occluder.vertex_positions
shape_grad grad-shape-relay-unbounded shape-relay.xml occluder.vertex_positions \
    -D max_depth=-1 -D rr_depth=1
shape_grad grad-shape-tilted shape-tilted.xml occluder.vertex_positions
shape_grad grad-shape-glass shape-glass.xml occluder.vertex_positions
# reused light samples at a moving mesh: targets without visibility; with it, under an occluder
shape_grad grad-shape-restir shape-plane.xml plane.vertex_positions --spp-grad 16 --restir \
    --restir-visibility off
shape_grad grad-shape-restir-visibility shape-shadow.xml occluder.vertex_positions -D sky=0.15 \
    --spp-grad 16 --restir
rm -rf "$out/optimize-shape"
python3 - "$tests" "$out/optimize-shape.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1] + "/shape-emitter-recover.json"))
c.update(iterations=20, checkpoint_every=10)
c["scene"] = sys.argv[1] + "/" + c["scene"]
c["target"]["scene"] = sys.argv[1] + "/" + c["target"]["scene"]
json.dump(c, open(sys.argv[2], "w"), indent=1)
PY
"$tandem" optimize "$out/optimize-shape.json" --out "$out/optimize-shape" >/dev/null 2>&1 &&
    finish optimize-shape
echo "recorded into $out"
