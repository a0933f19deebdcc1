#!/usr/bin/env bash
# Round 3: bits after NEE's environment sample brings its own radiance, det_math cost on
# env-probe, and the forward render's default layout on a triangle scene.
set -u
R=$(pwd); T=/work/main/build/tandem; A=$R/.device/app; W=/tmp/res3; mkdir -p $W
export TANDEM_CACHE_DIR=/tmp/tcache PYTHONUNBUFFERED=1
S=$(date +%s); el() { echo "[$(( $(date +%s) - S ))s] $*"; }
ks() { python3 -c 'import json,sys;print(json.load(sys.stdin)["kernel_seconds"])'; }
timeout 90 bash $R/scripts/record-outputs.sh $T /tmp/nv-out > $W/record.log 2>&1; echo "record rc=$?"
tar -C /tmp -czf $W/nv-out.tar.gz nv-out; el record
{
for round in 1 2 3; do
  for s in env-probe cbox-wall; do
    for v in det builtin; do
      if [ $v = builtin ]; then kd="TANDEM_KERNEL_DIR=$A/kern_builtin"; else kd=; fi
      echo "detmath $round $s $v $(env $kd $T render $R/scenes/$s.xml -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | ks)"
    done
  done
done
K="-D knot=/work/main/build/scenes/meshes/knot.ply"
for round in 1 2; do
  echo "default $round cbox-knot default $($T render $A/cbox-knot.xml $K -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | ks)"
  echo "default $round cbox-knot w2 $(TANDEM_BVH_WIDTH=2 $T render $A/cbox-knot.xml $K -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | ks)"
done
$T render $A/cbox-knot.xml $K --print-features
} > $W/perf.txt 2> $W/perf.err
el perf
cat $W/perf.txt
tar -C /tmp -czf $OUT/res3.tar.gz res3
