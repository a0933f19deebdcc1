// Scene flattening for the path tracer.
#include "core/scene/render_scene.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/matrix.hpp>

#include "core/io/image_io.h"
#include "core/scene/bitmaps.h"
#include "core/scene/plastic_table.h"
#include "core/scene/shape_mesh.h"
#include "runtime/error.h"
#include "shared/sampling.h"

namespace tandem {

namespace {

std::string where(const SceneDesc& desc, int line) {
    return desc.path + ":" + std::to_string(line) + ": ";
}

gpu::float4 vec4(const glm::vec3& v, float w = 0.0f) { return gpu::make_float4(v.x, v.y, v.z, w); }

gpu::Material make_material(const SceneDesc& desc, const Bsdf& b, const BsdfParams& params) {
    auto in_unit = [](const glm::vec3& c) {
        return c.x >= 0 && c.y >= 0 && c.z >= 0 && c.x <= 1 && c.y <= 1 && c.z <= 1;
    };
    if (b.reflectance.texture < 0 && !in_unit(b.reflectance.value))
        throw Error(where(desc, b.line) + "bsdf '" + b.id + "': reflectance must be in [0, 1]");
    if (!in_unit(b.specular_reflectance.value))
        throw Error(where(desc, b.line) + "bsdf '" + b.id + "': specular_reflectance must be in [0, 1]");
    if (b.specular_reflectance.texture >= 0)
        throw Error(where(desc, b.line) + "bsdf '" + b.id + "': a textured specular_reflectance is not rendered yet");
    gpu::Material m{};
    m.reflectance_param = params.reflectance;
    m.specular_param = params.specular;
    m.alpha_param = params.alpha;
    m.reflectance = vec4(b.reflectance.value);
    m.specular = vec4(b.specular_reflectance.value);
    m.flags = (b.twosided ? MATERIAL_FLAG_TWOSIDED : 0u) | (b.nonlinear ? MATERIAL_FLAG_NONLINEAR : 0u);
    // A black diffuse that no parameter can change reflects nothing: paths end at it.
    if (b.type == BsdfType::diffuse && b.reflectance.texture < 0 &&
        params.reflectance == NO_PARAM && b.reflectance.value == glm::vec3(0.0f))
        m.flags |= MATERIAL_FLAG_BLACK;
    m.alpha = b.alpha;
    m.texture = b.reflectance.texture >= 0 ? static_cast<unsigned>(b.reflectance.texture) : NO_TEXTURE;
    switch (b.type) {
    case BsdfType::diffuse: m.type = MATERIAL_DIFFUSE; break;
    case BsdfType::null: m.type = MATERIAL_NULL; break;
    case BsdfType::conductor:
    case BsdfType::roughconductor:
        m.type = b.type == BsdfType::conductor ? MATERIAL_CONDUCTOR : MATERIAL_ROUGHCONDUCTOR;
        m.eta = vec4(b.eta);
        m.k = vec4(b.k);
        break;
    case BsdfType::dielectric:
    case BsdfType::roughplastic:
        m.type = b.type == BsdfType::dielectric ? MATERIAL_DIELECTRIC : MATERIAL_ROUGHPLASTIC;
        if (!(b.int_ior > 0.0f && b.ext_ior > 0.0f))
            throw Error(where(desc, b.line) + "bsdf '" + b.id + "': int_ior and ext_ior must be positive");
        m.eta = gpu::make_float4(b.int_ior / b.ext_ior, 0.0f, 0.0f, 0.0f);
        break;
    }
    if ((b.type == BsdfType::roughconductor || b.type == BsdfType::roughplastic) &&
        !(b.alpha > 0.0f && b.alpha <= 1.0f))
        throw Error(where(desc, b.line) + "bsdf '" + b.id + "': alpha must be in (0, 1]");
    return m;
}

/// Appends the interface table of each relative IOR of a roughplastic to rs.plastic_tables
/// (computed once per process: core/scene/plastic_table.h) and points the materials at it.
void add_plastic_tables(RenderScene& rs) {
    std::map<float, unsigned> offsets;
    for (gpu::Material& m : rs.materials) {
        if (m.type != MATERIAL_ROUGHPLASTIC) continue;
        const auto at = offsets.emplace(m.eta.x, static_cast<unsigned>(rs.plastic_tables.size()));
        if (at.second) {
            const std::vector<float>& table = plastic_table(m.eta.x);
            rs.plastic_tables.insert(rs.plastic_tables.end(), table.begin(), table.end());
        }
        m.plastic_table = at.first->second;
    }
}

/// The device record of texture t; a bitmap that is not a parameter appends its texels.
gpu::TextureInfo make_texture(const Texture& t, const Bitmap& bitmap, unsigned param,
                              std::vector<gpu::float4>& texels) {
    gpu::TextureInfo info{};
    info.param = param;
    info.uv_row0 = gpu::make_float4(t.to_uv[0][0], t.to_uv[1][0], t.to_uv[2][0], 0.0f);
    info.uv_row1 = gpu::make_float4(t.to_uv[0][1], t.to_uv[1][1], t.to_uv[2][1], 0.0f);
    if (t.kind == Texture::Kind::checkerboard) {
        info.kind = TEXTURE_CHECKERBOARD;
        info.color0 = vec4(t.color0);
        info.color1 = vec4(t.color1);
        return info;
    }
    info.kind = TEXTURE_BITMAP;
    info.width = static_cast<unsigned>(bitmap.width);
    info.height = static_cast<unsigned>(bitmap.height);
    info.filter = t.filter_type == "nearest" ? TEXTURE_FILTER_NEAREST : TEXTURE_FILTER_BILINEAR;
    if (param != NO_PARAM) return info; // the kernels read its texels from the parameters
    info.offset = static_cast<unsigned>(texels.size());
    const std::vector<float>& rgb = bitmap.rgb;
    for (std::size_t i = 0; i < std::size_t(bitmap.width) * bitmap.height; ++i)
        texels.push_back(gpu::make_float4(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2], 0.0f));
    return info;
}

/// Whether `m` is affine: no projective row.
bool affine(const glm::mat4& m) {
    return m[0][3] == 0.0f && m[1][3] == 0.0f && m[2][3] == 0.0f && m[3][3] == 1.0f;
}

/// `shape` as an analytic sphere, where it is one the kernels trace as such: a sphere that emits
/// nothing, whose to_world is a rotation, a uniform positive scale and a translation (as Mitsuba
/// requires). Its texture coordinates are taken in its own axes (kernels/path/interaction.h:
/// primitive_uv). A mirroring or uneven scale keeps the tessellation (shape_mesh), and so does an
/// area emitter, whose light sampling is over triangles.
std::optional<Sphere> analytic_sphere(const Shape& shape) {
    if (shape.type != ShapeType::sphere || shape.emitter >= 0) return std::nullopt;
    const glm::mat4& m = shape.to_world;
    if (!affine(m)) return std::nullopt;
    const glm::mat3 linear(m);
    const float k = glm::length(linear[0]);
    if (!(k > 0.0f) || !(glm::determinant(linear) > 0.0f)) return std::nullopt;
    const glm::mat3 rotation = linear * (1.0f / k);
    const glm::mat3 gram = glm::transpose(rotation) * rotation;
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r)
            if (std::fabs(gram[c][r] - (c == r ? 1.0f : 0.0f)) > 1e-6f) return std::nullopt;
    Sphere s;
    s.center = glm::vec3(m * glm::vec4(shape.center, 1.0f));
    s.radius = shape.radius * k;
    s.orientation = shape.flip_normals ? -1.0f : 1.0f;
    const glm::quat to_local = glm::normalize(glm::quat_cast(glm::transpose(rotation)));
    s.to_local = glm::vec4(to_local.x, to_local.y, to_local.z, to_local.w);
    return s;
}

