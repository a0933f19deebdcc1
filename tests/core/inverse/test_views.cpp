// Several views (issue "many views"): scenes with several sensors and the batch sensor, the view
// schedule, per-sensor passes that render what a one-sensor scene of the same camera renders bit
// for bit, batches whose fixed-point gradient words are the exact sum of their views', a
// multi-view loss against finite differences, and photograph masks.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include "core/inverse/gradient_step.h"
#include "core/inverse/streams.h"
#include "core/inverse/view_schedule.h"
#include "inverse_fixtures.h"
#include "shared/fixed_point.h"
#include "support.h"

using namespace tandem;

namespace {

namespace fs = std::filesystem;

std::string write_scene(const std::string& name, const std::string& body) {
    const fs::path dir = fs::temp_directory_path() / "tandem-test-views";
    fs::create_directories(dir);
    const fs::path path = dir / name;
    std::ofstream(path) << "<scene version=\"3.0.0\">\n" << body << "\n</scene>\n";
    return path.string();
}

std::string sensor_xml(const char* id, const char* origin, int w, int h, int spp = 4) {
    return std::string("<sensor type=\"perspective\"") + (id[0] ? " id=\"" + std::string(id) + "\"" : "") +
           "><float name=\"fov\" value=\"40\"/><transform name=\"to_world\"><lookat origin=\"" +
           origin + "\" target=\"0, 0, 0\" up=\"0, 1, 0\"/></transform><film type=\"hdrfilm\">" +
           "<integer name=\"width\" value=\"" + std::to_string(w) + "\"/><integer name=\"height\" " +
           "value=\"" + std::to_string(h) + "\"/></film><sampler type=\"independent\"><integer " +
           "name=\"sample_count\" value=\"" + std::to_string(spp) + "\"/></sampler></sensor>\n";
}

/// The error `f` throws (fails the test when it throws none).
template <class F> std::string error_of(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    FAIL("no error");
    return "";
}

/// three-spheres at `res` (one sensor), and the same scene with a second sensor before it,
/// elsewhere and of another size: its sensor 1 is the first scene's sensor 0.
std::pair<SceneDesc, SceneDesc> one_and_two_sensors(int res) {
    const std::string file = std::string(TANDEM_SOURCE_DIR) + "/scenes/three-spheres.xml";
    SceneDesc one = load_scene(file, {{"res", std::to_string(res)}, {"max_depth", "3"}});
    SceneDesc two = one;
    Camera other = one.camera();
    other.to_world = look_at({3, 2, 4}, {0, 0, 0}, {0, 1, 0});
    other.width = res + 5;
    other.height = res - 3;
    two.sensors = {other, one.camera()};
    return {one, two};
}

} // namespace

