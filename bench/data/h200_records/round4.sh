#!/usr/bin/env bash
# Round 4 on the H200: the eight-wide traversal with BVH8_HOLD_NEAREST=0 on GPUs (the working
# tree's kernels/, through TANDEM_KERNEL_DIR) against the kernels packed before it (head) and
# those of ad82770 (before the hold-nearest loops), and the recorded outputs with it.
set -u
R=$(pwd); T=/work/main/build/tandem; W=/tmp/r4; mkdir -p $W
S=$(date +%s); el() { echo "[$(( $(date +%s) - S ))s] $*"; }
ks() { python3 -c 'import json,sys;print(json.load(sys.stdin)["kernel_seconds"])'; }
render() { $T render $R/scenes/$1.xml -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | ks; }
{
for round in 1 2; do
  for s in cbox cbox-wall indirect-room gallery-lights; do
    echo "render $round $s head $(render $s)"
    echo "render $round $s fixed $(TANDEM_KERNEL_DIR=$R/kernels render $s)"
    echo "render $round $s ad82770 $(TANDEM_KERNEL_DIR=/tmp/app/kern_ad82770 render $s)"
  done
done
} > $W/renders.txt 2>$W/renders.err; el renders
TANDEM_KERNEL_DIR=$R/kernels timeout 120 bash $R/scripts/record-outputs.sh $T $W/outputs \
  > $W/record.log 2>&1; el "record-outputs: exit $?"
