// Scene description: a loader for a documented subset of the Mitsuba 3 XML format, producing plain
// host-side data (no OpenCL). The parsed XML tree (scene_xml.cpp) is turned into a SceneDesc here.
//
// Supported subset (anything else is an error "FILE:LINE: ..." naming the tag or attribute):
//
// - Root `<scene version="2.x|3.x">`. `<default name="N" value="V"/>` (direct children of the
//   scene) declare variables; `$N` in any attribute value is replaced by its value. A `-D N=V`
//   define overrides a default and may also introduce a variable of its own. An unknown `$N` is
//   an error naming it. Variables must be declared before use.
// - Properties: `<float>`, `<integer>`, `<boolean value="true|false">`, `<string>`,
//   `<rgb value="r, g, b">` (or one value: grey), `<spectrum value="v">` (one value only: grey),
//   `<point>`/`<vector>` (`value="x, y, z"` or `x= y= z=`), `<transform>`. Numbers in a list are
//   separated by commas and/or spaces. A colour property also accepts a `<float>` (grey).
// - `<transform name="...">` holds any sequence of `<translate x= y= z=/>` or `value=`,
//   `<rotate x|y|z= angle="deg"/>` or `value|axis="x, y, z" angle=`, `<scale value="s"/>` or
//   `x= y= z=` or `value="x, y, z"`, `<matrix value="16 (or 9) numbers, row-major"/>`,
//   `<lookat origin= target= up=/>`. Each element applies after the previous one
//   (M = T_new * M), as in Mitsuba. lookat is Mitsuba's look_at: columns (left, new_up, dir,
//   origin); without `up`, up = coordinate_system(dir).first.
// - Objects at scene level may carry `id` and be referenced by `<ref id="..."/>` later in the file
//   (a bsdf from a shape or a twosided bsdf; a texture from a bsdf with `<ref name="..."
//   id=.../>`). Objects may also be nested directly. Ids are unique in the whole file.
// - `<integrator type="path|prb|volpath|prbvolpath">` (one estimator: the volumetric path where the
//   scene has media): integer `max_depth` (-1 = unbounded), `rr_depth`.
// - `<medium type="homogeneous|heterogeneous">` (scene_media.cpp; at scene level with an id, or
//   nested in a shape as name="interior"/"exterior", or in a sensor): `sigma_t` and `albedo` as a
//   float, rgb or `<volume type="constvolume|gridvolume">` (.vol files; grids in heterogeneous
//   media only), float `scale`, `<phase type="isotropic|hg">` (float `g`). `<bsdf type="null"/>`.
// - `<sensor type="perspective">`: float `fov`, string `fov_axis` (x|y|diagonal|smaller|larger),
//   float `near_clip`/`far_clip`, transform `to_world`; nested `<film type="hdrfilm">` (integer
//   `width`/`height`; `<rfilter type="box"/>`, string `pixel_format`/`component_format` accepted
//   and ignored) and `<sampler type="independent">` (integer `sample_count` -> spp). A scene
//   may have several sensors, numbered in file order; an `id` names one. Mitsuba's `<sensor
//   type="batch">` holds perspective sensors and one film whose width is split evenly between
//   them (each renders a width/N x height slice, as Mitsuba's batch sensor does): it stands for
//   those sensors, in order, each with the batch's sampler and a film of its slice's size. A
//   scene without a sensor has Mitsuba's default one.
// - `<shape type="obj|ply">` (string `filename`, relative to the scene file, must exist),
//   `rectangle` ([-1,1]^2 at z=0, normal +z), `cube` ([-1,1]^3), `sphere` (point `center`, float
//   `radius`), `disk` (unit disk at z=0, normal +z); spheres and disks are traced analytically
//   where they can be (build_render_scene). All take transform `to_world`, boolean
//   `flip_normals`, boolean `face_normals` (obj and ply: core/scene/vertex_normals.h), one nested `<bsdf>` or `<ref>`, one nested
//   `<emitter type="area">`. A shape without a bsdf gets bsdf = -1 (Mitsuba's default: diffuse
//   0.5, or a black diffuse on an area emitter).
// - `<bsdf>`: `diffuse` (`reflectance`: colour or texture); `conductor` (`specular_reflectance`,
//   `eta`/`k` rgb or string `material`: Cu Au Ag Al Cr none); `roughconductor` (same plus float
//   `alpha`, string `distribution` = ggx); `dielectric` (`specular_reflectance` (scales reflection), `int_ior`, `ext_ior`: float or a Mitsuba
//   IOR name such as "bk7"); `roughplastic` (`alpha`, `distribution` = ggx,
//   `diffuse_reflectance`, `specular_reflectance`, `int_ior`, `ext_ior`, boolean `nonlinear`);
//   `twosided` wrapping exactly one bsdf (nested or ref): the result is that bsdf with
//   twosided=true and the outer id. Note: without `distribution`, rough bsdfs use GGX here
//   (Mitsuba's default is Beckmann, which is not supported).
// - `<texture>`: `bitmap` (string `filename`, must exist; boolean `raw` -> srgb = !raw; string
//   `filter_type` bilinear|nearest; transform `to_uv`), `checkerboard` (rgb `color0`, `color1`,
//   transform `to_uv`). `to_uv` keeps the 2D part (x, y and translation) of the 4x4 transform.
// - `<emitter>`: `area` (only inside a shape; colour `radiance`), `point` (`intensity`; point
//   `position` or transform `to_world`), `spot` (`intensity`, float `cutoff_angle`, `beam_width`
//   in degrees, `to_world`), `constant` (`radiance`), `envmap` (string `filename`, must exist;
//   float `scale`; `to_world`).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