TEST_SUITE("views") {
    TEST_CASE("a scene's sensors: numbered in file order, named by id, and Mitsuba's batch sensor") {
        const std::string path = write_scene(
            "three.xml", sensor_xml("front", "0, 0, 4", 8, 6) + sensor_xml("", "4, 0, 0", 5, 5, 2) +
                             "<sensor type=\"batch\" id=\"rig\">" + "<sensor type=\"perspective\" " +
                             "id=\"left\"><transform name=\"to_world\"><lookat origin=\"0, 4, 0\" " +
                             "target=\"0, 0, 0\" up=\"0, 0, 1\"/></transform></sensor>" +
                             "<sensor type=\"perspective\"/><film type=\"hdrfilm\"><integer " +
                             "name=\"width\" value=\"12\"/><integer name=\"height\" value=\"4\"/>" +
                             "</film><sampler type=\"independent\"><integer name=\"sample_count\" " +
                             "value=\"3\"/></sampler></sensor>");
        const SceneDesc d = load_scene(path);
        REQUIRE(d.sensors.size() == 4);
        CHECK(d.sensors[0].id == "front");
        CHECK((d.sensors[0].width == 8 && d.sensors[0].height == 6 && d.sensors[0].spp == 4));
        CHECK((d.sensors[1].id.empty() && d.sensors[1].width == 5 && d.sensors[1].spp == 2));
        // the batch's film is split evenly, left to right; its sampler is shared
        CHECK((d.sensors[2].id == "left" && d.sensors[3].id == "rig_1"));
        for (int k : {2, 3})
            CHECK((d.sensors[k].width == 6 && d.sensors[k].height == 4 && d.sensors[k].spp == 3));
        CHECK(glm::vec3(d.sensors[1].to_world[3]) == glm::vec3(4, 0, 0));
        CHECK(find_sensor(d.sensors, "front") == 0);
        CHECK(find_sensor(d.sensors, "1") == 1);
        CHECK(find_sensor(d.sensors, "left") == 2);
        const std::string unknown = error_of([&] { find_sensor(d.sensors, "back"); });
        CHECK(unknown == "no sensor 'back': the scene has 4 sensors: 0 ('front'), 1, 2 ('left'), "
                         "3 ('rig_1')");
        CHECK(error_of([&] { find_sensor(d.sensors, "4"); }).find("no sensor '4'") == 0);
        // a scene without a sensor has Mitsuba's default one
        CHECK(load_scene(write_scene("none.xml", "")).sensors.size() == 1);
    }

    TEST_CASE("bad sensors are one-line errors naming the file and line") {
        const std::string uneven = write_scene(
            "uneven.xml", "<sensor type=\"batch\"><sensor type=\"perspective\"/><sensor "
                          "type=\"perspective\"/><sensor type=\"perspective\"/><film "
                          "type=\"hdrfilm\"><integer name=\"width\" value=\"8\"/></film></sensor>");
        CHECK(error_of([&] { load_scene(uneven); })
                  .find("uneven.xml:2: <sensor type=\"batch\">: the film's width 8 does not split "
                        "evenly between its 3 sensors") != std::string::npos);
        const std::string own_film = write_scene(
            "own.xml", "<sensor type=\"batch\"><sensor type=\"perspective\">\n<film "
                       "type=\"hdrfilm\"/></sensor></sensor>");
        CHECK(error_of([&] { load_scene(own_film); })
                  .find("own.xml:3: <sensor type=\"batch\">: a nested sensor has no <film>") !=
              std::string::npos);
        const std::string twice = write_scene(
            "twice.xml", sensor_xml("a", "0, 0, 4", 4, 4) + sensor_xml("a", "0, 0, 3", 4, 4));
        CHECK(error_of([&] { load_scene(twice); }).find("duplicate id 'a'") != std::string::npos);
    }

    TEST_CASE("the view schedule: shuffled epochs, each a permutation, no view twice in a batch") {
        for (unsigned views : {1u, 3u, 8u})
            for (unsigned batch = 1; batch <= views; ++batch) {
                ViewSchedule s(views, batch, 7);
                ViewSchedule again(views, batch, 7);
                std::vector<unsigned> order, counts(views, 0);
                const unsigned iterations = 5 * views;
                for (unsigned n = 0; n < iterations; ++n) {
                    for (unsigned v = 0; v < views; ++v) // the count before iteration n, directly
                        CHECK(again.visits(v, n) == counts[v]);
                    const auto b = s.at(n);
                    REQUIRE(b.size() == batch);
                    std::set<unsigned> distinct;
                    for (const ViewSchedule::Visit& v : b) {
                        distinct.insert(v.view);
                        CHECK(v.visit == counts[v.view]); // visited that often before
                        ++counts[v.view];
                        order.push_back(v.view);
                    }
                    CHECK(distinct.size() == batch);
                }
                // every epoch of the sequence is a permutation of the views
                for (std::size_t e = 0; (e + 1) * views <= order.size(); ++e) {
                    std::vector<unsigned> epoch(order.begin() + long(e * views),
                                                order.begin() + long((e + 1) * views));
                    std::sort(epoch.begin(), epoch.end());
                    for (unsigned v = 0; v < views; ++v) CHECK(epoch[v] == v);
                }
                // any iteration, in any order, on another instance: the same batches
                for (unsigned n = iterations; n-- > 0;) {
                    const auto a = again.at(n), b = s.at(n);
                    for (unsigned k = 0; k < batch; ++k) CHECK(a[k].view == b[k].view);
                }
                if (batch == views) // every view every iteration, in order
                    for (unsigned k = 0; k < views; ++k) CHECK(s.at(3)[k].view == k);
            }
        // shuffled: 8 views one at a time do not come in index order, and the seed matters
        ViewSchedule a(8, 1, 0), b(8, 1, 1);
        bool in_order = true, same = true;
        for (unsigned n = 0; n < 8; ++n) {
            in_order = in_order && a.at(n)[0].view == n;
            same = same && a.at(n)[0].view == b.at(n)[0].view;
        }
        CHECK_FALSE(in_order);
        CHECK_FALSE(same);
        CHECK(error_of([] { ViewSchedule(3, 4, 0); }).find("batch: 4 views") == 0);
        // each view draws its own streams; sensor 0 the run's own (one sensor: as before)
        CHECK(view_seed(7, 0) == 7u);
        std::set<std::uint32_t> seeds;
        for (unsigned k = 0; k < 8; ++k) seeds.insert(view_seed(7, k));
        CHECK(seeds.size() == 8);
    }

    TEST_CASE("a view revisited after other steps compares with the parameters it was last rendered with") {
        // Two views, one per iteration: view 0 at theta_a, view 1 at theta_b, view 0 again at
        // theta_c. The old state of view 0's second visit is theta_a, not theta_prev = theta_b.
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = build_render_scene(one_and_two_sensors(12).second);
        DeviceScene device(*ctx, KernelLibrary::from_environment(), scene);
        ParamState state(*ctx, scene.params);
        std::vector<ViewTarget> targets;
        for (unsigned k = 0; k < 2; ++k)
            targets.push_back({k, std::vector<float>(3 * device.pixels(k), 0.3f), {}});
        GradientStep step(device, KernelLibrary::from_environment(), LOSS_L2, targets, CvMode::ps,
                          CvVariance::consistent, 1);
        step.attach(state);
        const Parameter& p = scene.params.find("matte.reflectance");
        std::vector<float> theta = scene.params.values();
        auto set = [&](float v) { // an optimizer's step: theta_prev <- theta, then theta moves
            state.remember_theta();
            std::fill_n(theta.begin() + long(p.offset), 3, v);
            state.theta().upload(theta);
        };
        auto visit = [&](unsigned view, unsigned count) {
            ViewPass pass;
            pass.view = view;
            pass.visit = count;
            pass.seed_primal = 40 + view + count;
            step.evaluate(state, {pass}, 2, 1);
            return pass.seed_primal;
        };
        set(0.2f);
        visit(0, 0);
        const std::vector<float> theta_a = theta;
        set(0.5f);
        visit(1, 0);
        set(0.8f);
        const std::uint32_t seed = visit(0, 1);
        const std::vector<float> h = step.image_old().download();
        Buffer<float> now(*ctx, "now", theta), then(*ctx, "then", theta_a);
        Buffer<float> f(*ctx, "f", h.size()), want(*ctx, "h", h.size());
        render_two_state(View(device, 0), now, then, seed, 2, f, want);
        CHECK(test::same_bytes(h, want.download()));
        CHECK(test::same_bytes(step.image().download(), f.download()));
    }

    TEST_CASE("a sensor renders what a one-sensor scene of its camera renders, bit for bit") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const auto [one_desc, two_desc] = one_and_two_sensors(16);
        const RenderScene one = build_render_scene(one_desc), two = build_render_scene(two_desc);
        for (int wavefront : {0, 1}) {
            CAPTURE(wavefront);
            BuildFlags f1 = render_features(one, *ctx), f2 = render_features(two, *ctx);
            f1.set("WAVEFRONT", wavefront);
            f2.set("WAVEFRONT", wavefront);
            DeviceScene a(*ctx, KernelLibrary::from_environment(), one, f1);
            DeviceScene b(*ctx, KernelLibrary::from_environment(), two, f2);
            const Buffer<float> params = parameter_buffer(*ctx, one.params);
            RenderOptions opt;
            opt.spp = 3;
            opt.seed = 11;
            const RenderResult ra = render_image(a, params, opt);
            const RenderResult rb = render_image(View(b, 1), params, opt);
            const RenderResult r0 = render_image(View(b, 0), params, opt);
            CHECK(test::same_bytes(ra.rgb, rb.rgb));
            CHECK((r0.width == 21 && r0.height == 13)); // the other sensor's own film
            // the two-state render and the gradient likewise
            Buffer<float> fa(*ctx, "f", ra.rgb.size()), ha(*ctx, "h", ra.rgb.size());
            Buffer<float> fb(*ctx, "f", ra.rgb.size()), hb(*ctx, "h", ra.rgb.size());
            render_two_state(a, params, params, 5, 2, fa, ha);
            render_two_state(View(b, 1), params, params, 5, 2, fb, hb);
            CHECK(test::same_bytes(fa.download(), fb.download()));
            CHECK(test::same_bytes(ha.download(), hb.download()));
            Buffer<float> delta(*ctx, "delta", std::vector<float>(ra.rgb.size(), 0.01f));
            GradientBuffers ga(*ctx, one.params.size()), gb(*ctx, one.params.size());
            backward(a, params, 9, 2, delta, ga);
            backward(View(b, 1), params, 9, 2, delta, gb);
            CHECK(test::same_bytes(ga.value.download(), gb.value.download()));
            CHECK(error_of([&] { View(b, 2); }) == "no sensor 2: the scene has 2");
        }
    }

    TEST_CASE("a batch's fixed-point gradient words are the exact sum of its views' words") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = build_render_scene(one_and_two_sensors(12).second);
        DeviceScene device(*ctx, KernelLibrary::from_environment(), scene);
        const Buffer<float> params = parameter_buffer(*ctx, scene.params);
        std::vector<std::unique_ptr<Buffer<float>>> deltas;
        for (unsigned k = 0; k < 2; ++k) {
            std::vector<float> d(3 * device.pixels(k));
            // view 1's eight times larger: the batch's scale is not view 0's
            for (std::size_t i = 0; i < d.size(); ++i)
                d[i] = (k == 0 ? 0.001f : 0.008f) * (float((i * 37 + k) % 11) - 4.0f);
            deltas.push_back(std::make_unique<Buffer<float>>(*ctx, "delta", d));
        }
        // the words of view 0 alone, view 1 alone, and of both into one accumulator
        auto words = [&](std::vector<unsigned> views) {
            GradientBuffers g(*ctx, scene.params.size());
            g.forced_exponent = 6;
            choose_gradient_scale(device, {deltas[0].get()}, g);
            for (unsigned k : views) accumulate_gradients(View(device, k), params, 21 + k, 2, *deltas[k], g);
            return g.fixed.download();
        };
        const std::vector<unsigned> w0 = words({0}), w1 = words({1}), both = words({0, 1});
        const std::vector<unsigned> reversed = words({1, 0});
        CHECK(test::same_bytes(both, reversed));
        std::size_t nonzero = 0;
        for (std::size_t e = 0; e < scene.params.size(); ++e) {
            // per element (shared/fixed_point.h): a 64-bit sum in two words (lo, hi), then the net
            // count of wraps, zero here
            auto sum64 = [&](const std::vector<unsigned>& w) {
                return std::uint64_t(w[GRAD_WORDS * e]) | std::uint64_t(w[GRAD_WORDS * e + 1]) << 32;
            };
            CHECK(sum64(both) == sum64(w0) + sum64(w1)); // mod 2^64, as the words add
            CHECK((w0[GRAD_WORDS * e + 2] == 0 && w1[GRAD_WORDS * e + 2] == 0 &&
                   both[GRAD_WORDS * e + 2] == 0));
            nonzero += sum64(w0) != 0 && sum64(w1) != 0;
        }
        CHECK(nonzero >= 10); // elements both views reach: the sums are not trivial
        // the scale of a batch is chosen from all its deltas, in order: one delta, as backward()
        GradientBuffers one(*ctx, scene.params.size()), two(*ctx, scene.params.size());
        choose_gradient_scale(device, {deltas[0].get()}, one);
        choose_gradient_scale(device, {deltas[0].get(), deltas[1].get()}, two);
        const int s1 = one.exponent.download()[0], s2 = two.exponent.download()[0];
        // the device's order: chunks of 4096 elements in index order, then the chunk sums in order
        auto sum_abs = [](const std::vector<std::vector<float>>& ds) {
            std::vector<float> chunks;
            for (const std::vector<float>& d : ds)
                for (std::size_t c = 0; c < d.size(); c += 4096) {
                    float s = 0.0f;
                    for (std::size_t i = c; i < std::min(d.size(), c + 4096); ++i) s += std::abs(d[i]);
                    chunks.push_back(s);
                }
            float total = 0.0f;
            for (float c : chunks) total += c;
            return total;
        };
        const std::vector<float> d0 = deltas[0]->download(), d1 = deltas[1]->download();
        CHECK(s1 == gpu::grad_exponent_for(sum_abs({d0})));
        CHECK(s2 == gpu::grad_exponent_for(sum_abs({d0, d1})));
        CHECK(s2 < s1 - 1); // view 1 dominates the batch's sum
        // and in the other order, the same sum of both (not the last view's alone: view 0's)
        GradientBuffers reversed_scale(*ctx, scene.params.size());
        choose_gradient_scale(device, {deltas[1].get(), deltas[0].get()}, reversed_scale);
        CHECK(reversed_scale.exponent.download()[0] == gpu::grad_exponent_for(sum_abs({d1, d0})));
        CHECK(reversed_scale.exponent.download()[0] == s2);
    }

    TEST_CASE("the gradient of a loss summed over views matches finite differences") {
        // As test_gradient.cpp's check (its header says why): PRB of the mean loss of each view,
        // summed by one batch, against a Richardson central difference of the sum of the views'
        // mean images rendered with each view's adjoint seed and no roulette.
        TANDEM_REQUIRE_DEVICE(ctx);
        const auto descs = one_and_two_sensors(16);
        RenderScene scene = build_render_scene(descs.second);
        scene.rr_depth = 1;
        RenderScene no_roulette = scene;
        no_roulette.rr_depth = 1 << 20;
        DeviceScene device(*ctx, KernelLibrary::from_environment(), scene);
        DeviceScene fd_device(*ctx, KernelLibrary::from_environment(), no_roulette);
        ParamState state(*ctx, scene.params);
        GradientStep step(device, KernelLibrary::from_environment(), LOSS_MEAN,
                          {ViewTarget{0, {}, {}}, ViewTarget{1, {}, {}}}, CvMode::none,
                          CvVariance::consistent);
        step.attach(state);
        const Parameter& p = scene.params.find("matte.reflectance");
        const std::vector<float> theta = scene.params.values();
        auto mean_images = [&](const std::vector<float>& values, std::uint32_t seed0, std::uint32_t seed1) {
            Buffer<float> params(*ctx, "params", values);
            double sum = 0.0;
            for (unsigned k = 0; k < 2; ++k) {
                Buffer<float> rgb(*ctx, "image", 3 * fd_device.pixels(k));
                render(View(fd_device, k), params, k == 0 ? seed0 : seed1, 8, rgb);
                double s = 0.0;
                for (float v : rgb.download()) s += v;
                sum += s / double(rgb.size());
            }
            return sum;
        };
        test::Stat diff, prb;
        for (unsigned s = 0; s < 16; ++s) {
            ViewPass a, b;
            a.view = 0, b.view = 1;
            a.seed_adjoint = 500 + s, b.seed_adjoint = 900 + s;
            step.evaluate(state, {a, b}, 1, 8);
            const std::vector<float> g = state.gradient().value.download();
            const double gv = double(g[p.offset]) + g[p.offset + 1] + g[p.offset + 2];
            auto central = [&](float h) {
                std::vector<float> plus = theta, minus = theta;
                for (unsigned c = 0; c < 3; ++c) plus[p.offset + c] += h, minus[p.offset + c] -= h;
                return (mean_images(plus, a.seed_adjoint, b.seed_adjoint) -
                        mean_images(minus, a.seed_adjoint, b.seed_adjoint)) / (2.0 * h);
            };
            const double fd = (4.0 * central(0.02f) - central(0.04f)) / 3.0;
            prb.add(gv);
            diff.add(gv - fd);
        }
        const double tolerance = 4.0 * diff.se() + 1e-5 * std::abs(prb.mean());
        INFO("g.v " << prb.mean() << " +- " << prb.se() << ", PRB - FD " << diff.mean() << " +- " << diff.se());
        CHECK(std::abs(diff.mean()) <= tolerance);
        CHECK(tolerance < 0.1 * std::abs(prb.mean())); // the check has the power to fail
        // and each view's share counts: view 1 alone gives a different gradient
        GradientStep single(device, KernelLibrary::from_environment(), LOSS_MEAN,
                            {ViewTarget{1, {}, {}}}, CvMode::none, CvVariance::consistent);
        single.attach(state);
        ViewPass b;
        b.seed_adjoint = 900;
        single.evaluate(state, {b}, 1, 8);
        const std::vector<float> g1 = state.gradient().value.download();
        CHECK(std::abs(double(g1[p.offset]) + g1[p.offset + 1] + g1[p.offset + 2]) < 0.9 * std::abs(prb.mean()));
    }

    TEST_CASE("a mask of 0 leaves a pixel out of the loss and its gradient") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = build_render_scene(one_and_two_sensors(12).first);
        DeviceScene device(*ctx, KernelLibrary::from_environment(), scene);
        const std::size_t pixels = device.pixels(0);
        std::vector<float> reference(3 * pixels, 0.25f), mask(pixels, 1.0f);
        for (std::size_t i = 0; i < pixels; i += 2) mask[i] = 0.0f; // every other pixel out
        auto run = [&](const std::vector<float>& m) {
            ParamState state(*ctx, scene.params);
            GradientStep step(device, KernelLibrary::from_environment(), LOSS_L2,
                              {ViewTarget{0, reference, m}}, CvMode::none, CvVariance::consistent);
            step.attach(state);
            step.evaluate(state, 0, 3, 2, 4, 2);
            return std::make_pair(step.loss(), step.delta().download());
        };
        const auto [full_loss, full_delta] = run({});
        const auto [masked_loss, masked_delta] = run(mask);
        bool exact = true;
        for (std::size_t i = 0; i < pixels; ++i)
            for (unsigned c = 0; c < 3; ++c) // the same render: exactly
                exact = exact && masked_delta[3 * i + c] ==
                                     (mask[i] == 0.0f ? 0.0f : full_delta[3 * i + c]);
        CHECK(exact);
        CHECK(masked_loss < full_loss);
        CHECK(masked_loss > 0.3 * full_loss);
        CHECK(error_of([&] { run(std::vector<float>(pixels - 1, 1.0f)); }).find("the mask of sensor 0 has") == 0);
    }
}
