// Parameter registry.
#include "core/params.h"

#include <algorithm>
#include <limits>

#include "core/render_scene.h"
#include "runtime/error.h"

namespace tandem {

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
    for (const Parameter& p : m_params) std::fill_n(out.begin() + p.offset, p.size, p.lower);
    return out;
}

std::vector<float> ParamRegistry::upper_bounds() const {
    std::vector<float> out(m_values.size());
    for (const Parameter& p : m_params) std::fill_n(out.begin() + p.offset, p.size, p.upper);
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

ParamRegistry::ParamRegistry(const SceneDesc& desc, RenderScene& scene) {
    const float inf = std::numeric_limits<float>::infinity();
    // scene.materials[i] is desc.bsdfs[i]; the default diffuse after them is not a parameter.
    for (std::size_t i = 0; i < desc.bsdfs.size(); ++i) {
        const Bsdf& b = desc.bsdfs[i];
        gpu::Material& m = scene.materials[i];
        if (b.shared_from >= 0) { // a twosided <ref>: the referenced bsdf's parameters
            const gpu::Material& original = scene.materials[static_cast<std::size_t>(b.shared_from)];
            m.reflectance_param = original.reflectance_param;
            m.specular_param = original.specular_param;
            m.alpha_param = original.alpha_param;
            continue;
        }
        const std::string id = b.id.empty() ? owner_name(desc, false, i) : b.id;
        if (b.type == BsdfType::diffuse || b.type == BsdfType::roughplastic) {
            if (b.reflectance.texture >= 0) {
                gpu::TextureInfo& t = scene.textures[static_cast<std::size_t>(b.reflectance.texture)];
                if (t.kind == TEXTURE_BITMAP && t.param == NO_PARAM) {
                    std::vector<float> texels;
                    for (std::size_t k = 0; k < std::size_t(t.width) * t.height; ++k) {
                        const gpu::float4& c = scene.texels[t.offset + k];
                        texels.insert(texels.end(), {c.x, c.y, c.z});
                    }
                    t.param = add(id + ".reflectance", Parameter::Kind::texture, texels.data(),
                                  texels.size(), 0.0f, 1.0f, int(t.width), int(t.height));
                }
            } else {
                m.reflectance_param = add(id + ".reflectance", Parameter::Kind::rgb,
                                          &b.reflectance.value.x, 3, 0.0f, 1.0f);
            }
        }
        if (b.type != BsdfType::diffuse)
            m.specular_param = add(id + ".specular_reflectance", Parameter::Kind::rgb,
                                   &b.specular_reflectance.value.x, 3, 0.0f, 1.0f);
        if (b.type == BsdfType::roughconductor || b.type == BsdfType::roughplastic)
            m.alpha_param = add(id + ".alpha", Parameter::Kind::scalar, &b.alpha, 1, 1e-3f, 1.0f);
    }
    std::vector<unsigned> emitter_param(desc.emitters.size(), NO_PARAM);
    for (std::size_t i = 0; i < desc.emitters.size(); ++i) {
        const Emitter& e = desc.emitters[i];
        if (e.type != EmitterType::area && e.type != EmitterType::constant) continue;
        const std::string id = e.id.empty() ? owner_name(desc, true, i) : e.id;
        // the value the kernel uses: a constant environment's radiance times its scale
        const glm::vec3 radiance = e.type == EmitterType::constant ? e.radiance * e.scale : e.radiance;
        emitter_param[i] = add(id + ".radiance", Parameter::Kind::rgb, &radiance.x, 3, 0.0f, inf);
        if (e.type == EmitterType::constant) scene.env_param = emitter_param[i];
    }
    for (std::size_t k = 0; k < scene.emissive.size(); ++k)
        scene.emissive[k].radiance_param = emitter_param[scene.emissive_source[k]];
}

const Parameter& ParamRegistry::find(const std::string& name) const {
    for (const Parameter& p : m_params)
        if (p.name == name) return p;
    std::string known;
    for (const Parameter& p : m_params) known += (known.empty() ? "" : ", ") + p.name;
    throw Error("unknown parameter '" + name + "' (this scene has: " + known + ")");
}

} // namespace tandem