/// `shape` as an analytic disk, where it is one the kernels trace as such: a disk that emits
/// nothing, whose to_world maps its plane by a rotation and a uniform scale (any scale along its
/// normal, which only decides the side it faces, and a translation). Otherwise it keeps the
/// tessellation. Its front faces Mitsuba's normal, to_world's inverse transpose of +z, turned by
/// flip_normals.
std::optional<Disk> analytic_disk(const Shape& shape) {
    if (shape.type != ShapeType::disk || shape.emitter >= 0) return std::nullopt;
    const glm::mat4& m = shape.to_world;
    if (!affine(m)) return std::nullopt;
    Disk d;
    d.center = glm::vec3(m[3]);
    d.x_axis = glm::vec3(m[0]);
    d.y_axis = glm::vec3(m[1]);
    const float r2 = glm::dot(d.x_axis, d.x_axis);
    const float det = glm::determinant(glm::mat3(m));
    if (!(r2 > 0.0f) || det == 0.0f ||
        std::fabs(glm::dot(d.y_axis, d.y_axis) - r2) > 1e-6f * r2 ||
        std::fabs(glm::dot(d.x_axis, d.y_axis)) > 1e-6f * r2)
        return std::nullopt;
    d.orientation = (det > 0.0f) != shape.flip_normals ? 1.0f : -1.0f;
    return d;
}

