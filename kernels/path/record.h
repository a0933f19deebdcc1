// What the PRB adjoint's first pass keeps of a path for its replay (kernels/adjoint.cl): the
// outcome of each NEE shadow ray, one bit per vertex, and the hits of its first bounces. The
// replay reads them instead of tracing the same rays again: it would ask the same questions of
// the same rays (it computes every primal value bit for bit), so the answers are the primal's.
// Neither grows with the path: 4 bytes of bits and 16 bytes per recorded bounce, a fixed number.
#ifndef TANDEM_KERNELS_PATH_RECORD_H
#define TANDEM_KERNELS_PATH_RECORD_H

#include "path/scene.h"

#ifndef SHADOW_RECORD
#error "SHADOW_RECORD must be passed as 0 or 1"
#endif

/// The vertex depths whose shadow ray a PathRecord holds (one bit each).
#define SHADOW_RECORD_DEPTHS 32u

/// One path's record. A vertex at depth SHADOW_RECORD_DEPTHS or deeper traces its shadow ray in
/// both passes, and so does every bounce from hit_bounces on.
typedef struct PathRecord {
    uint shadow;        ///< bit d: the shadow ray of the vertex at depth d reached its light
    int replay;         ///< 0: trace each ray and record it; 1: read what is recorded
    __global Hit* hits; ///< the hit of bounce d at hits[d * hit_stride], for d < hit_bounces
    uint hit_stride;
    uint hit_bounces;
} PathRecord;

/// A record to fill (replay 0) or read (replay 1) with `bounces` hits at `hits`, `stride` apart,
/// and the shadow bits `shadow` (0 to fill).
TANDEM_INLINE PathRecord path_record(int replay, uint shadow, __global Hit* hits, uint stride,
                                     uint bounces) {
    PathRecord r;
    r.shadow = shadow;
    r.replay = replay;
    r.hits = hits;
    r.hit_stride = stride;
    r.hit_bounces = bounces;
    return r;
}

/// trace_closest for bounce `depth` of a path with record `rec` (0: none, traced). One call of
/// trace_closest, so that the traversal is inlined once.
TANDEM_INLINE Hit record_closest(const SceneRefs* s, Ray ray, uint depth, PathRecord* rec) {
    const int kept = rec && depth < rec->hit_bounces;
    __global Hit* slot = kept ? rec->hits + depth * rec->hit_stride : 0;
    if (kept && rec->replay) return *slot;
    const Hit hit = trace_closest(s, ray);
    if (kept) *slot = hit;
    return hit;
}

/// `hit`, which the caller traced for bounce `depth` of a path with a record to fill (`rec`; 0:
/// none), kept in the record as record_closest would have kept it.
TANDEM_INLINE Hit record_traced(Hit hit, uint depth, PathRecord* rec) {
    if (rec && !rec->replay && depth < rec->hit_bounces) rec->hits[depth * rec->hit_stride] = hit;
    return hit;
}

#endif // TANDEM_KERNELS_PATH_RECORD_H
