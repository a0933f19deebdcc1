// The parameter registry: every differentiable scene parameter as a named range of one flat float
// array (Mitsuba's traverse() idea). Built from the scene description alone; the flattening step
// (core/scene/render_scene.h) reads each object's offsets from it. Gradients, optimizer moments
// and the parameter state (core/inverse/param_state.h) mirror this layout.
#pragma once

#include <string>
#include <vector>

#include "core/scene/bitmaps.h"
#include "core/scene/scene.h"
#include "shared/scene_layout.h"

namespace tandem {

struct Parameter {
    enum class Kind { rgb, texture, scalar, volume, vertices };
    std::string name; ///< "<bsdf id>.reflectance", "<bsdf id>.alpha", "<emitter id>.radiance", ...
    Kind kind = Kind::rgb;
    std::size_t offset = 0, size = 0; ///< range in ParamRegistry::values
    int width = 0, height = 0;        ///< texture: texels (size = width * height * 3)
    /// volume: a medium's grid of width x height x depth voxels of `channels` floats, in the
    /// layout of Mitsuba's .vol (channel fastest, then x, y, z; core/io/volume_io.h)
    int depth = 0, channels = 0;
    float lower = 0.0f, upper = 1.0f; ///< valid range of every element
    /// Whether changing it moves surfaces (and so invalidates paths shared between two states):
    /// a mesh's vertex positions.
    bool moves_geometry() const { return kind == Kind::vertices; }
    /// Whether its elements form an array (a texture, a grid or a mesh's vertices) rather than a
    /// value.
    bool is_array() const {
        return kind == Kind::texture || kind == Kind::volume || kind == Kind::vertices;
    }
    /// Whether it is a medium's (participating media: no two-state path or light-sample reuse
    /// covers them yet).
    bool in_medium = false;
};

/// "rgb", "texture", "scalar", "volume" or "vertices".
const char* parameter_kind_name(Parameter::Kind kind);

/// Where the differentiable values of one bsdf live in the flat array (NO_PARAM: not a
/// parameter). A textured reflectance is the texture's parameter (ParamRegistry::texture).
struct BsdfParams {
    unsigned reflectance = NO_PARAM, specular = NO_PARAM, alpha = NO_PARAM;
};

/// Where the differentiable values of one medium live (NO_PARAM: not a parameter): sigma_t and
/// albedo are rgb, or a grid's voxels; scale and g are scalars.
struct MediumParams {
    unsigned sigma_t = NO_PARAM, albedo = NO_PARAM, scale = NO_PARAM, g = NO_PARAM;
};

struct VolumeGrid;

class ParamRegistry {
public:
    ParamRegistry() = default;
    /// Registers the parameters of `desc`, with start values from the description and, for
    /// bitmaps, from `bitmaps` (load_bitmaps(desc)). A bitmap shared by several bsdfs is one
    /// parameter, named after the first; a twosided <ref> shares the referenced bsdf's.
    /// - `<bsdf id>.reflectance`: diffuse / roughplastic diffuse colour, rgb or texture, [0, 1];
    /// - `<bsdf id>.specular_reflectance`: conductors, dielectric, roughplastic, rgb, [0, 1];
    /// - `<bsdf id>.alpha`: rough bsdfs, scalar, [1e-3, 1];
    /// - `<emitter id>.radiance`: area and constant emitters, rgb, [0, inf).
    /// Indices of refraction (eta, k, int_ior / ext_ior) are not parameters: the two-state path
    /// weighs a delta lobe sampled under the new state with the old state's weight, which is exact
    /// only while the lobe's choice probability is the same in both (continuation_weight_old).
    /// Objects without an id are named by the shape that holds them ("light.emitter",
    /// "floor.bsdf", as Mitsuba), else by kind and index ("bsdf3", "emitter0").
    ParamRegistry(const SceneDesc& desc, const std::vector<Bitmap>& bitmaps);

    const std::vector<Parameter>& parameters() const { return m_params; }
    /// The start values, in layout order.
    const std::vector<float>& values() const { return m_values; }
    std::size_t size() const { return m_values.size(); }
    /// Per-element lower and upper bounds (the parameter's range), in the layout of values().
    std::vector<float> lower_bounds() const;
    std::vector<float> upper_bounds() const;
    /// The parameter called `name`; throws Error naming it and the known names otherwise.
    const Parameter& find(const std::string& name) const;

    /// Offsets of SceneDesc::bsdfs[i] (shared with the referenced bsdf for a twosided <ref>).
    BsdfParams bsdf(std::size_t i) const { return m_bsdf.at(i); }
    /// Offset of the texels of SceneDesc::textures[t], or NO_PARAM when it is not a parameter.
    unsigned texture(std::size_t t) const { return m_texture.at(t); }
    /// Offset of the radiance of SceneDesc::emitters[e] (area and constant), else NO_PARAM.
    unsigned emitter(std::size_t e) const { return m_emitter.at(e); }

    /// Registers the parameters of medium desc.media[i], after those of the constructor (the
    /// flattening step calls it once per medium, in order, with the grids it has read and checked:
    /// core/scene/media.cpp). `sigma_t` and `albedo` are the medium's grids, or null for a
    /// constant. Named after the medium's id, else "<shape id>.interior_medium" /
    /// ".exterior_medium" (Mitsuba's names), else "medium<i>":
    /// - `NAME.sigma_t`: extinction before scale, rgb, or the grid's voxels, [0, inf);
    /// - `NAME.albedo`: single-scattering albedo, rgb, or the grid's voxels, [0, 1];
    /// - `NAME.scale`: scalar, [0, inf);
    /// - `NAME.g`: the Henyey-Greenstein asymmetry (hg phases only), [-0.999, 0.999].
    MediumParams add_medium(const SceneDesc& desc, std::size_t i, const VolumeGrid* sigma_t,
                            const VolumeGrid* albedo);

    /// Registers `NAME.vertex_positions` of a triangle mesh shape (the flattening step calls it
    /// once per mesh shape, in order): its `count` world-space vertices, x y z each (kind
    /// vertices, width = count), unbounded. Returns the offset.
    unsigned add_vertices(const std::string& name, const float* xyz, std::size_t count);

private:
    /// Appends a parameter; returns its offset.
    unsigned add(const std::string& name, Parameter::Kind kind, const float* data, std::size_t size,
                 float lower, float upper, int width = 0, int height = 0);
    /// add() for a medium's grid or value (in_medium set).
    unsigned add_medium_value(const std::string& name, const VolumeGrid* grid, const float* value,
                              Parameter::Kind kind, float lower, float upper);
    std::vector<Parameter> m_params;
    std::vector<float> m_values;
    std::vector<BsdfParams> m_bsdf;
    std::vector<unsigned> m_texture, m_emitter;
};

} // namespace tandem