gpu::TriangleUV triangle_uv(const TriangleMesh& m, const glm::uvec3& t) {
    if (m.uvs.empty()) // Mitsuba: a mesh without uvs uses the barycentric parametrisation
        return {gpu::make_float4(0, 0, 1, 0), gpu::make_float4(0, 1, 0, 0)};
    const glm::vec2 a = m.uvs[t.x], b = m.uvs[t.y], c = m.uvs[t.z];
    return {gpu::make_float4(a.x, a.y, b.x, b.y), gpu::make_float4(c.x, c.y, 0, 0)};
}

} // namespace

std::vector<gpu::AliasEntry> build_alias_table(const std::vector<double>& weights) {
    const std::size_t n = weights.size();
    double sum = 0.0;
    for (double w : weights) sum += w;
    if (n == 0 || !(sum > 0.0)) throw Error("alias table: weights must have a positive sum");
    std::vector<double> scaled(n);
    std::vector<std::size_t> small, large;
    for (std::size_t i = 0; i < n; ++i) {
        scaled[i] = weights[i] * static_cast<double>(n) / sum;
        (scaled[i] < 1.0 ? small : large).push_back(i);
    }
    std::vector<gpu::AliasEntry> table(n);
    while (!small.empty() && !large.empty()) {
        const std::size_t s = small.back(), l = large.back();
        small.pop_back();
        table[s] = gpu::AliasEntry{static_cast<float>(scaled[s]), static_cast<unsigned>(l)};
        scaled[l] -= 1.0 - scaled[s];
        if (scaled[l] < 1.0) {
            large.pop_back();
            small.push_back(l);
        }
    }
    // Leftovers are 1 up to rounding: always keep the slot itself.
    for (std::size_t i : small) table[i] = gpu::AliasEntry{1.0f, static_cast<unsigned>(i)};
    for (std::size_t i : large) table[i] = gpu::AliasEntry{1.0f, static_cast<unsigned>(i)};
    return table;
}

