// Layout probe: reports the device compiler's sizeof/offsetof of every shared struct, in the order
// of TANDEM_SHARED_LAYOUT, so tests/kernels/test_layout.cpp can compare them with the host.
#pragma OPENCL FP_CONTRACT OFF

#include "probes/layout_probe.h"

#define PROBE_STRUCT(T)                                                                            \
    {                                                                                              \
        out[n++] = (uint)sizeof(T);                                                                \
    }
#define PROBE_FIELD(T, f)                                                                          \
    {                                                                                              \
        T probe;                                                                                   \
        out[n++] = (uint)((char*)&probe.f - (char*)&probe);                                        \
    }

/// Writes out[0..n): for each struct its size, then the offset of each of its fields.
/// Writes out[capacity - 1] = n, the number of entries. Run with one work item.
__kernel void layout_probe(__global uint* out, uint capacity) {
    if (get_global_id(0) != 0) return;
    uint n = 0;
    TANDEM_SHARED_LAYOUT(PROBE_STRUCT, PROBE_FIELD)
    out[capacity - 1] = n;
}
