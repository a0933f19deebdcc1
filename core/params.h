// The parameter registry: every differentiable scene parameter as a named range of one flat float
// array (Mitsuba's traverse() idea). Gradients and optimizer moments mirror this layout.
#pragma once

#include <string>
#include <vector>

namespace tandem {

struct SceneDesc;
struct RenderScene;

struct Parameter {
    enum class Kind { rgb, texture, scalar };
    std::string name;   ///< "<bsdf id>.reflectance", "<bsdf id>.alpha", "<emitter id>.radiance", ...
    Kind kind = Kind::rgb;
    std::size_t offset = 0, size = 0; ///< range in ParamRegistry::values
    int width = 0, height = 0;        ///< texture: texels (size = width * height * 3)
    float lower = 0.0f, upper = 1.0f; ///< valid range of every element
    /// Whether changing it moves surfaces (and so invalidates paths shared between two states).
    /// No kind does yet: vertex positions are not parameters.
    bool moves_geometry() const { return false; }
};

class ParamRegistry {
public:
    ParamRegistry() = default;
    /// Registers the parameters of `desc`, with current values from `scene` (texels as loaded),
    /// and points the device structs of `scene` at them (Material::*_param, TextureInfo::param,
    /// EmissiveTriangle::radiance_param, RenderScene::env_param): the kernels read every
    /// differentiable value from the flat buffer. A bitmap shared by several bsdfs is one
    /// parameter, named after the first.
    ///   <bsdf id>.reflectance           diffuse / roughplastic diffuse colour: rgb or texture, [0, 1]
    ///   <bsdf id>.specular_reflectance  conductors, dielectric, roughplastic: rgb, [0, 1]
    ///   <bsdf id>.alpha                 rough bsdfs: scalar, [1e-3, 1]
    ///   <emitter id>.radiance           area and constant emitters: rgb, [0, inf)
    /// Objects without an id are named by the shape that holds them ("light.emitter",
    /// "floor.bsdf", as Mitsuba), else by kind and index ("bsdf3", "emitter0").
    ParamRegistry(const SceneDesc& desc, RenderScene& scene);

    const std::vector<Parameter>& parameters() const { return m_params; }
    const std::vector<float>& values() const { return m_values; }
    std::size_t size() const { return m_values.size(); }
    /// Per-element lower and upper bounds (the parameter's range), in the layout of values().
    std::vector<float> lower_bounds() const;
    std::vector<float> upper_bounds() const;
    /// The parameter called `name`; throws Error naming it and the known names otherwise.
    const Parameter& find(const std::string& name) const;

private:
    /// Appends a parameter; returns its offset.
    unsigned add(const std::string& name, Parameter::Kind kind, const float* data, std::size_t size,
                 float lower, float upper, int width = 0, int height = 0);
    std::vector<Parameter> m_params;
    std::vector<float> m_values;
};

} // namespace tandem
