// The scaled fixed-point accumulation (kernels/shared/fixed_point.h): per-texel gradients of a
// dark 1024x1024 texture near convergence against a float64 host reference, which the unscaled
// units of 2^-40 round away; and the exactness of the scale (scale invariance, and the same bits
// as the unscaled sums where those are exact).
//
// The scene: a diffuse plane filling the view exactly (fov 2 atan(1/3) at distance 3), its albedo
// a bitmap with one texel per pixel (nearest lookup), under a constant sky of radiance 1, with
// direct light only (max_depth 2) and BSDF sampling only. A sample's radiance is then the
// cosine-sampled weight, which is exactly the albedo, times the sky: L = rho_t, with t the texel
// its camera ray hit, and dL/drho_t = 1. Every pixel's sample (1 spp) pushes delta_p times that
// into the one texel it hit, so the exact gradient of texel t is the sum of delta_p over the
// pixels whose adjoint sample hit t. Which texel a sample hits does not depend on the albedo, so
// a render with the adjoint's seed of an "id" texture ((x + 0.5) / 1024, (y + 0.5) / 1024, 0.5)
// names it exactly: the reference needs no assumption about the camera's mapping (a sample within
// rounding of a texel edge may land in the neighbour; the id render says so).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <random>
#include <unistd.h>

#include "core/inverse/gradient_step.h"
#include "core/io/image_io.h"
#include "support.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

/// The plane scene (see above) at res x res with a res x res bitmap, written to a scratch
/// directory, loaded, and the directory removed.
RenderScene plane_scene(int res) {
    const fs::path dir = fs::temp_directory_path() /
                         ("tandem-gradscale-" + std::to_string(getpid()) + "-" + std::to_string(res));
    fs::create_directories(dir);
    write_image((dir / "albedo.exr").string(), res, res,
                std::vector<float>(3 * std::size_t(res) * res, 0.5f));
    const std::string xml = R"(<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="2"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="36.86989764584402"/>
        <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value=")" + std::to_string(res) + R"("/>
            <integer name="height" value=")" + std::to_string(res) + R"("/>
        </film>
    </sensor>
    <bsdf type="diffuse" id="paint">
        <texture type="bitmap" name="reflectance">
            <string name="filename" value="albedo.exr"/>
            <boolean name="raw" value="true"/>
            <string name="filter_type" value="nearest"/>
        </texture>
    </bsdf>
    <shape type="rectangle"><ref id="paint"/></shape>
    <emitter type="constant" id="sky"><rgb name="radiance" value="1, 1, 1"/></emitter>
</scene>
)";
    const fs::path path = dir / "plane.xml";
    std::ofstream(path) << xml;
    RenderScene scene = build_render_scene(load_scene(path.string()));
    fs::remove_all(dir);
    return scene;
}

/// The plane scene on the device, rendered with BSDF sampling only.
struct Plane {
    explicit Plane(Context& ctx, int res)
        : scene(plane_scene(res)),
          device(ctx, KernelLibrary::from_environment(), scene,
                 render_features(scene, ctx.device(), LightStrategy::bsdf_only)),
          texture(scene.params.find("paint.reflectance")) {}
    /// theta with the texture's texels replaced by `texels` (3 per texel).
    std::vector<float> with_texels(const std::vector<float>& texels) const {
        std::vector<float> theta = scene.params.values();
        std::copy(texels.begin(), texels.end(), theta.begin() + texture.offset);
        return theta;
    }
    /// For each pixel, the texel its sample (1 spp, `seed`) hit, or -1 (it saw the sky, or its
    /// BSDF sample failed): from a render of the id texture.
    std::vector<long> texel_hit(Context& ctx, std::uint32_t seed) {
        const std::size_t w = texture.width, h = texture.height;
        std::vector<float> id(3 * w * h);
        for (std::size_t y = 0; y < h; ++y)
            for (std::size_t x = 0; x < w; ++x) {
                id[3 * (y * w + x)] = (float(x) + 0.5f) / float(w);
                id[3 * (y * w + x) + 1] = (float(y) + 0.5f) / float(h);
                id[3 * (y * w + x) + 2] = 0.5f;
            }
        Buffer<float> params(ctx, "id params", with_texels(id));
        Buffer<float> rgb(ctx, "id image", 3 * device.pixels());
        render(device, params, seed, 1, rgb);
        const std::vector<float> img = rgb.download();
        std::vector<long> hit(device.pixels(), -1);
        for (std::size_t p = 0; p < hit.size(); ++p) {
            const float r = img[3 * p], g = img[3 * p + 1], b = img[3 * p + 2];
            if (b != 0.5f) continue; // the sky (1, 1, 1) or a failed sample (0, 0, 0)
            const float fx = r * float(w) - 0.5f, fy = g * float(h) - 0.5f;
            REQUIRE(fx == std::floor(fx)); // exactly an id: L is the albedo, bit for bit
            REQUIRE(fy == std::floor(fy));
            REQUIRE((fx >= 0.0f && fx < float(w) && fy >= 0.0f && fy < float(h)));
            hit[p] = long(fy) * long(w) + long(fx);
        }
        return hit;
    }

