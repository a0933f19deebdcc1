// A stand-in for bench/kernels/trace.cl that Oclgrind 21.10 cannot create, for oclgrind.kernel_creation_error
// (tests/CMakeLists.txt): inlining a function with `restrict` arguments leaves calls to
// llvm.experimental.noalias.scope.decl, an intrinsic Oclgrind 21.10 cannot run (see
// kernels/shared/compat.h). The Tracer creates trace_closest_bvh2 first.
void copy2(__global float* restrict out, __global const float* restrict in) {
    out[0] = in[0];
    out[1] = in[1];
}

__kernel void trace_closest_bvh2(__global float* out, __global const float* in) { copy2(out, in); }
