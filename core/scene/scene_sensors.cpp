// Mitsuba 3 XML, second pass: the sensors (a perspective sensor, or Mitsuba's batch of them).
#include <map>

#include "core/scene/scene.h"
#include "core/scene/scene_reader.h"
#include "runtime/error.h"

namespace tandem::scene_detail {

namespace {

/// The loader's errors: "FILE:LINE: what".
struct Sensors {
    const std::string& m_path;
    const std::function<int(const Node&)>& m_medium;
    std::vector<std::pair<Camera, const Node*>> out;

    [[noreturn]] void fail(int line, const std::string& what) const {
        throw Error(m_path + ":" + std::to_string(line) + ": " + what);
    }
    /// Mitsuba's batch sensor (src/sensors/batch.cpp): its film is split evenly, left to right,
    /// between its perspective sensors, which share its sampler.
    void batch(const Node& n) {
        Reader r(m_path, n);
        Camera shared;
        film_and_sampler(r, "<sensor type=\"batch\">", shared);
        const std::vector<const Node*> nested = r.children({"sensor"});
        if (nested.empty()) fail(n.line, "<sensor type=\"batch\">: no nested <sensor>");
        const int count = static_cast<int>(nested.size());
        if (shared.width % count != 0)
            fail(n.line, "<sensor type=\"batch\">: the film's width " +
                             std::to_string(shared.width) + " does not split evenly between its " +
                             std::to_string(count) + " sensors");
        r.finish();
        for (std::size_t i = 0; i < nested.size(); ++i) {
            const Node& c = *nested[i];
            Reader cr(m_path, c);
            require_type(cr, "perspective");
            for (const Node* own : cr.children({"film", "sampler"}))
                fail(own->line, "<sensor type=\"batch\">: a nested sensor has no <" + own->tag +
                                    "> of its own (the batch's is shared)");
            Camera cam = perspective(cr, c);
            cam.width = shared.width / count;
            cam.height = shared.height;
            cam.spp = shared.spp;
            if (cam.id.empty() && !n.id.empty()) cam.id = n.id + "_" + std::to_string(i);
            cr.finish();
            out.emplace_back(std::move(cam), &c);
        }
    }

    /// The properties of a perspective sensor (its film and sampler aside).
    Camera perspective(Reader& r, const Node& n) {
        Camera cam;
        cam.id = n.id;
        cam.line = n.line;
        cam.fov = r.get_float("fov", cam.fov);
        if (!(cam.fov > 0.f && cam.fov < 180.f))
            fail(n.line, "<sensor>: fov must be in (0, 180) degrees");
        const std::string axis = r.get_string("fov_axis", "x");
        const std::map<std::string, FovAxis> axes = {{"x", FovAxis::x},
                                                     {"y", FovAxis::y},
                                                     {"diagonal", FovAxis::diagonal},
                                                     {"smaller", FovAxis::smaller},
                                                     {"larger", FovAxis::larger}};
        if (!axes.count(axis))
            fail(r.get("fov_axis", {PropKind::string})->line,
                 "<sensor>: fov_axis must be x, y, diagonal, smaller or larger, not '" + axis +
                     "'");
        cam.fov_axis = axes.at(axis);
        cam.near_clip = r.get_float("near_clip", cam.near_clip);
        cam.far_clip = r.get_float("far_clip", cam.far_clip);
        if (!(cam.near_clip > 0.f && cam.far_clip > cam.near_clip))
            fail(n.line, "<sensor>: need 0 < near_clip < far_clip");
        cam.to_world = r.get_transform("to_world");
        // The medium the camera sits in (Mitsuba: any medium child of the sensor).
        const std::vector<const Node*> media = r.children({"medium", "ref"});
        if (media.size() > 1) fail(media[1]->line, "<sensor>: more than one medium");
        if (!media.empty()) cam.medium = m_medium(*media[0]);
        return cam;
    }

    /// The nested <film> and <sampler> of a sensor (`what`), into cam's film size and spp.
    void film_and_sampler(Reader& r, const std::string& what, Camera& cam) {
        const std::vector<const Node*> films = r.children({"film"});
        const std::vector<const Node*> samplers = r.children({"sampler"});
        if (films.size() > 1) fail(films[1]->line, what + ": more than one <film>");
        if (samplers.size() > 1) fail(samplers[1]->line, what + ": more than one <sampler>");
        if (!films.empty()) {
            Reader f(m_path, *films[0]);
            require_type(f, "hdrfilm");
            cam.width = f.get_int("width", cam.width);
            cam.height = f.get_int("height", cam.height);
            if (cam.width <= 0 || cam.height <= 0)
                fail(films[0]->line, "<film>: width and height must be positive");
            // The kernels index pixels, and three channels per pixel, in 32-bit integers.
            if (static_cast<long long>(cam.width) * cam.height > (1ll << 30))
                fail(films[0]->line, "<film>: " + std::to_string(cam.width) + " x " +
                                         std::to_string(cam.height) +
                                         " pixels; at most 2^30 (e.g. 32768 x 32768)");
            f.get_string("pixel_format", ""); // accepted and ignored
            f.get_string("component_format", "");
            for (const Node* rf : f.children({"rfilter"})) {
                Reader rr(m_path, *rf);
                require_type(rr, "box");
                rr.finish();
            }
            f.finish();
        }
        if (!samplers.empty()) {
            Reader s(m_path, *samplers[0]);
            require_type(s, "independent");
            cam.spp = s.get_int("sample_count", cam.spp);
            if (cam.spp <= 0) fail(samplers[0]->line, "<sampler>: sample_count must be positive");
            s.finish();
        }
    }
};

} // namespace

std::vector<std::pair<Camera, const Node*>>
read_sensor(const std::string& path, const Node& n,
            const std::function<int(const Node&)>& medium) {
    Sensors s{path, medium, {}};
    if (n.type == "batch") {
        s.batch(n);
        return std::move(s.out);
    }
    Reader r(path, n);
    require_type(r, "perspective");
    Camera cam = s.perspective(r, n);
    s.film_and_sampler(r, "<sensor>", cam);
    r.finish();
    s.out.emplace_back(std::move(cam), &n);
    return std::move(s.out);
}

} // namespace tandem::scene_detail

namespace tandem {

int find_sensor(const std::vector<Camera>& sensors, const std::string& key) {
    const int count = static_cast<int>(sensors.size());
    const bool digits = !key.empty() && key.find_first_not_of("0123456789") == std::string::npos;
    if (digits && key.size() <= 9 && std::stoi(key) < count) return std::stoi(key);
    for (int k = 0; k < count; ++k)
        if (!sensors[k].id.empty() && sensors[k].id == key) return k;
    std::string known;
    for (int k = 0; k < count; ++k)
        known += (k ? ", " : "") + std::to_string(k) +
                 (sensors[k].id.empty() ? "" : " ('" + sensors[k].id + "')");
    throw Error("no sensor '" + key + "': the scene has " + std::to_string(count) + " sensor" +
                (count == 1 ? "" : "s") + ": " + known);
}

} // namespace tandem
