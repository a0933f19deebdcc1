#!/bin/bash
# usage (from the repository root): MESH=file bench/data/trace_prefetch/ab.sh rounds -> "round pf set rate embree ratio"; alternates TANDEM_BVH_PREFETCH=0/1
rounds=$1
for r in $(seq $rounds); do
  if [ $((r % 2)) = 1 ]; then order="1 0"; else order="0 1"; fi
  for v in $order; do
    TANDEM_BVH_PREFETCH=$v build/tandem bench trace --mesh ${MESH:-build/scenes/meshes/knot.ply} --rays 262144 --repeats 3 2>&1 | grep -E "^(coherent|incoherent|shadow)" | awk -v r=$r -v kd=pf$v '{print r, kd, $1, $7, $8, $11}'
  done
done
