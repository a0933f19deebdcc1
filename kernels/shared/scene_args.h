// The scene's kernel arguments, written once: every kernel that traces paths takes them first, in
// this order, and the host binds them from the same list (core/render/device_scene.h). A test
// (tests/core/render/test_device_scene.cpp) reads the compiled kernels' argument names and types back
// from the OpenCL implementation and checks them against this list.
#ifndef TANDEM_SHARED_SCENE_ARGS_H
#define TANDEM_SHARED_SCENE_ARGS_H

#include "shared/bvh_layout.h"
#include "shared/scene_layout.h"

/// TANDEM_SCENE_ARGS(BUFFER, VALUE) expands BUFFER(T, name) for each read-only device array
/// (__global const T* name on the device, a Buffer<T> on the host) and VALUE(T, name) for
/// each struct passed by value, in argument order. `nodes` holds BvhNode, Bvh4Node or Bvh8Node
/// records (BVH_WIDTH), as float4 rows.
#define TANDEM_SCENE_ARGS(BUFFER, VALUE)                                                           \
    BUFFER(float4, nodes)           /* BVH nodes, depth-first (shared/bvh_layout.h) */           \
    BUFFER(BvhTriangle, tris)       /* primitive records in BVH leaf order, world space */       \
    BUFFER(ShadingPrimitive, prims) /* primitive records in primitive order, world space */      \
    BUFFER(TriangleInfo, infos)     /* per primitive: material and emitter */                    \
    BUFFER(TriangleUV, uvs)         /* per primitive: vertex texture coordinates */              \
    BUFFER(TextureInfo, textures)   /* every texture of the scene, in file order */              \
    BUFFER(float4, texels)          /* texels of bitmaps that are not parameters, linear RGB */  \
    BUFFER(Material, materials)     /* scene bsdfs, then the defaults: diffuse 0.5, black */     \
    BUFFER(EmissiveTriangle, emissive) /* area-light triangles, world space */                   \
    BUFFER(DeltaLight, delta_lights)   /* point and spot lights */                               \
    BUFFER(AliasEntry, alias)       /* light selection: emissive, then delta lights */           \
    BUFFER(float4, env_texels)      /* environment map: rgb radiance, w sampling weight */       \
    BUFFER(float, env_cdf)          /* environment map cell CDFs: marginal, conditionals */      \
    BUFFER(float, plastic_tables)   /* roughplastic interface tables (shared/plastic_table.h) */ \
    BUFFER(Medium, media)           /* participating media (HAS_MEDIA builds) */                 \
    BUFFER(DeviceGrid, grids)       /* the media's voxel grids and majorant grids */             \
    BUFFER(float, medium_data)      /* the grids' voxels */                                      \
    BUFFER(uint4, prim_params)      /* per primitive: its vertices' parameters (SHAPE_GRAD) */   \
    BUFFER(TriangleNormals, normals) /* per primitive: shading normals (HAS_SHADING_NORMALS) */  \
    BUFFER(NormalJacobian, normal_jac) /* derived normals' derivatives (HAS_SHADING_NORMALS) */  \
    VALUE(EnvMap, envmap)           /* environment map record (unused without HAS_ENVMAP) */     \
    VALUE(DeviceCamera, cam)        /* the sensor */

#if TANDEM_DEVICE
#define TANDEM_SCENE_ARG_BUFFER(T, name) __global const T *name,
#define TANDEM_SCENE_ARG_VALUE(T, name) T name,
/// The scene's parameters at the head of a kernel signature, each followed by a comma: write the
/// kernel's own parameters after it, `__kernel void k(SCENE_ARGS RenderParams rp, ...)`.
#define SCENE_ARGS TANDEM_SCENE_ARGS(TANDEM_SCENE_ARG_BUFFER, TANDEM_SCENE_ARG_VALUE)
#endif

#endif // TANDEM_SHARED_SCENE_ARGS_H
