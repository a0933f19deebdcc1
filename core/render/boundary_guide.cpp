// The guide of the secondary boundary term: training, binning, CDFs.
#include "core/render/boundary_guide.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "runtime/error.h"

namespace tandem {

int secondary_guide_mode(const std::string& name, const std::string& what) {
    if (name == "auto") return -1;
    if (name == "on") return 1;
    if (name == "off") return 0;
    throw Error(what + ": '" + name + "' is not a guide mode (auto, on or off)");
}

bool secondary_guided(const RenderScene& scene) {
    for (const gpu::Material& m : scene.materials)
        if (m.type == MATERIAL_ROUGHCONDUCTOR || m.type == MATERIAL_ROUGHPLASTIC) return true;
    return false;
}

namespace {

/// h blurred by [1 2 1]^2 / 16 over its n x n cells: theta clamped, phi wrapping.
std::vector<double> blur_cells(const std::vector<double>& h, unsigned n) {
    std::vector<double> out(h.size(), 0.0);
    for (unsigned i = 0; i < n; ++i)
        for (unsigned j = 0; j < n; ++j) {
            double sum = 0.0;
            for (int di = -1; di <= 1; ++di) {
                const int ii = int(i) + di;
                if (ii < 0 || ii >= int(n)) continue;
                for (int dj = -1; dj <= 1; ++dj) {
                    const auto jj = unsigned((int(j) + dj + int(n)) % int(n));
                    sum += double((2 - std::abs(di)) * (2 - std::abs(dj))) * h[unsigned(ii) * n + jj];
                }
            }
            out[i * n + j] = sum / 16.0;
        }
    return out;
}

} // namespace

SecondaryGuideTables build_secondary_guide(const std::vector<gpu::float4>& samples,
                                           const std::vector<unsigned>& cells,
                                           const std::vector<unsigned>& edge_of,
                                           unsigned edge_count, const SecondaryGuideShape& shape) {
    SecondaryGuideTables out;
    const unsigned bins = shape.bins, n = shape.dir_res;
    // the kernels index slot * cells in 32 bits
    if (bins == 0 || n == 0 || n > 1024 ||
        std::uint64_t(shape.max_slots) * n * n >= (std::uint64_t(1) << 32))
        throw Error("secondary guide: bins " + std::to_string(bins) + ", dir_res " +
                    std::to_string(n) + ", max_slots " + std::to_string(shape.max_slots) +
                    " (need bins and dir_res >= 1, dir_res <= 1024, max_slots dir_res^2 < 2^32)");
    const unsigned cell_count = n * n;
    out.guide.bins = bins;
    out.guide.dir_res = n;
    out.edge_slot.assign(edge_count, GUIDE_NO_SLOT);
    out.edge_weight.assign(edge_count, 0.0);
    auto used = [&](std::size_t i) {
        return samples[i].y > 0.0f && std::isfinite(samples[i].y) &&
               std::isfinite(samples[i].x) && cells[i] < cell_count && edge_of[i] < edge_count;
    };
    for (std::size_t i = 0; i < samples.size(); ++i)
        if (used(i)) out.edge_weight[edge_of[i]] += samples[i].y;
    // the edges of most weight first (ties by index), as many as max_slots holds
    std::vector<unsigned> order(edge_count);
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](unsigned a, unsigned b) {
        return out.edge_weight[a] > out.edge_weight[b];
    });
    unsigned slots = 0;
    for (unsigned e : order) {
        if (!(out.edge_weight[e] > 0.0) || slots + bins > shape.max_slots) break;
        out.edge_slot[e] = slots;
        slots += bins;
    }
    if (slots == 0) return out; // nothing learnt: no guide
    std::vector<double> hist(std::size_t(slots) * cell_count, 0.0);
    for (std::size_t i = 0; i < samples.size(); ++i) {
        if (!used(i) || out.edge_slot[edge_of[i]] == GUIDE_NO_SLOT) continue;
        const unsigned bin = std::min(unsigned(std::max(samples[i].x, 0.0f) * float(bins)), bins - 1);
        hist[std::size_t(out.edge_slot[edge_of[i]] + bin) * cell_count + cells[i]] += samples[i].y;
    }
    out.cdf.resize(hist.size());
    for (unsigned e = 0; e < edge_count; ++e) {
        if (out.edge_slot[e] == GUIDE_NO_SLOT) continue;
        std::vector<double> whole(cell_count, 0.0); // the edge's histogram, for empty bins
        for (unsigned b = 0; b < bins; ++b)
            for (unsigned c = 0; c < cell_count; ++c)
                whole[c] += hist[std::size_t(out.edge_slot[e] + b) * cell_count + c];
        for (unsigned b = 0; b < bins; ++b) {
            const std::size_t base = std::size_t(out.edge_slot[e] + b) * cell_count;
            std::vector<double> h(hist.begin() + std::ptrdiff_t(base),
                                  hist.begin() + std::ptrdiff_t(base + cell_count));
            if (!(std::accumulate(h.begin(), h.end(), 0.0) > 0.0)) h = whole;
            const std::vector<double> smooth = blur_cells(h, n);
            const double total = std::accumulate(smooth.begin(), smooth.end(), 0.0);
            double running = 0.0;
            for (unsigned c = 0; c < cell_count; ++c) {
                running += smooth[c];
                out.cdf[base + c] = static_cast<float>(running / total);
            }
            out.cdf[base + cell_count - 1] = 1.0f;
        }
    }
    out.guide.fraction = shape.fraction;
    out.guide.slots = slots;
    return out;
}

void guide_edge_choice(const SecondaryGuideTables& guide, const SecondaryGuideShape& shape,
                       std::vector<gpu::SecondaryEdge>& edges) {
    const double total = std::accumulate(guide.edge_weight.begin(), guide.edge_weight.end(), 0.0);
    if (!(total > 0.0) || guide.edge_weight.size() != edges.size()) return;
    const double f = shape.edge_fraction;
    for (std::size_t i = 0; i < edges.size(); ++i)
        edges[i].n0.w = static_cast<float>((1.0 - f) * edges[i].n0.w +
                                           f * guide.edge_weight[i] / total);
}

SecondaryGuideTables train_secondary_guide(const View& view, const Buffer<float>& params,
                                           std::uint32_t seed, int per_pixel,
                                           const Buffer<gpu::SecondaryEdge>& edges,
                                           unsigned edge_count, const SecondaryGuideShape& shape) {
    DeviceScene& scene = *view.scene;
    Context& ctx = scene.context();
    // as many as the estimate's samples, within [2^10, 2^20], and at most 2^28 / edges: each
    // searches every edge, and a scene of many edges would spend its time here
    const std::size_t cap = std::max<std::size_t>(
        std::size_t(1) << 10, (std::size_t(1) << 28) / std::max(edge_count, 1u));
    const auto count = static_cast<unsigned>(std::min(
        cap, std::clamp<std::size_t>(view.pixels() * std::size_t(per_pixel), std::size_t(1) << 10,
                                     std::size_t(1) << 20)));
    Buffer<gpu::float4> samples(ctx, "secondary guide samples", count);
    Buffer<unsigned> cells(ctx, "secondary guide cells", count);
    Buffer<unsigned> edge_of(ctx, "secondary guide edges", count);
    scene.launch(view.sensor, scene.kernel("boundary.cl", "boundary_guide_train"), "boundary",
                 count, scene.launch_params(seed), params, edges, edge_count, shape.dir_res, count,
                 samples, cells, edge_of);
    return build_secondary_guide(samples.download(), cells.download(), edge_of.download(),
                                 edge_count, shape);
}

} // namespace tandem