    RenderScene scene;
    DeviceScene device;
    const Parameter& texture;
};

/// How far PRB's texel gradients g are from the float64 reference ref (the sum of delta_p over
/// the pixels that hit each texel; mag: the sum of their |delta_p|, n: their count), for
/// contributions scaled by 2^s. The requirement: |g - ref| <= 1e-4 mag, accurate to 1e-4 of the
/// size of what the texel received (the darkest texels' contributions are a few thousand units of
/// 2^-(40 + s) at s = 24: measured worst 3e-5). The rounding bound: 1e-6 mag (each contribution is
/// delta (L / f) (df/drho), a few float roundings of 6e-8) plus half a unit of 2^-(40 + s) per
/// contribution and one unit for the decode; it says the accumulation loses nothing but that.
struct Agreement {
    std::size_t texels = 0;         ///< texel channels with a nonzero reference
    std::size_t zeros = 0;          ///< of those, with a gradient of exactly 0
    std::size_t inaccurate = 0;     ///< of those, off by more than 1e-4 mag
    std::size_t beyond_rounding = 0; ///< of those, off by more than the rounding bound
    std::size_t off_10_percent = 0; ///< of those, off by more than 10% of the reference
    double worst = 0.0;             ///< max |g - ref| / mag (units count where mag is tiny)
    double total_ref = 0.0, total_g = 0.0; ///< sums over all texel channels
};

Agreement compare(const std::vector<float>& g, std::size_t offset, const std::vector<double>& ref,
                  const std::vector<double>& mag, const std::vector<int>& n, int s) {
    Agreement a;
    const double unit = std::ldexp(1.0, -(40 + s));
    for (std::size_t i = 0; i < ref.size(); ++i) {
        const double v = g[offset + i];
        a.total_ref += ref[i];
        a.total_g += v;
        if (ref[i] == 0.0) {
            CHECK(v == 0.0); // no sample reached it (or its delta was 0)
            continue;
        }
        ++a.texels;
        a.zeros += v == 0.0;
        const double err = std::abs(v - ref[i]);
        a.worst = std::max(a.worst, err / mag[i]);
        a.inaccurate += err > 1e-4 * mag[i];
        a.beyond_rounding += err > 1e-6 * mag[i] + (0.5 * n[i] + 1.0) * unit;
        a.off_10_percent += err > 0.1 * std::abs(ref[i]);
    }
    return a;
}

std::ostream& operator<<(std::ostream& o, const Agreement& a) {
    return o << a.inaccurate << " of " << a.texels << " texel channels off the float64 reference by more than 1e-4 of their |delta| (" << a.off_10_percent
             << " by more than 10%), " << a.zeros << " zero, worst error " << a.worst
             << " of |delta|, " << a.beyond_rounding << " beyond the rounding bound; sum over texels "
             << a.total_g << " for " << a.total_ref;
}

} // namespace

