#!/usr/bin/env bash
# Round 2: bits with the branch-free det_math (default layout and BVH8), det_math cost, leaf
# formats and widths on triangle scenes and a 131k-triangle knot in the box, trace, adjoint, CV.
set -u
R=$(pwd); T=/work/main/build/tandem; A=$R/.device/app; W=/tmp/res; mkdir -p $W
export TANDEM_CACHE_DIR=/tmp/tcache PYTHONUNBUFFERED=1
S=$(date +%s); el() { echo "[$(( $(date +%s) - S ))s] $*"; }
ks() { python3 -c 'import json,sys;print(json.load(sys.stdin)["kernel_seconds"])'; }
timeout 120 bash $R/scripts/record-outputs.sh $T /tmp/nv-out > $W/record.log 2>&1; echo "record rc=$?"
tar -C /tmp -czf $W/nv-out.tar.gz nv-out; el record
TANDEM_BVH_WIDTH=8 timeout 90 bash $R/scripts/record-outputs.sh $T /tmp/nv-out8 > $W/record8.log 2>&1; echo "record8 rc=$?"
tar -C /tmp -czf $W/nv-out8.tar.gz nv-out8; el record8
timeout 60 /work/main/build/test_kernels -tc='*det_math*' > $W/test_det.log 2>&1; echo "det tests rc=$?"; tail -3 $W/test_det.log
{
for round in 1 2 3; do
  for s in env-probe three-spheres cbox; do
    for v in det builtin; do
      if [ $v = builtin ]; then kd="TANDEM_KERNEL_DIR=$A/kern_builtin"; else kd=; fi
      echo "detmath $round $s $v $(env $kd $T render $R/scenes/$s.xml -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | ks)"
    done
  done
done
el detmath >&2
for round in 1 2; do
  for s in $A/cbox-knot.xml $R/scenes/cbox.xml $R/scenes/cbox-wall.xml $R/scenes/indirect-room.xml $R/scenes/gallery-lights.xml; do
    for cfg in 2:records 4:records 4:tri4 8:records 8:tri4; do
      echo "layout $round $(basename $s .xml) $cfg $(TANDEM_BVH_WIDTH=${cfg%:*} TANDEM_BVH_LEAVES=${cfg#*:} $T render $s -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | ks)"
    done
  done
done
el layouts >&2
} > $W/perf.txt 2> $W/perf.err
timeout 60 $T bench trace --json > $W/trace.json 2> $W/trace.err; el trace
for cfg in 2:records 8:records 8:tri4; do
  TANDEM_BVH_WIDTH=${cfg%:*} TANDEM_BVH_LEAVES=${cfg#*:} timeout 40 $T bench grad --sizes 128 256 512 1024 --json > $W/grad_${cfg%:*}_${cfg#*:}.json 2>> $W/grad.err
  TANDEM_BVH_WIDTH=${cfg%:*} TANDEM_BVH_LEAVES=${cfg#*:} timeout 40 $T bench grad --scene $R/scenes/cbox.xml --param white.reflectance --sizes 128 256 512 1024 --json > $W/gradcbox_${cfg%:*}_${cfg#*:}.json 2>> $W/grad.err
  TANDEM_BVH_WIDTH=${cfg%:*} TANDEM_BVH_LEAVES=${cfg#*:} timeout 40 $T bench cv --size 1024 --repeats 5 --steady-size 8 --steady-runs 2 --iterations 2 --reference-spp 1 --cv-variance consistent --json > $W/cv_${cfg%:*}_${cfg#*:}.json 2>> $W/cv.err
  el "grad/cv $cfg"
done
tar -C /tmp -czf $OUT/res.tar.gz res
el done