void build_envmap(const std::vector<float>& rgb_in, int w_in, int h_in, const glm::mat4& to_world,
                  RenderScene& out) {
    // Mitsuba pads a map to at least 2 x 3 texels, repeating the last column and row (the
    // bilinear lookup needs two rows; the poles take one each).
    const int w = std::max(w_in, 2), h = std::max(h_in, 3);
    std::vector<float> rgb(std::size_t(w) * h * 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int k = 0; k < 3; ++k)
                rgb[3 * (std::size_t(y) * w + x) + k] =
                    rgb_in[3 * (std::size_t(std::min(y, h_in - 1)) * w_in + std::min(x, w_in - 1)) +
                           k];
    // Sampling weight of each texel, at its grid point (column x at u = (x + 1/2) / w, row y at
    // theta = pi y / (h - 1)): luminance times sin(theta). The density in (u, v) is their
    // bilinear interpolant (Mitsuba's warp over the same grid), normalised to integrate to 1.
    std::vector<double> weight(std::size_t(w) * h);
    bool lit = false;
    for (int y = 0; y < h; ++y) {
        const double s = (y == 0 || y == h - 1) ? 0.0 : std::sin(3.14159265358979 * y / (h - 1));
        for (int x = 0; x < w; ++x) {
            const float* c = &rgb[3 * (std::size_t(y) * w + x)];
            const double lum = std::max(0.0, 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]);
            weight[std::size_t(y) * w + x] = lum * s;
            lit |= lum > 0.0;
        }
    }
    // Cell (x, y) spans grid columns x, x + 1 (wrapping) and rows y, y + 1; its mass is the
    // mean of its four corners over the w (h - 1) cells.
    const int cells_y = h - 1;
    auto at = [&](int x, int y) { return weight[std::size_t(y) * w + (x % w)]; };
    std::vector<double> cell(std::size_t(w) * cells_y), row_sum(cells_y, 0.0);
    double total = 0.0;
    for (int y = 0; y < cells_y; ++y) {
        for (int x = 0; x < w; ++x) {
            const double m = 0.25 * (at(x, y) + at(x + 1, y) + at(x, y + 1) + at(x + 1, y + 1));
            cell[std::size_t(y) * w + x] = m;
            row_sum[y] += m;
        }
        total += row_sum[y];
    }
    if (!(total > 0.0))
        throw Error(lit ? "the environment map is black but for its first and last rows (the poles)"
                        : "the environment map is black");
    const double norm = total / (double(w) * cells_y); // the integral of the interpolant
    out.has_envmap = true;
    gpu::EnvMap& env = out.envmap;
    env.width = static_cast<unsigned>(w);
    env.height = static_cast<unsigned>(h);
    env.texel_offset = 0;
    env.cdf_offset = 0;
    env.total = static_cast<float>(norm);
    // to_local = inverse of to_world's linear part (GLM is column-major: inv[c][r])
    const glm::mat3 inv = glm::inverse(glm::mat3(to_world));
    env.to_local0 = vec4(glm::vec3(inv[0][0], inv[1][0], inv[2][0]));
    env.to_local1 = vec4(glm::vec3(inv[0][1], inv[1][1], inv[2][1]));
    env.to_local2 = vec4(glm::vec3(inv[0][2], inv[1][2], inv[2][2]));
    out.env_texels.resize(std::size_t(w) * h);
    for (std::size_t i = 0; i < out.env_texels.size(); ++i)
        out.env_texels[i] = gpu::make_float4(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2],
                                             static_cast<float>(weight[i] / norm));
    // The marginal CDF over cell rows, then each cell row's conditional CDF over its cells. An
    // entry past the last mass is exactly 1 (rows of zero mass get a uniform CDF): neither is
    // ever chosen.
    out.env_cdf.clear();
    double acc = 0.0;
    out.env_cdf.push_back(0.0f);
    for (int y = 0; y < cells_y; ++y) {
        acc += row_sum[y];
        out.env_cdf.push_back(acc >= total ? 1.0f : static_cast<float>(acc / total));
    }
    for (int y = 0; y < cells_y; ++y) {
        double racc = 0.0;
        out.env_cdf.push_back(0.0f);
        for (int x = 0; x < w; ++x) {
            racc += cell[std::size_t(y) * w + x];
            const float c =
                row_sum[y] > 0.0
                    ? (racc >= row_sum[y] ? 1.0f : static_cast<float>(racc / row_sum[y]))
                    : static_cast<float>(x + 1) / static_cast<float>(w);
            out.env_cdf.push_back(x + 1 == w ? 1.0f : c);
        }
    }
}

