// Parameter registry.
#include "core/scene/params.h"

#include <algorithm>
#include <limits>

#include "core/io/volume_io.h"
#include "runtime/error.h"

namespace tandem {

const char* parameter_kind_name(Parameter::Kind kind) {
    switch (kind) {
    case Parameter::Kind::rgb: return "rgb";
    case Parameter::Kind::texture: return "texture";
    case Parameter::Kind::scalar: return "scalar";
    case Parameter::Kind::volume: return "volume";
    case Parameter::Kind::vertices: return "vertices";
    }
    return "?";
}

unsigned ParamRegistry::add(const std::string& name, Parameter::Kind kind, const float* data,
                            std::size_t size, float lower, float upper, int width, int height) {
    Parameter p;
    p.name = name;
    p.kind = kind;
    p.offset = m_values.size();
    p.size = size;
    p.width = width;
    p.height = height;
    p.lower = lower;
    p.upper = upper;
    m_values.insert(m_values.end(), data, data + size);
    m_params.push_back(p);
    return static_cast<unsigned>(p.offset);
}

std::vector<float> ParamRegistry::lower_bounds() const {
    std::vector<float> out(m_values.size());
    for (const Parameter& p : m_params)
        std::fill_n(out.begin() + p.offset, p.size, p.lower);
    return out;
}

std::vector<float> ParamRegistry::upper_bounds() const {
    std::vector<float> out(m_values.size());
    for (const Parameter& p : m_params)
        std::fill_n(out.begin() + p.offset, p.size, p.upper);
    return out;
}

namespace {

/// The name of an object without an id: "<shape id>.bsdf" / "<shape id>.emitter" when a shape with
/// an id owns it (Mitsuba's naming), else "<kind><index>".
std::string owner_name(const SceneDesc& desc, bool emitter, std::size_t index) {
    for (const Shape& s : desc.shapes)
        if (!s.id.empty() && (emitter ? s.emitter : s.bsdf) == static_cast<int>(index))
            return s.id + (emitter ? ".emitter" : ".bsdf");
    return (emitter ? "emitter" : "bsdf") + std::to_string(index);
}

} // namespace

ParamRegistry::ParamRegistry(const SceneDesc& desc, const std::vector<Bitmap>& bitmaps)
    : m_bsdf(desc.bsdfs.size()), m_texture(desc.textures.size(), NO_PARAM),
      m_emitter(desc.emitters.size(), NO_PARAM) {
    const float inf = std::numeric_limits<float>::infinity();
    for (std::size_t i = 0; i < desc.bsdfs.size(); ++i) {
        const Bsdf& b = desc.bsdfs[i];
        BsdfParams& m = m_bsdf[i];
        if (b.shared_from >= 0) { // a twosided <ref>: the referenced bsdf's parameters
            m = m_bsdf[static_cast<std::size_t>(b.shared_from)];
            continue;
        }
        const std::string id = b.id.empty() ? owner_name(desc, false, i) : b.id;
        if (b.type == BsdfType::diffuse || b.type == BsdfType::roughplastic) {
            if (b.reflectance.texture >= 0) {
                const auto t = static_cast<std::size_t>(b.reflectance.texture);
                const Bitmap& bitmap = bitmaps.at(t);
                if (desc.textures[t].kind == Texture::Kind::bitmap && m_texture[t] == NO_PARAM)
                    m_texture[t] =
                        add(id + ".reflectance", Parameter::Kind::texture, bitmap.rgb.data(),
                            bitmap.rgb.size(), 0.0f, 1.0f, bitmap.width, bitmap.height);
            } else {
                m.reflectance = add(id + ".reflectance", Parameter::Kind::rgb,
                                    &b.reflectance.value.x, 3, 0.0f, 1.0f);
            }
        }
        if (b.type != BsdfType::diffuse && b.type != BsdfType::null)
            m.specular = add(id + ".specular_reflectance", Parameter::Kind::rgb,
                             &b.specular_reflectance.value.x, 3, 0.0f, 1.0f);
        if (b.type == BsdfType::roughconductor || b.type == BsdfType::roughplastic)
            m.alpha = add(id + ".alpha", Parameter::Kind::scalar, &b.alpha, 1, 1e-3f, 1.0f);
    }
    for (std::size_t i = 0; i < desc.emitters.size(); ++i) {
        const Emitter& e = desc.emitters[i];
        if (e.type != EmitterType::area && e.type != EmitterType::constant) continue;
        const std::string id = e.id.empty() ? owner_name(desc, true, i) : e.id;
        // the value the kernel uses: a constant environment's radiance times its scale
        const glm::vec3 radiance =
            e.type == EmitterType::constant ? e.radiance * e.scale : e.radiance;
        m_emitter[i] = add(id + ".radiance", Parameter::Kind::rgb, &radiance.x, 3, 0.0f, inf);
    }
}

unsigned ParamRegistry::add_medium_value(const std::string& name, const VolumeGrid* grid,
                                         const float* value, Parameter::Kind kind, float lower,
                                         float upper) {
    unsigned offset;
    if (grid) {
        offset = add(name, Parameter::Kind::volume, grid->values.data(), grid->values.size(), lower,
                     upper, grid->width, grid->height);
        m_params.back().depth = grid->depth;
        m_params.back().channels = grid->channels;
    } else {
        offset = add(name, kind, value, kind == Parameter::Kind::rgb ? 3 : 1, lower, upper);
    }
    m_params.back().in_medium = true;
    return offset;
}

MediumParams ParamRegistry::add_medium(const SceneDesc& desc, std::size_t i,
                                       const VolumeGrid* sigma_t, const VolumeGrid* albedo) {
    const Medium& m = desc.media.at(i);
    std::string name = m.id;
    for (const Shape& s : desc.shapes) {
        if (!name.empty()) break;
        if (s.id.empty()) continue;
        if (s.interior == static_cast<int>(i)) name = s.id + ".interior_medium";
        else if (s.exterior == static_cast<int>(i)) name = s.id + ".exterior_medium";
    }
    if (name.empty()) name = "medium" + std::to_string(i);
    const float inf = std::numeric_limits<float>::infinity();
    MediumParams p;
    p.sigma_t = add_medium_value(name + ".sigma_t", sigma_t, &m.sigma_t.value.x,
                                 Parameter::Kind::rgb, 0.0f, inf);
    p.albedo = add_medium_value(name + ".albedo", albedo, &m.albedo.value.x, Parameter::Kind::rgb,
                                0.0f, 1.0f);
    p.scale = add_medium_value(name + ".scale", nullptr, &m.scale, Parameter::Kind::scalar, 0.0f,
                               inf);
    if (m.phase == PhaseType::hg)
        p.g = add_medium_value(name + ".g", nullptr, &m.g, Parameter::Kind::scalar, -0.999f,
                               0.999f);
    return p;
}

unsigned ParamRegistry::add_vertices(const std::string& name, const float* xyz,
                                     std::size_t count) {
    const float inf = std::numeric_limits<float>::infinity();
    return add(name + ".vertex_positions", Parameter::Kind::vertices, xyz, 3 * count, -inf, inf,
               static_cast<int>(count), 1);
}

const Parameter& ParamRegistry::find(const std::string& name) const {
    for (const Parameter& p : m_params)
        if (p.name == name) return p;
    std::string known;
    for (const Parameter& p : m_params)
        known += (known.empty() ? "" : ", ") + p.name;
    throw Error("unknown parameter '" + name + "' (this scene has: " + known + ")");
}

} // namespace tandem
