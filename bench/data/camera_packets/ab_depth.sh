#!/bin/bash
# As ab.sh, at a given max_depth: ab_depth.sh ROUNDS SPP MAX_DEPTH SCENES...
rounds=$1; spp=$2; depth=$3; shift 3
for r in $(seq 1 $rounds); do
  for s in "$@"; do
    for v in 0 1; do
      if [ $(( (r + v) % 2 )) -eq 0 ]; then o=0; else o=1; fi
      t=$(TANDEM_CAMERA_PACKETS=$o ${TANDEM:-build/tandem} render scenes/$s.xml -D max_depth=$depth --spp $spp --seed 1 --json --out /tmp/ab_$s.exr 2>/dev/null | python3 -c "import json,sys; print(json.load(sys.stdin)['kernel_seconds'])")
      echo "$r $s $o $t"
    done
  done
done
