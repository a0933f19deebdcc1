#!/usr/bin/env bash
# Round 1 (the build of 8c32906 with its libraries packed beside it, run on the H200 with TANDEM_DEVICE=NVIDIA):
# the recorded outputs, the device tests, DET_MATH cost and BVH widths. $A/kern_builtin is a copy
# of kernels/ whose det_math.h takes the builtins (DET_MATH_BUILTINS 1).
set -u
R=$(pwd)                      # the repo copy on the device (scenes/, tests/, scripts/)
T=/work/main/build/tandem     # the packed build at its absolute path
A=$R/.device/app
O=$OUT
export TANDEM_CACHE_DIR=/tmp/tcache PYTHONUNBUFFERED=1
S=$(date +%s); el() { echo "[$(( $(date +%s) - S ))s] $*"; }
{ nvidia-smi -L; nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm --format=csv; $T devices; } > $O/devices.txt 2>&1
el devices
timeout 170 bash $R/scripts/record-outputs.sh $T /tmp/nv-out > $O/record.log 2>&1; echo "record rc=$?" >> $O/summary.txt
tar -C /tmp -czf $O/nv-out.tar.gz nv-out; el record
for t in test_kernels test_render test_gradient; do
  timeout 100 /work/main/build/$t > /tmp/$t.log 2>&1; echo "$t rc=$?" >> $O/summary.txt; tail -5 /tmp/$t.log >> $O/summary.txt
  grep -B2 -A12 -E "ERROR|FAILED|CHECK.*fail" /tmp/$t.log | head -60 >> $O/tests_fail.txt; el $t
done
{
for round in 1 2 3; do
  for s in cbox cbox-wall three-spheres indirect-room env-probe; do
    for v in det builtin; do
      if [ $v = builtin ]; then kd="TANDEM_KERNEL_DIR=$A/kern_builtin"; else kd=; fi
      k=$(env $kd $T render $R/scenes/$s.xml -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | python3 -c 'import json,sys;print(json.load(sys.stdin)["kernel_seconds"])')
      echo "detmath $round $s $v $k"
    done
  done
done
for round in 1 2; do
  for s in cbox cbox-wall three-spheres indirect-room env-probe; do
    for w in 2 4 8; do
      k=$(TANDEM_BVH_WIDTH=$w $T render $R/scenes/$s.xml -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | python3 -c 'import json,sys;print(json.load(sys.stdin)["kernel_seconds"])')
      echo "width $round $s $w $k"
    done
  done
done
} > $O/perf.txt 2> $O/perf.err
timeout 120 $T bench trace --json > $O/trace.json 2> $O/trace.err
timeout 90 $T bench grad --sizes 128 256 512 1024 --json > $O/grad.json 2> $O/grad.err