gpu::DeviceCamera make_device_camera(const Camera& c) {
    const float w = static_cast<float>(c.width), h = static_cast<float>(c.height);
    const float t = std::tan(0.5f * c.fov * 3.14159265358979f / 180.0f);
    FovAxis axis = c.fov_axis;
    if (axis == FovAxis::smaller) axis = w < h ? FovAxis::x : FovAxis::y;
    if (axis == FovAxis::larger) axis = w > h ? FovAxis::x : FovAxis::y;
    float tx = t, ty = t;
    if (axis == FovAxis::x) ty = t * h / w;
    if (axis == FovAxis::y) tx = t * w / h;
    if (axis == FovAxis::diagonal) {
        const float d = std::sqrt(w * w + h * h);
        tx = t * w / d;
        ty = t * h / d;
    }
    const glm::vec3 left = glm::normalize(glm::vec3(c.to_world[0]));
    const glm::vec3 up = glm::normalize(glm::vec3(c.to_world[1]));
    const glm::vec3 forward = glm::normalize(glm::vec3(c.to_world[2]));
    gpu::DeviceCamera cam{};
    cam.origin = vec4(glm::vec3(c.to_world[3]));
    cam.dir_x = vec4(left * tx);
    cam.dir_y = vec4(up * ty);
    cam.dir_z = vec4(forward);
    cam.near_clip = c.near_clip;
    cam.far_clip = c.far_clip;
    cam.width = static_cast<unsigned>(c.width);
    cam.height = static_cast<unsigned>(c.height);
    cam.medium = c.medium >= 0 ? static_cast<unsigned>(c.medium) : NO_MEDIUM;
    return cam;
}

