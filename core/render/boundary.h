// The primary boundary term of shape gradients (kernels/boundary.cl): the edge pieces of moving
// meshes that a sensor sees, and the pass that samples them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/render/boundary_reuse.h"
#include "core/render/device_scene.h"
#include "core/render/gradient_buffers.h"
#include "shared/boundary.h"

namespace tandem {

/// The edges across which sensor `cam`'s image of `scene`, its mesh as `mesh` (the device
/// scene's now: DeviceScene::mesh), may jump and which move: every edge of a mesh shape whose vertex positions grad differentiates, except those between two coplanar
/// triangles (the same plane on both sides: no jump there; a silhouette, a crease of face
/// normals, an open mesh's border and a non-manifold edge all stay). Each is clipped to the near
/// plane and to the film, and weighted by its film length (pmf). Empty when nothing moves or
/// nothing is in view.
std::vector<gpu::BoundaryEdge> primary_edges(const RenderScene& scene, const TriangleMesh& mesh,
                                             const gpu::DeviceCamera& cam,
                                             const GradientBuffers& grad);

/// Whether grad differentiates an element of a parameter that moves geometry (chosen with
/// GradientBuffers::differentiate_only: the all-elements default leaves shapes out).
bool differentiates_geometry(const RenderScene& scene, const GradientBuffers& grad);

/// The edges of the secondary term (kernels/path/boundary_secondary.h): every edge of every mesh
/// shape, except those between two coplanar triangles, with its faces' normals, weighted by
/// length; the vertices of the shapes grad differentiates carry their parameter offsets (the
/// others' edges still matter where a moving receiver sees them). Empty when nothing moves.
std::vector<gpu::SecondaryEdge> secondary_edges(const RenderScene& scene, const TriangleMesh& mesh,
                                                const GradientBuffers& grad);

/// Bounding spheres (xyz the centre, w the radius) of the emissive triangles in chunks of
/// EMISSIVE_CHUNK consecutive ones (shared/boundary.h), then the groups of consecutive chunks,
/// each as its sphere and its range of chunks (x, y: the first and one past the last, as exact
/// floats), for the secondary term's direction density; one zero sphere where there are none (a
/// buffer is never empty).
std::vector<gpu::float4> emissive_chunks(const std::vector<gpu::EmissiveTriangle>& emissive);

/// The point and spot lights' share of light sampling: one less every emissive triangle's
/// selection probability (p1.w), subtracted in table order in float, as the kernels did it.
float delta_light_share(const std::vector<gpu::EmissiveTriangle>& emissive);

/// Throws Error naming what is not built yet where grad differentiates vertex positions of
/// `scene` that its shape gradients cannot follow: a moving shape whose material is not a plain
/// diffuse one (the interior term differentiates diffuse f cos only), media, and, where the
/// passes reuse light samples (`reuse`: reservoirs), a moving emitter (kernels/path/resample.h;
/// docs/restir.md, "Moving shapes").
void check_shape_gradients(const RenderScene& scene, const GradientBuffers& grad, bool reuse);

/// The primary boundary term of view `view` for delta = dloss/d(image): `per_pixel` times the
/// film's pixels edge samples (kernels/boundary.cl, boundary_primary) with `seed`, added into
/// grad.fixed at the scale grad.exponent holds. Nothing when primary_edges() is empty.
void accumulate_primary_boundary(const View& view, const Buffer<float>& params, std::uint32_t seed,
                                 int per_pixel, const Buffer<float>& delta, GradientBuffers& grad);

/// Light pairs of the secondary term. With many lights, few of the plain sampler's (edge point,
/// direction) pairs count: the direction must aim at a light, and the edge be a silhouette seen
/// from it (on a blob under twelve small lights, 0.2 % of samples push anything). So with
/// probability k_secondary_pair_share a sample draws instead one pair (edge, light) of
/// secondary_light_pairs(), a point uniform along the edge and, to aim at, a point uniform on a
/// triangle of the light drawn uniformly. Every sample is weighed by the mixture's density,
/// evaluated whichever part drew it (kernels/path/boundary_pairs.h: secondary_pair_density),
/// and every point and direction the plain sampler reaches keeps 1 - k_secondary_pair_share of its
/// density, so the term stays unbiased whatever the pairs hold. Off by default
/// (BoundarySamples::light_pairs): docs/method.md, "Light pairs", says what is measured and what
/// is not settled.
constexpr double k_secondary_pair_share = 0.5;

/// The pairs as the kernel reads them: sorted by edge, then light; first[e] .. first[e + 1] - 1
/// are edge e's (edges + 1 entries); every list empty where there are none.
struct SecondaryPairList {
    std::vector<gpu::uint2> list;   ///< (edge, light)
    std::vector<float> pmf;         ///< each pair's probability
    std::vector<unsigned> first;
    std::vector<gpu::uint2> lights; ///< (first triangle, count): runs of one radiance parameter
};
/// The light pairs of `edges` (secondary_edges()) under the area lights of `emissive` (a light: a
/// run of triangles of one radiance parameter): each edge with each light from some point of
/// whose bounding sphere its two faces may lie on opposite sides (a border: with every light), at
/// a pmf proportional to the edge's length times the light's share of the power over the squared
/// distance between them. None with fewer than two lights of any power (one light's directions
/// the plain sampler's light sampling already aims at: on tests/scenes/shape-shadow.xml the pairs
/// only took samples from the rest of the mixture), or where edges times lights exceed
/// k_secondary_pair_tests.
SecondaryPairList secondary_light_pairs(const std::vector<gpu::SecondaryEdge>& edges,
                                        const std::vector<gpu::EmissiveTriangle>& emissive);
/// The most edge-light tests secondary_light_pairs() makes (about 0.1 s on one core).
constexpr double k_secondary_pair_tests = 5e7;

/// The secondary boundary term (kernels/boundary.cl, boundary_secondary): `per_pixel` times the
/// film's pixels samples over secondary_edges(), with `seed`, guided (core/render/boundary_guide.h)
/// where `guide` is 1, or -1 and secondary_guided(), and with light pairs where `light_pairs`
/// (above), and reusing light vertices across iterations where `reuse` is set (no light pairs then:
/// core/render/boundary_reuse.h; a scene built with RESTIR=1, else Error), whose reservoirs it
/// advances. Nothing for a scene whose paths
/// have one segment (max_depth 1) or where nothing moves.
void accumulate_secondary_boundary(const View& view, const Buffer<float>& params,
                                   std::uint32_t seed, int per_pixel, int guide, bool light_pairs,
                                   const Buffer<float>& delta, GradientBuffers& grad,
                                   SecondaryReservoirs* reuse = nullptr);

} // namespace tandem
