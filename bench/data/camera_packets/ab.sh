#!/bin/bash
# Kernel seconds of `tandem render` with TANDEM_CAMERA_PACKETS=0 and 1, alternating which runs first,
# from the repository root; one line per render: round, scene, packets, seconds (summarize.py).
# usage: abpk.sh rounds spp scenes... ; A = TANDEM_CAMERA_PACKETS=0, B = default (1)
rounds=$1; spp=$2; shift 2
for r in $(seq 1 $rounds); do
  for s in "$@"; do
    for v in 0 1; do
      if [ $(( (r + v) % 2 )) -eq 0 ]; then o=0; else o=1; fi
      t=$(TANDEM_CAMERA_PACKETS=$o ${TANDEM:-build/tandem} render scenes/$s.xml --spp $spp --seed 1 --json --out /tmp/ab_$s.exr 2>/dev/null | python3 -c "import json,sys; print(json.load(sys.stdin)['kernel_seconds'])")
      echo "$r $s $o $t"
    done
  done
done
