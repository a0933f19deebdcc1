#!/bin/bash
# usage (from the repository root): bench/data/trace_prefetch/render_ab.sh rounds spp knotfile -> "scene round side kernel_s"; side old = TANDEM_BVH_PREFETCH=0, new = 1
rounds=$1; spp=$2; knot=$3; bin=${BIN:-build/tandem}
for r in $(seq $rounds); do
  if [ $((r % 2)) = 1 ]; then order="new old"; else order="old new"; fi
  for side in $order; do
    if [ $side = old ]; then v=0; else v=1; fi
    k=$(TANDEM_BVH_PREFETCH=$v $bin render bench/data/h200_layouts/cbox-knot.xml -D res=256 -D knot=$knot --spp $spp --seed 1 --out /tmp/abe_$side.exr --json 2>/dev/null | python3 -c 'import json,sys;print(json.load(sys.stdin)["kernel_seconds"])')
    echo "$(basename $knot .ply) $r $side $k"
  done
done
