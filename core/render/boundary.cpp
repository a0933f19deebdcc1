// Edge tables and the pass of the primary boundary term.
#include "core/render/boundary.h"

#include "core/render/boundary_guide.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "runtime/error.h"

namespace tandem {

namespace {

gpu::float3 f3(const glm::vec3& v) { return {v.x, v.y, v.z}; }

/// The film positions (pixels) and depth of p.
struct Projected {
    float x, y, z;
};
Projected project(const gpu::DeviceCamera& cam, const glm::vec3& p) {
    Projected r{};
    gpu::camera_project(&cam, f3(p), &r.x, &r.y, &r.z);
    return r;
}

/// Liang-Barsky: narrows [u0, u1] to the part of the film segment a + u (b - a) inside
/// [0, w] x [0, h]; false when none is.
bool clip_to_film(const Projected& a, const Projected& b, float w, float h, float& u0, float& u1) {
    const float dx = b.x - a.x, dy = b.y - a.y;
    const std::array<float, 4> p{-dx, dx, -dy, dy};
    const std::array<float, 4> q{a.x, w - a.x, a.y, h - a.y};
    for (int i = 0; i < 4; ++i) {
        if (p[i] == 0.0f) {
            if (q[i] < 0.0f) return false;
            continue;
        }
        const float r = q[i] / p[i];
        if (p[i] < 0.0f) u0 = std::max(u0, r);
        else u1 = std::min(u1, r);
    }
    return u0 < u1;
}

/// The piece of edge v0 -> v1 (parameters params0, params1) that the camera sees on its film, if
/// any, with its film length (pmf left 0).
bool edge_piece(const gpu::DeviceCamera& cam, const glm::vec3& v0, const glm::vec3& v1,
                unsigned param0, unsigned param1, gpu::BoundaryEdge& out) {
    // clip to the near plane, where depth is linear in t
    const float z0 = project(cam, v0).z, z1 = project(cam, v1).z;
    const float near = cam.near_clip;
    float t0 = 0.0f, t1 = 1.0f;
    if (z0 < near && z1 < near) return false;
    if (z0 < near) t0 = (near - z0) / (z1 - z0);
    if (z1 < near) t1 = (near - z0) / (z1 - z0);
    const glm::vec3 a3 = v0 + (v1 - v0) * t0, b3 = v0 + (v1 - v0) * t1;
    const Projected a = project(cam, a3), b = project(cam, b3);
    float u0 = 0.0f, u1 = 1.0f;
    if (!clip_to_film(a, b, float(cam.width), float(cam.height), u0, u1)) return false;
    // film fractions u to the segment's own parameter (1/z is linear on the film)
    const float tau0 = gpu::edge_perspective_tau(u0, a.z, b.z);
    const float tau1 = gpu::edge_perspective_tau(u1, a.z, b.z);
    const glm::vec3 pa = a3 + (b3 - a3) * tau0, pb = a3 + (b3 - a3) * tau1;
    const float ta = t0 + (t1 - t0) * tau0, tb = t0 + (t1 - t0) * tau1;
    const Projected fa = project(cam, pa), fb = project(cam, pb);
    const float length = std::hypot(fb.x - fa.x, fb.y - fa.y);
    if (!(length > 1e-6f) || !std::isfinite(length)) return false;
    out.a = gpu::make_float4(pa.x, pa.y, pa.z, ta);
    out.b = gpu::make_float4(pb.x, pb.y, pb.z, tb);
    out.param0 = param0;
    out.param1 = param1;
    out.length = length;
    out.pmf = 0.0f;
    return true;
}

glm::vec3 face_normal(const TriangleMesh& m, const glm::uvec3& t) {
    const glm::vec3 n = glm::cross(m.positions[t.y] - m.positions[t.x],
                                   m.positions[t.z] - m.positions[t.x]);
    const float len = glm::length(n);
    return len > 0.0f ? n / len : glm::vec3(0.0f);
}

/// An edge across which shading may jump: its vertices (the first face's, lo before hi in vertex
/// order) and its one or two faces (a second face only where exactly two share it).
struct JumpEdge {
    unsigned lo, hi;
    glm::vec3 n0, n1;
    bool two_faces;
};

/// The edges of mesh shape `s` except those between two coplanar triangles (nothing jumps there).
/// Vertices at the same position are one point of the surface (a cube's faces, or a seam of
/// texture coordinates, split them): edges are found between positions, so that a cube's edge is
/// one edge of two faces, not two borders. Its term goes to the vertices of its first face (in
/// triangle order): the derivative of moving the surface there, whose copies a caller that keeps
/// them together (Large Steps welds them) sums.
std::vector<JumpEdge> jump_edges(const TriangleMesh& m, const MeshShape& s) {
    const std::vector<unsigned> weld =
        weld_by_position(m.positions.data() + s.first_vertex, s.vertex_count);
    struct Side {
        unsigned lo, hi, tri, a, b; ///< welded ends (lo < hi), triangle, its own vertices
    };
    std::vector<Side> sides;
    sides.reserve(3 * std::size_t(s.triangle_count));
    for (unsigned i = 0; i < s.triangle_count; ++i) {
        const glm::uvec3& t = m.triangles[s.first_triangle + i];
        const unsigned v[3] = {t.x, t.y, t.z};
        for (int k = 0; k < 3; ++k) {
            const unsigned a = v[k], b = v[(k + 1) % 3];
            const unsigned wa = weld[a - s.first_vertex], wb = weld[b - s.first_vertex];
            if (wa == wb) continue;
            sides.push_back({std::min(wa, wb), std::max(wa, wb), s.first_triangle + i,
                             wa < wb ? a : b, wa < wb ? b : a});
        }
    }
    std::sort(sides.begin(), sides.end(), [](const Side& x, const Side& y) {
        return x.lo != y.lo ? x.lo < y.lo : x.hi != y.hi ? x.hi < y.hi : x.tri < y.tri;
    });
    std::vector<JumpEdge> out;
    for (std::size_t i = 0; i < sides.size();) {
        std::size_t j = i + 1;
        while (j < sides.size() && sides[j].lo == sides[i].lo && sides[j].hi == sides[i].hi) ++j;
        JumpEdge e{sides[i].a, sides[i].b, face_normal(m, m.triangles[sides[i].tri]),
                   glm::vec3(0.0f), j - i == 2};
        if (e.two_faces) e.n1 = face_normal(m, m.triangles[sides[i + 1].tri]);
        if (!e.two_faces || glm::dot(e.n0, e.n1) < 1.0f - 1e-6f) out.push_back(e);
        i = j;
    }
    return out;
}

} // namespace

bool differentiates_geometry(const RenderScene& scene, const GradientBuffers& grad) {
    if (!grad.selected()) return false;
    for (const MeshShape& s : scene.mesh_shapes)
        if (s.vertex_count && grad.differentiated(s.param)) return true;
    return false;
}

void check_shape_gradients(const RenderScene& scene, const GradientBuffers& grad, bool reuse) {
    const std::string no = "shape gradients (vertex_positions) do not cover ";
    if (!scene.media.empty()) throw Error(no + "participating media yet");
    for (const MeshShape& s : scene.mesh_shapes) {
        if (!s.vertex_count || !grad.differentiated(s.param)) continue;
        if (reuse) {
            // a reservoir's point on it is found again under the previous positions, in the
            // geometry of that state (path/resample.h, DeviceScene::geometry_at); the lights
            // stay where they were
            for (unsigned i = 0; i < s.triangle_count; ++i)
                if (scene.infos[s.first_triangle + i].emitter != NO_EMITTER)
                    throw Error(no + "reused light samples with a moving emitter yet (" + s.name +
                                ")");
        }
        for (unsigned i = 0; i < s.triangle_count; ++i) {
            const gpu::Material& m = scene.materials.at(scene.infos[s.first_triangle + i].material);
            if (m.flags & MATERIAL_FLAG_BLACK) continue; // an emitter's: no term depends on it
            // a bilinear bitmap is continuous under the sliding hit (kernels/path/shape_adjoint.h:
            // shape_vertex_texture); the jumps of nearest texels and checkerboards are
            // discontinuities that no boundary term samples
            const gpu::TextureInfo* t =
                m.texture == NO_TEXTURE ? nullptr : &scene.textures.at(m.texture);
            // a delta BSDF (conductor, dielectric) would move the vertex after it with its
            // surface: the replay keeps that vertex where it is (kernels/path/shape_adjoint.h)
            if (m.type != MATERIAL_DIFFUSE && m.type != MATERIAL_ROUGHCONDUCTOR &&
                m.type != MATERIAL_ROUGHPLASTIC)
                throw Error(no + "a moving shape whose bsdf is smooth (a mirror or glass: " + s.name +
                            "); diffuse, roughconductor and roughplastic move");
            if (t && (t->kind == TEXTURE_CHECKERBOARD || t->filter == TEXTURE_FILTER_NEAREST))
                throw Error(no + "a moving shape textured but by a bilinear bitmap, yet (" + s.name +
                            ")");
        }
    }
}

std::vector<gpu::BoundaryEdge> primary_edges(const RenderScene& scene, const TriangleMesh& m,
                                             const gpu::DeviceCamera& cam,
                                             const GradientBuffers& grad) {
    std::vector<gpu::BoundaryEdge> out;
    if (!grad.selected()) return out;
    for (const MeshShape& s : scene.mesh_shapes) {
        if (!s.vertex_count || !grad.differentiated(s.param)) continue;
        for (const JumpEdge& j : jump_edges(m, s)) {
            gpu::BoundaryEdge e{};
            if (edge_piece(cam, m.positions[j.lo], m.positions[j.hi],
                           s.param + 3 * (j.lo - s.first_vertex),
                           s.param + 3 * (j.hi - s.first_vertex), e))
                out.push_back(e);
        }
    }
    double total = 0.0;
    for (const gpu::BoundaryEdge& e : out) total += e.length;
    for (gpu::BoundaryEdge& e : out) e.pmf = static_cast<float>(e.length / total);
    return out;
}

std::vector<gpu::SecondaryEdge> secondary_edges(const RenderScene& scene, const TriangleMesh& m,
                                                const GradientBuffers& grad) {
    std::vector<gpu::SecondaryEdge> out;
    if (!differentiates_geometry(scene, grad)) return out;
    for (const MeshShape& s : scene.mesh_shapes) {
        const bool moving = s.vertex_count && grad.differentiated(s.param);
        for (const JumpEdge& j : jump_edges(m, s)) {
            const glm::vec3 &a = m.positions[j.lo], &b = m.positions[j.hi];
            if (!(glm::length(b - a) > 0.0f)) continue;
            const unsigned pa = moving ? s.param + 3 * (j.lo - s.first_vertex) : NO_PARAM;
            const unsigned pb = moving ? s.param + 3 * (j.hi - s.first_vertex) : NO_PARAM;
            gpu::SecondaryEdge e{};
            e.p0 = gpu::make_float4(a.x, a.y, a.z, gpu::as_float(pa));
            e.p1 = gpu::make_float4(b.x, b.y, b.z, gpu::as_float(pb));
            e.n0 = gpu::make_float4(j.n0.x, j.n0.y, j.n0.z, glm::length(b - a)); // pmf below
            e.n1 = gpu::make_float4(j.n1.x, j.n1.y, j.n1.z, j.two_faces ? 1.0f : 0.0f);
            out.push_back(e);
        }
    }
    double total = 0.0;
    for (const gpu::SecondaryEdge& e : out) total += e.n0.w;
    for (gpu::SecondaryEdge& e : out) e.n0.w = static_cast<float>(e.n0.w / total);
    return out;
}

void accumulate_secondary_boundary(const View& view, const Buffer<float>& params,
                                   std::uint32_t seed, int per_pixel, int guide_mode,
                                   bool light_pairs, const Buffer<float>& delta,
                                   GradientBuffers& grad, SecondaryReservoirs* reuse) {
    DeviceScene& scene = *view.scene;
    // max_depth 0 renders black and 1 sees emission alone: no path reaches past a receiver (the
    // kernel's max_depth - 1 would wrap 0 to unbounded)
    const int max_depth = scene.scene().max_depth;
    if (per_pixel <= 0 || (max_depth >= 0 && max_depth < 2)) return;
    std::vector<gpu::SecondaryEdge> edges = secondary_edges(scene.scene(), scene.mesh(), grad);
    if (edges.empty()) return;
    Context& ctx = scene.context();
    Buffer<gpu::SecondaryEdge> edge_buffer(ctx, "secondary edges", edges, CL_MEM_READ_ONLY);
    const auto edge_count = static_cast<unsigned>(edges.size());
    SecondaryGuideTables guide;
    if (guide_mode == 1 || (guide_mode < 0 && secondary_guided(scene.scene()))) {
        const SecondaryGuideShape shape;
        guide = train_secondary_guide(view, params, seed, per_pixel, edge_buffer, edge_count, shape);
        guide_edge_choice(guide, shape, edges);
        edge_buffer.upload(edges);
    }
    std::vector<double> weights;
    for (const gpu::SecondaryEdge& e : edges) weights.push_back(e.n0.w);
    const Buffer<gpu::AliasEntry> alias(ctx, "secondary edge alias table",
                                        build_alias_table(weights), CL_MEM_READ_ONLY);
    const Buffer<unsigned> guide_edges(ctx, "secondary guide edges", at_least_one(guide.edge_slot),
                                       CL_MEM_READ_ONLY);
    const Buffer<float> guide_cdf(ctx, "secondary guide", at_least_one(guide.cdf), CL_MEM_READ_ONLY);
    const Buffer<gpu::float4> chunks(ctx, "emissive chunks",
                                     emissive_chunks(scene.emissive_triangles()), CL_MEM_READ_ONLY);
    const float p_delta = delta_light_share(scene.emissive_triangles());
    const auto pixels = static_cast<unsigned>(view.pixels());
    const float inv_samples = 1.0f / (float(per_pixel) * float(pixels));
    const SecondaryPairList pairs = light_pairs && !reuse
                                        ? secondary_light_pairs(edges, scene.emissive_triangles())
                                        : SecondaryPairList{};
    const Buffer<gpu::uint2> list(ctx, "secondary pairs", at_least_one(pairs.list),
                                  CL_MEM_READ_ONLY);
    const Buffer<float> pair_pmf(ctx, "secondary pair pmf", at_least_one(pairs.pmf),
                                 CL_MEM_READ_ONLY);
    const Buffer<gpu::AliasEntry> pair_alias(
        ctx, "secondary pair alias table",
        pairs.pmf.empty() ? std::vector<gpu::AliasEntry>(1)
                          : build_alias_table(std::vector<double>(pairs.pmf.begin(), pairs.pmf.end())),
        CL_MEM_READ_ONLY);
    const Buffer<unsigned> starts(ctx, "secondary pair starts", at_least_one(pairs.first),
                                  CL_MEM_READ_ONLY);
    const Buffer<gpu::uint2> lights(ctx, "secondary pair lights", at_least_one(pairs.lights),
                                    CL_MEM_READ_ONLY);
    // the reuse's reservoirs, or placeholders the kernel does not read (enabled 0)
    gpu::SecondaryReuse settings{};
    std::optional<SecondaryReservoirs> none;
    if (reuse) {
        if (scene.features().get("RESTIR") != 1)
            throw Error("secondary reuse: the device scene was not built with RESTIR=1 "
                        "(restir_features)");
        settings = reuse->begin(scene.scene(), edges, std::size_t(per_pixel) * pixels);
    }
    else
        none.emplace(ctx, SecondaryReuseConfig{});
    SecondaryReservoirs& r = reuse ? *reuse : *none;
    scene.launch(view.sensor, scene.kernel("boundary.cl", "boundary_secondary"), "boundary",
                 view.pixels(), scene.launch_params(seed), params, delta, grad.exponent,
                 edge_buffer, alias, edge_count, guide.guide, guide_edges, guide_cdf, chunks,
                 p_delta, list, pair_pmf, pair_alias, starts, lights,
                 static_cast<unsigned>(pairs.list.size()),
                 static_cast<float>(k_secondary_pair_share), settings, r.previous(),
                 r.previous_edges(), r.bucket_first(), r.bucket_slots(), r.current(),
                 static_cast<unsigned>(per_pixel), inv_samples, grad.active, grad.fixed,
                 scene.guards());
    if (reuse) reuse->commit(edges);
}

namespace {

/// The bounding sphere (centre, radius; double) of the corners of triangles [first, end): the
/// centre of their box, the radius to the farthest corner.
std::pair<glm::dvec3, double> bounding_sphere(const gpu::EmissiveTriangle* first,
                                              const gpu::EmissiveTriangle* end) {
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
    for (const gpu::EmissiveTriangle* t = first; t != end; ++t)
        for (const gpu::float4& p : {t->p0, t->p1, t->p2}) {
            lo = glm::min(lo, glm::dvec3(p.x, p.y, p.z));
            hi = glm::max(hi, glm::dvec3(p.x, p.y, p.z));
        }
    const glm::dvec3 c = 0.5 * (lo + hi);
    double r = 0.0;
    for (const gpu::EmissiveTriangle* t = first; t != end; ++t)
        for (const gpu::float4& p : {t->p0, t->p1, t->p2})
            r = std::max(r, glm::length(glm::dvec3(p.x, p.y, p.z) - c));
    return {c, r};
}

} // namespace

SecondaryPairList secondary_light_pairs(const std::vector<gpu::SecondaryEdge>& edges,
                                        const std::vector<gpu::EmissiveTriangle>& emissive) {
    SecondaryPairList out;
    if (emissive.empty()) return out;
    // the lights: runs of triangles of one emitter's radiance, each in a bounding sphere, and its
    // share of the light sampling's pmf (its power)
    struct Sphere {
        glm::dvec3 c;
        double r, power;
    };
    std::vector<Sphere> spheres;
    for (unsigned e = 0; e < emissive.size(); ++e) {
        if (e == 0 || emissive[e].radiance_param != emissive[e - 1].radiance_param)
            out.lights.push_back({e, 0u});
        ++out.lights.back().y;
    }
    for (const gpu::uint2& l : out.lights) {
        const gpu::EmissiveTriangle* first = emissive.data() + l.x;
        const auto [c, r] = bounding_sphere(first, first + l.y);
        double power = 0.0;
        for (const gpu::EmissiveTriangle* t = first; t != first + l.y; ++t) power += t->p1.w;
        spheres.push_back({c, r, power});
    }
    // the pairs: each edge with each light from some point of whose bounding sphere its two faces
    // may lie on opposite sides (a silhouette seen from there), weighted by the edge's length and
    // the light's power over the squared distance
    // one light: the plain sampler's light sampling already aims every direction at it (measured:
    // the pairs only took samples from the other parts of the mixture)
    int lit = 0;
    for (const Sphere& L : spheres) lit += L.power > 0.0;
    if (lit < 2 || double(edges.size()) * double(spheres.size()) > k_secondary_pair_tests) {
        out.lights.clear();
        return out;
    }
    std::vector<double> weight;
    for (unsigned i = 0; i < edges.size(); ++i) {
        const gpu::SecondaryEdge& e = edges[i];
        const glm::dvec3 a(e.p0.x, e.p0.y, e.p0.z), b(e.p1.x, e.p1.y, e.p1.z);
        const glm::dvec3 n0(e.n0.x, e.n0.y, e.n0.z), n1(e.n1.x, e.n1.y, e.n1.z);
        const glm::dvec3 mid = 0.5 * (a + b);
        const double len = glm::length(b - a);
        for (unsigned k = 0; k < spheres.size(); ++k) {
            const Sphere& L = spheres[k];
            const double d = glm::length(L.c - mid);
            if (!(d > L.r)) continue; // the edge inside a light's bounds: left to the plain share
            bool possible = true;
            if (e.n1.w != 0.0f) {
                const double s0 = glm::dot(n0, L.c - mid), s1 = glm::dot(n1, L.c - mid);
                // the planes hold the whole edge: n . (y - x_B) = n . (y - mid) along it
                const double slack = L.r;
                const bool both_above = s0 > slack && s1 > slack;
                const bool both_below = s0 < -slack && s1 < -slack;
                possible = !both_above && !both_below;
            }
            if (!possible) continue;
            out.list.push_back({i, k});
            weight.push_back(len * L.power / (d * d));
        }
    }
    double total = 0.0;
    for (double w : weight) total += w;
    if (!(total > 0.0)) {
        out.list.clear();
        out.lights.clear();
        return out;
    }
    for (double w : weight) out.pmf.push_back(static_cast<float>(w / total));
    out.first.assign(edges.size() + 1, 0u);
    for (const gpu::uint2& p : out.list)
        ++out.first[p.x + 1];
    for (std::size_t e = 0; e < edges.size(); ++e)
        out.first[e + 1] += out.first[e];
    return out;
}

std::vector<gpu::float4> emissive_chunks(const std::vector<gpu::EmissiveTriangle>& emissive) {
    // the sphere of triangles [first, end), rounded up past the float centre's error: no corner
    // outside
    const auto sphere = [&](std::size_t first, std::size_t end) {
        const auto [c, r] = bounding_sphere(emissive.data() + first, emissive.data() + end);
        const glm::vec3 cf(c);
        const double slack = 1e-6 * (glm::length(c) + r) + 1e-7;
        return gpu::make_float4(cf.x, cf.y, cf.z, static_cast<float>(r + slack));
    };
    std::vector<gpu::float4> chunks;
    for (std::size_t first = 0; first < emissive.size(); first += EMISSIVE_CHUNK)
        chunks.push_back(sphere(first, std::min(first + EMISSIVE_CHUNK, emissive.size())));
    if (chunks.empty()) return {gpu::make_float4(0.0f, 0.0f, 0.0f, 0.0f)};
    // the groups: runs of at most EMISSIVE_GROUP chunks, a run ending where the box of its chunks'
    // spheres would reach past EMISSIVE_GROUP_SPREAD times its widest chunk's radius from its
    // middle (another light, far away: one group over two lights would be near every ray between
    // them); each group's sphere then bounds its triangles
    const std::size_t n = chunks.size();
    for (std::size_t c = 0; c < n;) {
        const auto centre = [&](std::size_t k) {
            return glm::vec3(chunks[k].x, chunks[k].y, chunks[k].z);
        };
        const auto lo_of = [&](std::size_t k) { return centre(k) - chunks[k].w; };
        const auto hi_of = [&](std::size_t k) { return centre(k) + chunks[k].w; };
        glm::vec3 lo = lo_of(c), hi = hi_of(c);
        float widest = chunks[c].w;
        std::size_t end = c + 1;
        while (end < n && end - c < EMISSIVE_GROUP) {
            const glm::vec3 l = glm::min(lo, lo_of(end)), h = glm::max(hi, hi_of(end));
            const float w = std::max(widest, chunks[end].w);
            if (0.5f * glm::length(h - l) > EMISSIVE_GROUP_SPREAD * w) break;
            lo = l, hi = h, widest = w;
            ++end;
        }
        chunks.push_back(sphere(c * EMISSIVE_CHUNK, std::min(end * EMISSIVE_CHUNK, emissive.size())));
        // its chunks [c, end), as floats (exact: far fewer than 2^24)
        chunks.push_back(gpu::make_float4(float(c), float(end), 0.0f, 0.0f));
        c = end;
    }
    return chunks;
}

float delta_light_share(const std::vector<gpu::EmissiveTriangle>& emissive) {
    float p = 1.0f;
    for (const gpu::EmissiveTriangle& t : emissive)
        p -= t.p1.w;
    return p;
}

void accumulate_primary_boundary(const View& view, const Buffer<float>& params, std::uint32_t seed,
                                 int per_pixel, const Buffer<float>& delta, GradientBuffers& grad) {
    DeviceScene& scene = *view.scene;
    if (per_pixel <= 0) return;
    const std::vector<gpu::BoundaryEdge> edges =
        primary_edges(scene.scene(), scene.mesh(), scene.camera(view.sensor), grad);
    if (edges.empty()) return;
    std::vector<double> weights;
    for (const gpu::BoundaryEdge& e : edges) weights.push_back(e.length);
    Context& ctx = scene.context();
    const Buffer<gpu::BoundaryEdge> edge_buffer(ctx, "boundary edges", edges, CL_MEM_READ_ONLY);
    const Buffer<gpu::AliasEntry> alias(ctx, "boundary edge alias table",
                                        build_alias_table(weights), CL_MEM_READ_ONLY);
    const auto pixels = static_cast<unsigned>(view.pixels());
    const float inv_samples = 1.0f / (float(per_pixel) * float(pixels));
    scene.launch(view.sensor, scene.kernel("boundary.cl", "boundary_primary"), "boundary",
                 view.pixels(), scene.launch_params(seed), params, delta, grad.exponent,
                 edge_buffer, alias, static_cast<unsigned>(edges.size()),
                 static_cast<unsigned>(per_pixel), inv_samples, grad.active, grad.fixed,
                 scene.guards());
}

} // namespace tandem
