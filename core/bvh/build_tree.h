// The temporary tree that Embree's rtcBuildBVH builds through Tandem's callbacks
// (core/bvh/bvh_build.cpp), before the leaf repacking (core/bvh/leaf_repack.h) and the flattening
// into the device layout. Nodes live in Embree's thread-local allocator and are freed with the
// RTCBVH.
#pragma once

#include <embree3/rtcore.h>

namespace tandem {

struct BuildNode {
    bool is_leaf;
};
struct BuildInner : BuildNode {
    BuildNode* children[8];
    RTCBounds bounds[8];
    unsigned child_count;
};
struct BuildLeaf : BuildNode {
    unsigned count;
    unsigned prims[1]; // `count` entries, allocated past the struct
};

} // namespace tandem