TEST_SUITE("gradient scale") {
    TEST_CASE("a dark 1024x1024 texture near convergence: per-texel gradients match a float64 reference, which unscaled units round away") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const int res = 1024;
        Plane plane(*ctx, res);
        const std::size_t texels = plane.texture.size / 3, n = 3 * plane.device.pixels();
        REQUIRE(texels == std::size_t(res) * res);

        // A dark texture (albedo 0.01 to 0.04 per channel) and a reference image within 4e-5
        // relative of its primal render: |delta| = 2 |x - r| / N <= ~1e-12, about 2 units of
        // 2^-40 at most, below half a unit (2^-41) wherever the albedo is darkest.
        std::mt19937 rng(11);
        std::uniform_real_distribution<float> dark(0.01f, 0.04f), rel(-4e-5f, 4e-5f);
        std::vector<float> texture(3 * texels);
        for (float& v : texture) v = dark(rng);
        const std::uint32_t seed_primal = 101, seed_adjoint = 202;
        ParamState state(*ctx, plane.scene.params);
        state.theta().upload(plane.with_texels(texture));
        Buffer<float> primal(*ctx, "primal", n);
        render(plane.device, state.theta(), seed_primal, 1, primal);
        std::vector<float> reference = primal.download();
        for (float& r : reference) r += r * rel(rng);
        GradientStep step(plane.device, KernelLibrary::from_environment(), LOSS_L2, reference);

        // The float64 reference from the delta the loss produced and the texels the adjoint's
        // samples hit.
        plane.device.reset_guards();
        step.evaluate(state, 0, seed_primal, 1, seed_adjoint, 1);
        const std::vector<float> delta = step.delta().download();
        const std::vector<float> scaled = state.gradient().value.download();
        const int s = state.gradient().exponent.download()[0];
        CHECK(plane.device.read_guards() == 0u);
        const std::vector<long> hit = plane.texel_hit(*ctx, seed_adjoint);
        std::vector<double> ref(3 * texels, 0.0), mag(3 * texels, 0.0);
        std::vector<int> count(3 * texels, 0);
        std::size_t below_half_unit = 0, contributions = 0;
        double abs_delta = 0.0;
        for (std::size_t p = 0; p < hit.size(); ++p) {
            for (std::size_t c = 0; c < 3; ++c) abs_delta += std::abs(double(delta[3 * p + c]));
            if (hit[p] < 0) continue;
            for (std::size_t c = 0; c < 3; ++c) {
                const std::size_t i = 3 * std::size_t(hit[p]) + c;
                const double d = delta[3 * p + c];
                ref[i] += d; // delta_p dL/drho_t, dL/drho_t = 1 (the sky's radiance)
                mag[i] += std::abs(d);
                count[i] += 1;
                contributions += d != 0.0;
                below_half_unit += d != 0.0 && std::abs(d) < std::ldexp(1.0, -41);
            }
        }
        // the exponent follows sum |delta| (~1e-6 here): sum 2^s in [2^4, 2^5)
        CHECK(std::ldexp(abs_delta, s - GRAD_TARGET_EXPONENT) >= 1.0 - 1e-4);
        CHECK(std::ldexp(abs_delta, s - GRAD_TARGET_EXPONENT) < 2.0 * (1.0 + 1e-4));
        std::size_t not_one = 0; // texels hit by no sample or by more than one
        for (std::size_t t = 0; t < texels; ++t) not_one += count[3 * t] != 1;
        MESSAGE(below_half_unit << " of " << contributions << " contributions below 2^-41; "
                << not_one << " texels hit by no sample or more than one");
        CHECK(below_half_unit > contributions / 2); // the case the scaling is for

        const Agreement good = compare(scaled, plane.texture.offset, ref, mag, count, s);
        MESSAGE("scaled by 2^" << s << ": " << good);
        CHECK(good.texels > 3 * texels * 9 / 10);
        CHECK(good.inaccurate == 0u);
        CHECK(good.beyond_rounding == 0u);
        CHECK(good.zeros == 0u);

        // The unscaled units (s = 0), as before the scaling: the same evaluation rounds the
        // gradients of the darkest texels to zero and quantizes the rest to multiples of 2^-40.
        state.gradient().forced_exponent = 0;
        step.evaluate(state, 0, seed_primal, 1, seed_adjoint, 1);
        const Agreement bad =
            compare(state.gradient().value.download(), plane.texture.offset, ref, mag, count, 0);
        MESSAGE("unscaled: " << bad);
        CHECK(bad.beyond_rounding == 0u); // within its own (useless) precision
        CHECK(bad.inaccurate > bad.texels * 9 / 10);
        CHECK(bad.zeros > bad.texels / 2);
        CHECK(bad.off_10_percent > bad.texels / 2);
    }

    TEST_CASE("the scale is exact: delta 2^k gives gradients exactly 2^k times as large, and the same bits as unscaled sums that were exact") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        // The plane at 64x64 with a user-given delta (as `tandem grad` with any loss): |delta| in
        // [1, 2) and albedos in [1/16, 1], so every contribution (delta to a texel, delta rho to
        // the sky) is a float of magnitude >= 2^-4, a multiple of 2^-27: exact in units of 2^-40
        // and of 2^-(40 + s) for the s chosen here (-10), so both accumulations are exact.
        const int res = 64;
        Plane plane(*ctx, res);
        std::mt19937 rng(5);
        std::uniform_real_distribution<float> albedo(1.0f / 16.0f, 1.0f), mag(1.0f, 2.0f);
        std::vector<float> texture(plane.texture.size);
        for (float& v : texture) v = albedo(rng);
        const Buffer<float> theta(*ctx, "theta", plane.with_texels(texture));
        std::vector<float> delta(3 * plane.device.pixels());
        for (float& d : delta) d = (rng() & 1u ? 1.0f : -1.0f) * mag(rng);
        GradientBuffers grad(*ctx, plane.scene.params.size());
        // the gradient of delta * factor (2 spp) into `out`
        auto gradient = [&](DeviceScene& device, const Buffer<float>& params, float factor,
                            GradientBuffers& out) {
            std::vector<float> d = delta;
            for (float& v : d) v *= factor;
            Buffer<float> buf(*ctx, "delta", d);
            device.reset_guards();
            backward(device, params, 9, 2, buf, out);
            CHECK(device.read_guards() == 0u);
            return out.value.download();
        };
        const std::vector<float> g = gradient(plane.device, theta, 1.0f, grad);
        const int s = grad.exponent.download()[0];
        CHECK(s == GRAD_TARGET_EXPONENT - 14); // sum |delta| ~ 12288 * 1.5 ~ 2^14.2
        grad.forced_exponent = 0;
        CHECK(test::same_bytes(gradient(plane.device, theta, 1.0f, grad), g));
        grad.forced_exponent.reset();
        for (int k : {-40, -17, 9, 30}) {
            INFO("k = " << k);
            const std::vector<float> gk = gradient(plane.device, theta, std::ldexp(1.0f, k), grad);
            CHECK(grad.exponent.download()[0] == s - k);
            std::vector<float> expected = g;
            for (float& v : expected) v = std::ldexp(v, k);
            CHECK(test::same_bytes(gk, expected));
        }
        // without the scaling, delta 2^-42 rounds every contribution (below 2^-41) to zero
        grad.forced_exponent = 0;
        const std::vector<float> lost = gradient(plane.device, theta, std::ldexp(1.0f, -42), grad);
        CHECK(std::count(lost.begin(), lost.end(), 0.0f) == std::ptrdiff_t(lost.size()));
        grad.forced_exponent.reset();

        // Scale invariance on a scene with MIS, bilinear texels and inexact contributions.
        const RenderScene scene = build_render_scene(load_scene(
            std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-texture.xml", {{"res", "16"}}));
        DeviceScene device(*ctx, lib, scene);
        const Buffer<float> values = parameter_buffer(*ctx, scene.params);
        GradientBuffers other(*ctx, scene.params.size());
        delta.assign(3 * device.pixels(), 0.0f);
        std::uniform_real_distribution<float> any(-1e-3f, 1e-3f);
        for (float& d : delta) d = any(rng);
        const std::vector<float> h = gradient(device, values, 1.0f, other);
        for (int k : {-25, 12}) {
            std::vector<float> expected = h;
            for (float& v : expected) v = std::ldexp(v, k);
            CHECK(test::same_bytes(gradient(device, values, std::ldexp(1.0f, k), other), expected));
        }
        CHECK(test::same_bytes(gradient(device, values, 1.0f, other), h)); // and run to run
    }
}
