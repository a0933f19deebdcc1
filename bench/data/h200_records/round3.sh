#!/usr/bin/env bash
# Round 3 on the H200: what made the eight-wide forward renders slower since 4097b6c. Kernel
# copies under /tmp/app (TANDEM_KERNEL_DIR), with today's host: kernels at ad82770 (before the
# closest-hit loop visits its nearest child without a push), d888313 (that change), dc23808 (the
# bound arrays by per-ray offsets), today's (head), and today's with dc23808's selects back (f1),
# with d888313's push-every-child loop back (f2), and both (f12).
set -u
R=$(pwd); T=/work/main/build/tandem; W=/tmp/r3; mkdir -p $W
S=$(date +%s); el() { echo "[$(( $(date +%s) - S ))s] $*"; }
ks() { python3 -c 'import json,sys;print(json.load(sys.stdin)["kernel_seconds"])'; }
render() { $T render $R/scenes/$1.xml -D res=512 --spp 256 --seed 1 --out /tmp/r.exr --json | ks; }
{
for round in 1 2; do
  for s in cbox-wall indirect-room; do
    echo "render $round $s head $(render $s)"
    for k in ad82770 d888313 dc23808 f1 f2 f12; do
      echo "render $round $s $k $(TANDEM_KERNEL_DIR=/tmp/app/kern_$k render $s)"
    done
  done
done
} > $W/renders.txt 2>$W/renders.err; el renders