namespace tandem {

enum class FovAxis { x, y, diagonal, smaller, larger };

/// Pinhole camera. Local frame as Mitsuba: looks along +z, +y up, +x to the left.
struct Camera {
    std::string id;           ///< the sensor's id (empty: none)
    int line = 0;             ///< the line of its <sensor> tag (0: the default sensor)
    glm::mat4 to_world{1.0f}; ///< camera to world
    float fov = 39.3077f;     ///< degrees, along fov_axis
    FovAxis fov_axis = FovAxis::x;
    int width = 768, height = 576;            ///< pixels
    int spp = 4;                              ///< samples per pixel
    float near_clip = 1e-2f, far_clip = 1e4f; ///< world units
    int medium = -1; ///< the medium the camera sits in (index into SceneDesc::media), or -1
};

struct Integrator {
    std::string type = "path"; ///< path, volpath or prbvolpath (the same estimator here)
    int max_depth = -1; ///< -1 = unbounded, as Mitsuba
    int rr_depth = 5;   ///< Russian roulette starts at this depth
};

/// A colour input: constant RGB, or a texture (index into SceneDesc::textures).
struct ColorInput {
    glm::vec3 value{0.5f}; ///< linear RGB, used when texture < 0
    int texture = -1;
};

struct Texture {
    enum class Kind { bitmap, checkerboard } kind = Kind::bitmap;
    std::string filename;                 ///< bitmap: resolved absolute path
    bool srgb = true;                     ///< bitmap: raw = false
    std::string filter_type = "bilinear"; ///< bitmap: bilinear | nearest
    glm::vec3 color0{0.4f}, color1{0.2f}; ///< checkerboard, linear RGB
    glm::mat3 to_uv{1.0f};                ///< uv -> texture space, 2D homogeneous
    std::string id;
    int line = 0; ///< line of the <texture> tag
};

enum class BsdfType { diffuse, conductor, roughconductor, dielectric, roughplastic, null };

struct Bsdf {
    std::string id;
    BsdfType type = BsdfType::diffuse;
    bool twosided = false;
    /// A twosided bsdf wrapping a <ref>: the index of the referenced bsdf, whose parameters it
    /// shares (one set of parameters, named after the referenced bsdf); -1 otherwise.
    int shared_from = -1;
    ColorInput reflectance; ///< diffuse reflectance; roughplastic diffuse_reflectance
    ColorInput specular_reflectance{glm::vec3(1.0f)};
    float alpha = 0.1f;                           ///< GGX roughness (rough bsdfs)
    glm::vec3 eta{0.f}, k{1.f};                   ///< conductor complex IOR, per RGB channel
    float int_ior = 1.5046f, ext_ior = 1.000277f; ///< dielectric, roughplastic
    bool nonlinear = false;                       ///< roughplastic
    int line = 0;
};

enum class EmitterType { area, point, spot, constant, envmap };

struct Emitter {
    std::string id;
    EmitterType type = EmitterType::area;
    glm::vec3 radiance{1.0f};  ///< area, constant: linear RGB radiance
    glm::vec3 intensity{1.0f}; ///< point, spot: linear RGB radiant intensity
    glm::mat4 to_world{1.0f};  ///< point (position), spot, envmap
    float cutoff_angle = 20.f; ///< spot, degrees
    float beam_width = -1.f;   ///< spot, degrees; the loader sets cutoff_angle * 3/4 if not given
    std::string filename;      ///< envmap, resolved absolute path
    float scale = 1.0f;        ///< envmap
    int line = 0;
};

enum class ShapeType { obj, ply, rectangle, cube, sphere, disk };

struct Shape {
    std::string id;
    ShapeType type = ShapeType::obj;
    std::string filename;     ///< obj, ply: resolved absolute path
    glm::mat4 to_world{1.0f}; ///< object to world
    bool flip_normals = false;
    /// obj, ply: shade with the triangles' own normals, not the file's vertex normals or normals
    /// derived from the vertices (Mitsuba's `face_normals`)
    bool face_normals = false;
    glm::vec3 center{0.f}; ///< sphere, object space
    float radius = 1.f;    ///< sphere
    int bsdf = -1;         ///< index into bsdfs; -1 means a default diffuse is needed
    int emitter = -1;      ///< index into emitters (area)
    /// The media inside (behind the normals) and outside the shape, indices into
    /// SceneDesc::media, or -1 (vacuum). A shape with either is a medium transition.
    int interior = -1, exterior = -1;
    int line = 0;
};

/// A volume input of a heterogeneous medium: Mitsuba's `constvolume` or `gridvolume`.
struct VolumeInput {
    bool grid = false;         ///< gridvolume (else constvolume)
    glm::vec3 value{1.0f};     ///< constvolume: its value (grey or rgb)
    std::string filename;      ///< gridvolume: resolved absolute path (.vol)
    glm::mat4 to_world{1.0f};  ///< gridvolume: maps the grid's unit cube into the world
    int line = 0;
};

inline VolumeInput constant_volume(float value) {
    VolumeInput v;
    v.value = glm::vec3(value);
    return v;
}

enum class MediumType { homogeneous, heterogeneous };
enum class PhaseType { isotropic, hg };

/// A participating medium (Mitsuba's `homogeneous` and `heterogeneous`), with its phase function.
struct Medium {
    std::string id;
    MediumType type = MediumType::homogeneous;
    /// homogeneous: constant extinction and albedo; heterogeneous: the volumes that give them
    VolumeInput sigma_t, albedo = constant_volume(0.75f);
    float scale = 1.0f; ///< multiplies sigma_t
    PhaseType phase = PhaseType::isotropic;
    float g = 0.0f; ///< Henyey-Greenstein asymmetry, in (-1, 1)
    int line = 0;
};

struct SceneDesc {
    std::string path; ///< the scene file, as given
    Integrator integrator;
    /// The sensors in file order (at least one: Mitsuba's default when the file has none).
    std::vector<Camera> sensors{Camera{}};
    Camera& camera() { return sensors.front(); } ///< sensor 0
    const Camera& camera() const { return sensors.front(); }
    std::vector<Texture> textures;
    std::vector<Bsdf> bsdfs;
    /// All non-area emitters at scene level, and the area emitters that shapes reference.
    std::vector<Emitter> emitters;
    std::vector<Shape> shapes;
    std::vector<Medium> media; ///< top-level ones with an id, and those nested in shapes/sensors
};

/// Loads a scene file. `defines` are -D name=value overrides of <default> values; each must name
/// a variable of the scene (a <default> or a $name it uses). Throws tandem::Error
/// (runtime/error.h) with a one-line message "FILE:LINE: ..." naming the tag/attribute.
SceneDesc load_scene(const std::string& path,
                     const std::vector<std::pair<std::string, std::string>>& defines = {});

/// The files a scene is made of: its scene file, then every file it references (bitmaps,
/// environment maps, then meshes), each once.
std::vector<std::string> scene_files(const SceneDesc& desc);

/// The index of the sensor `key` names: its index in file order ("0", "1", ...) or its id.
/// Throws Error naming the sensors there are otherwise.
int find_sensor(const std::vector<Camera>& sensors, const std::string& key);

/// Mitsuba's Transform4f::look_at: columns (left, new_up, dir, origin).
glm::mat4 look_at(const glm::vec3& origin, const glm::vec3& target, const glm::vec3& up);

// ---- The XML tree, after variable substitution and value parsing (scene_xml.cpp) ----
namespace xml {

enum class PropKind { float_, integer, boolean, string, rgb, spectrum, point, vector, transform };

/// One property tag such as <float name="fov" value="45"/>; only the field of its kind is set.
struct Property {
    std::string name;
    PropKind kind = PropKind::float_;
    int line = 0;
    float f = 0.f;  ///< float, spectrum
    int i = 0;      ///< integer
    bool b = false; ///< boolean
    std::string s;  ///< string
    glm::vec3 v{0}; ///< rgb, point, vector
    glm::mat4 m{1}; ///< transform
};

/// An object tag (scene, integrator, sensor, film, sampler, rfilter, shape, bsdf, texture,
/// emitter) or a <ref> (tag "ref": id and optional name).
struct Node {
    std::string tag, type, id, name;
    int line = 0;
    std::vector<Property> props;
    std::vector<Node> children;
};

/// Parses the file into its root <scene> node. Throws Error "FILE:LINE: ..." on malformed XML,
/// unknown tags or attributes, malformed values and unknown variables.
Node parse_file(const std::string& path,
                const std::vector<std::pair<std::string, std::string>>& defines);

} // namespace xml
} // namespace tandem