RenderScene build_render_scene(const SceneDesc& desc, bool analytic_shapes) {
    RenderScene rs;
    rs.max_depth = desc.integrator.max_depth;
    rs.rr_depth = desc.integrator.rr_depth;
    rs.spp = desc.camera().spp;
    rs.sensors = desc.sensors;
    rs.cameras.clear();
    for (const Camera& c : desc.sensors) rs.cameras.push_back(make_device_camera(c));

    // Step 1: the parameters, then textures and materials, which read their offsets from them.
    // A shape without a bsdf gets Mitsuba's default (src/render/shape.cpp): diffuse 0.5, or a black
    // diffuse (reflectance 0) when it is an area emitter. Neither is a parameter.
    const std::vector<Bitmap> bitmaps = load_bitmaps(desc);
    rs.params = ParamRegistry(desc, bitmaps);
    for (std::size_t i = 0; i < desc.textures.size(); ++i)
        rs.textures.push_back(make_texture(desc.textures[i], bitmaps[i], rs.params.texture(i), rs.texels));
    for (std::size_t i = 0; i < desc.bsdfs.size(); ++i)
        rs.materials.push_back(make_material(desc, desc.bsdfs[i], rs.params.bsdf(i)));
    Bsdf fallback;
    fallback.id = "default";
    const auto default_material = static_cast<unsigned>(rs.materials.size());
    rs.materials.push_back(make_material(desc, fallback, BsdfParams{}));
    fallback.id = "default-emitter";
    fallback.reflectance.value = glm::vec3(0.0f);
    const auto default_emitter_material = static_cast<unsigned>(rs.materials.size());
    rs.materials.push_back(make_material(desc, fallback, BsdfParams{}));
    add_plastic_tables(rs);

    // Step 2: scene-level emitters.
    std::vector<double> delta_power;
    for (std::size_t i = 0; i < desc.emitters.size(); ++i) {
        const Emitter& e = desc.emitters[i];
        if (e.type == EmitterType::area) continue; // attached to shapes below
        if (e.type == EmitterType::point || e.type == EmitterType::spot) {
            gpu::DeltaLight d{};
            d.position = vec4(glm::vec3(e.to_world[3]));
            d.intensity = vec4(e.intensity);
            const float lum = 0.2126f * e.intensity.x + 0.7152f * e.intensity.y + 0.0722f * e.intensity.z;
            if (e.type == EmitterType::point) {
                d.type = DELTA_POINT;
                delta_power.push_back(4.0 * 3.14159265358979 * lum);
            } else {
                const float deg = 3.14159265358979f / 180.0f;
                const float cutoff = e.cutoff_angle * deg, beam = std::min(e.beam_width, e.cutoff_angle) * deg;
                d.type = DELTA_SPOT;
                d.axis = vec4(glm::normalize(glm::vec3(e.to_world * glm::vec4(0, 0, 1, 0))), std::cos(cutoff));
                d.cos_beam = std::cos(beam);
                d.cutoff = cutoff;
                d.inv_transition = cutoff > beam ? 1.0f / (cutoff - beam) : 0.0f;
                delta_power.push_back(2.0 * 3.14159265358979 * (1.0 - std::cos(cutoff)) * lum);
            }
            rs.delta_lights.push_back(d);
            continue;
        }
        if (rs.has_env) throw Error(where(desc, e.line) + "only one environment emitter is supported");
        rs.has_env = true;
        if (e.type == EmitterType::constant) {
            rs.env_param = rs.params.emitter(i); // its radiance times scale is a parameter
            continue;
        }
        int w = 0, h = 0;
        std::vector<float> rgb;
        try {
            rgb = read_image(e.filename, &w, &h, true);
        } catch (const Error& err) {
            throw Error(where(desc, e.line) + "envmap '" + e.id + "': " + err.what());
        }
        for (float& c : rgb) c *= e.scale;
        try {
            build_envmap(rgb, w, h, e.to_world, rs);
        } catch (const Error& err) {
            throw Error(where(desc, e.line) + "envmap '" + e.id + "' (" + e.filename + "): " + err.what());
        }
    }

    // Step 3: shapes, merged into one mesh (analytic spheres, then disks, after every triangle);
    // emissive triangles weighted by power.
    std::vector<double> power;
    std::vector<gpu::TriangleInfo> sphere_infos, disk_infos;
    for (const Shape& s : desc.shapes) {
        const unsigned material = s.bsdf >= 0      ? static_cast<unsigned>(s.bsdf)
                                  : s.emitter >= 0 ? default_emitter_material
                                                   : default_material;
        const unsigned interior = s.interior >= 0 ? static_cast<unsigned>(s.interior) : NO_MEDIUM;
        const unsigned exterior = s.exterior >= 0 ? static_cast<unsigned>(s.exterior) : NO_MEDIUM;
        const gpu::TriangleInfo plain{material, NO_EMITTER, interior, exterior};
        if (const std::optional<Sphere> sphere =
                analytic_shapes ? analytic_sphere(s) : std::nullopt) {
            rs.mesh.spheres.push_back(*sphere);
            sphere_infos.push_back(plain);
            continue;
        }
        if (const std::optional<Disk> disk = analytic_shapes ? analytic_disk(s) : std::nullopt) {
            rs.mesh.disks.push_back(*disk);
            disk_infos.push_back(plain);
            continue;
        }
        const TriangleMesh m = shape_mesh(s, desc.path);
        const auto base = static_cast<unsigned>(rs.mesh.positions.size());
        MeshShape ms;
        ms.name = s.id.empty() ? "shape" + std::to_string(&s - desc.shapes.data()) : s.id;
        ms.first_vertex = base;
        ms.vertex_count = static_cast<unsigned>(m.positions.size());
        ms.first_triangle = static_cast<unsigned>(rs.mesh.triangles.size());
        ms.triangle_count = static_cast<unsigned>(m.triangles.size());
        ms.param = rs.params.add_vertices(ms.name, &m.positions.data()->x, m.positions.size());
        ms.smooth = !m.normals.empty();
        ms.normals_derived = m.normals_derived;
        rs.mesh_shapes.push_back(ms);
        rs.mesh.positions.insert(rs.mesh.positions.end(), m.positions.begin(), m.positions.end());
        if (ms.smooth) {
            rs.mesh.normals.resize(base, glm::vec3(0.0f)); // zero for the flat shapes before
            rs.mesh.normals.insert(rs.mesh.normals.end(), m.normals.begin(), m.normals.end());
        }
        for (const glm::uvec3& t : m.triangles) {
            rs.mesh.triangles.push_back(t + glm::uvec3(base));
            rs.uvs.push_back(triangle_uv(m, t));
            gpu::TriangleInfo info = plain;
            if (s.emitter >= 0) {
                const Emitter& e = desc.emitters[static_cast<std::size_t>(s.emitter)];
                const glm::vec3 p0 = m.positions[t.x], p1 = m.positions[t.y], p2 = m.positions[t.z];
                const float area = 0.5f * glm::length(glm::cross(p1 - p0, p2 - p0));
                if (area > 0.0f) { // zero-area triangles emit nothing and are never sampled
                    info.emitter = static_cast<unsigned>(rs.emissive.size());
                    gpu::EmissiveTriangle et{};
                    et.radiance_param = rs.params.emitter(static_cast<std::size_t>(s.emitter));
                    et.p0 = vec4(p0, area);
                    et.p1 = vec4(p1);
                    et.p2 = vec4(p2);
                    const gpu::float3 n = gpu::triangle_front_normal(
                        {p0.x, p0.y, p0.z}, {p1.x, p1.y, p1.z}, {p2.x, p2.y, p2.z});
                    et.nx = n.x;
                    et.ny = n.y;
                    et.nz = n.z;
                    rs.emissive.push_back(et);
                    const glm::vec3& L = e.radiance;
                    power.push_back(double(area) * (0.2126 * L.x + 0.7152 * L.y + 0.0722 * L.z));
                }
            }
            rs.infos.push_back(info);
        }
    }
    rs.infos.insert(rs.infos.end(), sphere_infos.begin(), sphere_infos.end());
    rs.infos.insert(rs.infos.end(), disk_infos.begin(), disk_infos.end());
    rs.uvs.resize(rs.infos.size(), gpu::TriangleUV{}); // analytic shapes compute theirs (primitive_uv)
    if (!rs.mesh.normals.empty()) rs.mesh.normals.resize(rs.mesh.positions.size(), glm::vec3(0.0f));
    rs.mesh.source = desc.path;
    if (rs.mesh.primitive_count() == 0) throw Error(desc.path + ": the scene has no shapes");
    build_media(desc, rs);

    // Step 4: one alias table over emissive triangles, then point and spot lights, by power;
    // each light's selection probability goes in p1.w (triangles) or position.w (delta lights).
    power.insert(power.end(), delta_power.begin(), delta_power.end());
    if (!power.empty()) {
        double total = 0.0;
        for (double p : power) total += p;
        if (!(total > 0.0)) power.assign(power.size(), 1.0), total = double(power.size());
        rs.alias = build_alias_table(power);
        for (std::size_t i = 0; i < rs.emissive.size(); ++i)
            rs.emissive[i].p1.w = static_cast<float>(power[i] / total);
        for (std::size_t i = 0; i < rs.delta_lights.size(); ++i)
            rs.delta_lights[i].position.w = static_cast<float>(power[rs.emissive.size() + i] / total);
    }
    return rs;
}

const MeshShape& RenderScene::mesh_shape(const Parameter& p) const {
    for (const MeshShape& s : mesh_shapes)
        if (s.param == p.offset && p.kind == Parameter::Kind::vertices) return s;
    throw Error(p.name + " is not the vertex positions of a mesh shape");
}

std::vector<unsigned> RenderScene::shape_triangles(const MeshShape& s) const {
    std::vector<unsigned> out;
    for (unsigned t = 0; t < s.triangle_count; ++t)
        for (int c = 0; c < 3; ++c) out.push_back(mesh.triangles[s.first_triangle + t][c] - s.first_vertex);
    return out;
}

} // namespace tandem
