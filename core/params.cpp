// Parameter registry.
#include "core/params.h"

#include <limits>

#include "runtime/error.h"

namespace tandem {

void ParamRegistry::add(const std::string& name, Parameter::Kind kind, const float* data,
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

ParamRegistry::ParamRegistry(const SceneDesc& desc, const RenderScene& scene) {
    const float inf = std::numeric_limits<float>::infinity();
    for (std::size_t i = 0; i < desc.bsdfs.size(); ++i) {
        const Bsdf& b = desc.bsdfs[i];
        const std::string id = b.id.empty() ? owner_name(desc, false, i) : b.id;
        if (b.type == BsdfType::diffuse || b.type == BsdfType::roughplastic) {
            if (b.reflectance.texture >= 0) {
                const gpu::TextureInfo& t = scene.textures[static_cast<std::size_t>(b.reflectance.texture)];
                if (t.kind == TEXTURE_BITMAP) {
                    std::vector<float> texels;
                    for (std::size_t k = 0; k < std::size_t(t.width) * t.height; ++k) {
                        const gpu::float4& c = scene.texels[t.offset + k];
                        texels.insert(texels.end(), {c.x, c.y, c.z});
                    }
                    add(id + ".reflectance", Parameter::Kind::texture, texels.data(), texels.size(),
                        0.0f, 1.0f, int(t.width), int(t.height));
                }
            } else {
                add(id + ".reflectance", Parameter::Kind::rgb, &b.reflectance.value.x, 3, 0.0f, 1.0f);
            }
        }
        if (b.type != BsdfType::diffuse)
            add(id + ".specular_reflectance", Parameter::Kind::rgb, &b.specular_reflectance.value.x,
                3, 0.0f, 1.0f);
        if (b.type == BsdfType::roughconductor || b.type == BsdfType::roughplastic)
            add(id + ".alpha", Parameter::Kind::scalar, &b.alpha, 1, 1e-3f, 1.0f);
    }
    for (std::size_t i = 0; i < desc.emitters.size(); ++i) {
        const Emitter& e = desc.emitters[i];
        if (e.type != EmitterType::area && e.type != EmitterType::constant) continue;
        const std::string id = e.id.empty() ? owner_name(desc, true, i) : e.id;
        add(id + ".radiance", Parameter::Kind::rgb, &e.radiance.x, 3, 0.0f, inf);
    }
}

const Parameter& ParamRegistry::find(const std::string& name) const {
    for (const Parameter& p : m_params)
        if (p.name == name) return p;
    std::string known;
    for (const Parameter& p : m_params) known += (known.empty() ? "" : ", ") + p.name;
    throw Error("unknown parameter '" + name + "' (this scene has: " + known + ")");
}

} // namespace tandem
