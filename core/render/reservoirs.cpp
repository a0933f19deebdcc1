// Light-sample reservoirs as the passes read them.
#include "core/render/reservoirs.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "runtime/error.h"

namespace tandem {

namespace {

/// The pixel radius of spatial reuse: 3 % of the film's smaller side, at least 4.
unsigned spatial_radius(const View& view) {
    const double side = std::min(view.width(), view.height());
    return std::max(4u, static_cast<unsigned>(std::lround(0.03 * side)));
}

/// RestirParams::radiance_floor: 1e-3 of the brightest light's luminance in the scene's own
/// values (area and constant-environment radiance, environment-map texels, point and spot
/// intensities), or 1e-3 without any: small against every light that matters, and fixed for the
/// run (a resumed run uses the same).
float radiance_floor(const RenderScene& scene) {
    auto lum = [](float r, float g, float b) { return 0.2126f * r + 0.7152f * g + 0.0722f * b; };
    const std::vector<float>& v = scene.params.values();
    float brightest = 0.0f;
    auto param = [&](unsigned offset) {
        if (offset != NO_PARAM && offset + 2 < v.size())
            brightest = std::max(brightest, lum(v[offset], v[offset + 1], v[offset + 2]));
    };
    for (const gpu::EmissiveTriangle& e : scene.emissive)
        param(e.radiance_param);
    param(scene.env_param);
    for (const gpu::float4& t : scene.env_texels)
        brightest = std::max(brightest, lum(t.x, t.y, t.z));
    for (const gpu::DeltaLight& d : scene.delta_lights)
        brightest = std::max(brightest, lum(d.intensity.x, d.intensity.y, d.intensity.z));
    return 1e-3f * (brightest > 0.0f && std::isfinite(brightest) ? brightest : 1.0f);
}

} // namespace

const char* restir_direct_name(RestirDirect d) {
    switch (d) {
    case RestirDirect::mis:
        return "mis";
    case RestirDirect::all:
        return "all";
    case RestirDirect::automatic:
        break;
    }
    return "auto";
}

RestirDirect restir_direct(const std::string& name) {
    for (RestirDirect d : {RestirDirect::mis, RestirDirect::all, RestirDirect::automatic})
        if (name == restir_direct_name(d)) return d;
    throw Error("'direct' must be \"auto\", \"all\" or \"mis\", not \"" + name + "\"");
}

void validate_restir_config(const RestirConfig& c, const std::string& where) {
    auto fail = [&](const std::string& what) { throw Error(where + ": " + what); };
    if (c.candidates < 1 || c.candidates > 1024) fail("'candidates' must be in [1, 1024]");
    if (c.spatial < 0 || c.spatial > int(RESTIR_MAX_NEIGHBOURS) - 1)
        fail("'spatial' must be in [0, " + std::to_string(RESTIR_MAX_NEIGHBOURS - 1) + "]");
    if (!(c.m_cap >= 1.0f && c.m_cap <= 1e30f)) fail("'m_cap' must be in [1, 1e30]");
    if (c.burn_in < 0 || c.burn_in > 65536) fail("'burn_in' must be in [0, 65536]");
    if (!(c.normal_cos >= -1.0f && c.normal_cos <= 1.0f)) fail("'normal_cos' must be in [-1, 1]");
    if (!(c.depth_rel >= 0.0f && std::isfinite(c.depth_rel)))
        fail("'depth_rel' must be a finite number >= 0");
}

std::string restir_unsupported(const RenderScene& scene) {
    const bool null_surfaces =
        std::any_of(scene.materials.begin(), scene.materials.end(),
                    [](const gpu::Material& m) { return m.type == MATERIAL_NULL; });
    if (!scene.media.empty() || null_surfaces)
        return "the scene has participating media or null bsdfs, which light-sample reuse does "
               "not cover yet";
    if (scene.emissive.empty() && scene.delta_lights.empty() && !scene.has_env)
        return "the scene has no light to sample";
    if (scene.max_depth >= 0 && scene.max_depth < 2)
        return "max_depth " + std::to_string(scene.max_depth) +
               " < 2: no path samples a light at its first surface";
    bool samples_lights = false; // a surface NEE applies at: not smooth, not black
    for (const gpu::TriangleInfo& info : scene.infos) {
        const gpu::Material& m = scene.materials[info.material];
        samples_lights |= m.type != MATERIAL_CONDUCTOR && m.type != MATERIAL_DIELECTRIC &&
                          !(m.flags & MATERIAL_FLAG_BLACK);
    }
    if (!samples_lights)
        return "every surface is smooth (conductor or dielectric) or black: no light samples";
    return "";
}

BuildFlags restir_features(BuildFlags features) {
    features.set("RESTIR", 1);
    return features;
}

ReservoirPasses::ReservoirPasses(const View& view, const RestirConfig& config, int spp)
    : m_config(config), m_spp(std::max(1, spp)), m_radius(spatial_radius(view)),
      m_radiance_floor(radiance_floor(view.scene->scene())) {
    const DeviceScene& scene = *view.scene;
    validate_restir_config(config, "restir");
    if (scene.features().get("RESTIR") != 1)
        throw Error("restir: the device scene was not built with RESTIR=1");
    const std::string why = restir_unsupported(scene.scene());
    if (!why.empty()) throw Error("restir: cannot reuse light samples: " + why);
    m_slots = view.pixels() * static_cast<std::size_t>(m_spp);
    if (m_slots >= (std::size_t(1) << 32))
        throw Error("restir: " + std::to_string(m_slots) + " reservoir slots exceed 2^32");
    // the lights' radiance parameters, once: every emissive triangle of an emitter shares its own
    const RenderScene& s = scene.scene();
    if (s.env_param != NO_PARAM) m_light_params.push_back(s.env_param);
    for (const gpu::EmissiveTriangle& e : s.emissive)
        if (e.radiance_param != NO_PARAM) m_light_params.push_back(e.radiance_param);
    std::sort(m_light_params.begin(), m_light_params.end());
    m_light_params.erase(std::unique(m_light_params.begin(), m_light_params.end()),
                         m_light_params.end());
}

PathReservoirs ReservoirPasses::resampled(const Buffer<gpu::Reservoir>& current,
                                          const Buffer<float>& theta_prev,
                                          const Buffer<gpu::Reservoir>& prev,
                                          const GradientBuffers& grad, std::uint32_t seed) const {
    PathResample r;
    r.params_old = &theta_prev;
    r.prev = &prev;
    r.active = &grad.active;
    r.grad = &grad;
    gpu::RestirParams& rs = r.params;
    rs.seed = seed;
    rs.spp = static_cast<unsigned>(m_spp);
    rs.candidates = static_cast<unsigned>(m_config.candidates);
    rs.temporal = m_config.temporal ? 1u : 0u;
    rs.spatial = static_cast<unsigned>(m_config.spatial);
    rs.radius = m_radius;
    rs.visibility = m_config.visibility ? 1u : 0u;
    rs.m_cap = m_config.m_cap;
    rs.normal_cos = m_config.normal_cos;
    rs.depth_rel = m_config.depth_rel;
    rs.radiance_floor = m_radiance_floor;
    rs.direct = static_cast<unsigned>(m_config.direct); // RESTIR_DIRECT_*
    // Every slot needs a reservoir where a light's radiance is differentiated (the primary
    // vertex's NEE term has a derivative whatever its material); else only those on a material
    // with a differentiated parameter (kernels/path/resample.h: restir_serves). The primal's
    // chain serves the same slots: its image matters only through delta, which meets the
    // adjoint's derivatives, and those are largest where the first surface is differentiated;
    // elsewhere NEE's own sample keeps it unbiased at a fraction of the cost (docs/restir.md,
    // "Reuse in the primal").
    r.serve_all = std::any_of(m_light_params.begin(), m_light_params.end(),
                              [&](unsigned param) { return grad.differentiated(param); });
    PathReservoirs out = read(current);
    out.resample = r;
    return out;
}

PathReservoirs ReservoirPasses::read(const Buffer<gpu::Reservoir>& current) const {
    PathReservoirs r;
    r.buffer = &current;
    r.spp = static_cast<unsigned>(m_spp);
    r.trace_visibility = !m_config.visibility;
    r.direct = static_cast<unsigned>(m_config.direct);
    return r;
}

} // namespace tandem
