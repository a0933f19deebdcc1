#!/usr/bin/env bash
# Round 2 on the H200 (after bench/gpu_check.sh, round 1): forward renders with and without the
# BVH's leaf repacking, the adjoint's hit record on more scenes and in tandem optimize, and the
# recorded outputs with every hit recorded and no repacking (to compare with PoCL's, bit for bit).
set -u
R=$(pwd); T=/work/main/build/tandem; W=/tmp/r2; mkdir -p $W
S=$(date +%s); el() { echo "[$(( $(date +%s) - S ))s] $*"; }
ks() { python3 -c 'import json,sys;print(json.load(sys.stdin)["kernel_seconds"])'; }
{
for round in 1 2; do
  for s in cbox cbox-wall indirect-room gallery-lights; do
    for rp in 1 0; do
      echo "render $round $s repack$rp $(TANDEM_BVH_REPACK=$rp $T render $R/scenes/$s.xml -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | ks)"
    done
  done
done
} > $W/renders.txt 2>$W/renders.err; el renders
for round in 1 2; do
  for sp in indirect-room:painting.reflectance three-spheres:floor.reflectance \
            gallery-lights:painting.reflectance env-probe:orange.reflectance; do
    for h in 0 32; do
      TANDEM_HIT_RECORD=$h timeout 60 $T bench grad --scene $R/scenes/${sp%%:*}.xml \
        --param ${sp#*:} --sizes 256 1024 --json > $W/grad_${sp%%:*}_h${h}_$round.json 2>>$W/bench.err
    done
  done
done; el grad
for h in 3 4 6; do
  TANDEM_HIT_RECORD=$h timeout 60 $T bench grad --scene $R/scenes/cbox-wall.xml \
    --param wall.reflectance --sizes 256 1024 --json > $W/grad_cbox-wall_h${h}_1.json 2>>$W/bench.err
done; el curve
cat > $W/optimize.json <<JSON
{
  "scene": "$R/scenes/cbox-wall.xml", "defines": {"res": 512},
  "target": {"scene": "$R/scenes/cbox-wall.xml", "defines": {"res": 512}, "spp": 256},
  "params": {"wall.reflectance": {"lr": 0.02, "init": 0.5}},
  "optimizer": "adam", "iterations": 40, "spp": 4, "spp_grad": 4, "loss": "l2", "seed": 0,
  "checkpoint_every": 40, "image_error_spp": 4, "cv": "ps"
}
JSON
for round in 1 2; do
  for h in 0 32; do
    rm -rf $W/opt-$h
    TANDEM_HIT_RECORD=$h timeout 60 $T optimize $W/optimize.json --out $W/opt-$h >/dev/null 2>>$W/optimize.err
    python3 - $W/opt-$h/metrics.csv $round $h <<'PY'
import csv, sys
rows = [r for r in csv.reader(open(sys.argv[1])) if r and r[0].isdigit()]
t = {int(r[0]): float(r[1]) for r in rows}
print(f"optimize {sys.argv[2]} hits {sys.argv[3]} s/iteration {(t[40] - t[10]) / 30:.6f}")
PY
  done
done > $W/optimize.txt; el optimize
TANDEM_HIT_RECORD=32 TANDEM_BVH_REPACK=0 timeout 150 bash $R/scripts/record-outputs.sh $T $W/outputs \
  > $W/record.log 2>&1; el "record-outputs: exit $?"
