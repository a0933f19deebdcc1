// Participating media flattened for the device: Medium records, their grids and majorant grids.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <tuple>

#include <glm/gtc/type_ptr.hpp>
#include <glm/matrix.hpp>

#include "core/io/volume_io.h"
#include "core/scene/render_scene.h"
#include "runtime/error.h"
#include "shared/medium.h"

namespace tandem {

namespace {

/// Voxels per majorant cell along each axis: coarse enough that a ray crosses few cells, fine
/// enough that a cell's bound is tight where the density varies (a 64^3 grid gets 8^3 cells).
constexpr unsigned k_majorant_cell_voxels = 8;

/// The grid record of values placed by to_world (the unit cube into the world).
gpu::DeviceGrid device_grid(const glm::mat4& to_world, unsigned offset, unsigned nx, unsigned ny,
                            unsigned nz, unsigned channels) {
    const glm::mat4 inv = glm::inverse(to_world);
    gpu::DeviceGrid g{};
    const auto row = [&](int r) {
        return gpu::make_float4(inv[0][r], inv[1][r], inv[2][r], inv[3][r]);
    };
    g.to_local0 = row(0);
    g.to_local1 = row(1);
    g.to_local2 = row(2);
    g.offset = offset;
    g.nx = nx;
    g.ny = ny;
    g.nz = nz;
    g.channels = channels;
    return g;
}

} // namespace

std::vector<float> build_majorant_grid(const std::vector<float>& values, unsigned nx, unsigned ny,
                                       unsigned nz, unsigned channels, unsigned cells_x,
                                       unsigned cells_y, unsigned cells_z) {
    std::vector<float> out(std::size_t(cells_x) * cells_y * cells_z, 0.0f);
    for (unsigned cz = 0; cz < cells_z; ++cz)
        for (unsigned cy = 0; cy < cells_y; ++cy)
            for (unsigned cx = 0; cx < cells_x; ++cx) {
                unsigned x0, x1, y0, y1, z0, z1;
                gpu::majorant_cell_voxels(cx, cells_x, nx, &x0, &x1);
                gpu::majorant_cell_voxels(cy, cells_y, ny, &y0, &y1);
                gpu::majorant_cell_voxels(cz, cells_z, nz, &z0, &z1);
                float m = 0.0f;
                for (unsigned z = z0; z <= z1; ++z)
                    for (unsigned y = y0; y <= y1; ++y)
                        for (unsigned x = x0; x <= x1; ++x)
                            for (unsigned c = 0; c < channels; ++c)
                                m = std::max(
                                    m, values[((std::size_t(z) * ny + y) * nx + x) * channels + c]);
                out[(std::size_t(cz) * cells_y + cy) * cells_x + cx] = m;
            }
    return out;
}

void build_media(const SceneDesc& desc, RenderScene& out) {
    for (std::size_t i = 0; i < desc.media.size(); ++i) {
        const Medium& m = desc.media[i];
        const std::string where = desc.path + ":" + std::to_string(m.line) + ": medium" +
                                  (m.id.empty() ? "" : " '" + m.id + "'") + ": ";
        gpu::Medium d{};
        d.phase = m.phase == PhaseType::hg ? PHASE_HG : PHASE_ISOTROPIC;
        d.g = m.g;
        d.albedo = gpu::make_float4(m.albedo.value.x, m.albedo.value.y, m.albedo.value.z, 0.0f);
        d.sigma_t_grid = d.albedo_grid = d.majorant_grid = NO_GRID;
        // A grid, range-checked: its record (whose voxels are a parameter) and values.
        const auto add_grid = [&](const VolumeInput& v, const char* what, float hi) {
            VolumeGrid grid;
            try {
                grid = read_volume(v.filename);
            } catch (const Error& e) {
                throw Error(where + what + ": " + e.what());
            }
            for (std::size_t i = 0; i < grid.values.size(); ++i) {
                const float x = grid.values[i];
                if (x >= 0.0f && x <= hi) continue;
                const std::size_t voxel = i / std::size_t(grid.channels);
                const std::size_t vx = voxel % grid.width, vy = voxel / grid.width % grid.height,
                                  vz = voxel / (std::size_t(grid.width) * grid.height);
                throw Error(where + what + ": " + v.filename + ": voxel (" + std::to_string(vx) +
                            ", " + std::to_string(vy) + ", " + std::to_string(vz) + ") is " +
                            std::to_string(x) + ", outside [0, " +
                            (hi > 1.0f ? std::string("inf") : std::string("1")) + "]");
            }
            // a .vdb grid sits where its own transform puts it, then where to_world does
            const glm::mat4 to_world =
                grid.placed ? v.to_world * glm::make_mat4(grid.to_world.data()) : v.to_world;
            // its voxels are a parameter: the offset is set once they are registered, below
            out.grids.push_back(device_grid(to_world, NO_PARAM, unsigned(grid.width),
                                            unsigned(grid.height), unsigned(grid.depth),
                                            unsigned(grid.channels)));
            return std::make_pair(static_cast<unsigned>(out.grids.size() - 1), grid);
        };
        VolumeGrid albedo_grid, sigma_t_grid;
        if (m.albedo.grid) std::tie(d.albedo_grid, albedo_grid) = add_grid(m.albedo, "albedo", 1.0f);
        const bool grid_sigma_t = m.type == MediumType::heterogeneous && m.sigma_t.grid;
        d.sigma_t = gpu::make_float4(1.0f, 1.0f, 1.0f, m.scale);
        if (grid_sigma_t) {
            const auto [index, grid] =
                add_grid(m.sigma_t, "sigma_t", std::numeric_limits<float>::max());
            sigma_t_grid = grid;
            d.kind = MEDIUM_GRID;
            d.sigma_t_grid = index;
            const auto cells = [](int n) {
                return std::max(1u, (unsigned(n) + k_majorant_cell_voxels - 1) /
                                        k_majorant_cell_voxels);
            };
            const unsigned cx = cells(grid.width), cy = cells(grid.height), cz = cells(grid.depth);
            const std::vector<float> bounds =
                build_majorant_grid(grid.values, unsigned(grid.width), unsigned(grid.height),
                                    unsigned(grid.depth), unsigned(grid.channels), cx, cy, cz);
            const auto offset = static_cast<unsigned>(out.medium_data.size());
            out.medium_data.insert(out.medium_data.end(), bounds.begin(), bounds.end());
            gpu::DeviceGrid bounds_grid = out.grids[index]; // the same placement
            bounds_grid.offset = offset;
            bounds_grid.nx = cx;
            bounds_grid.ny = cy;
            bounds_grid.nz = cz;
            bounds_grid.channels = 1u;
            out.grids.push_back(bounds_grid);
            d.majorant_grid = static_cast<unsigned>(out.grids.size() - 1);
            d.majorant = m.scale * *std::max_element(bounds.begin(), bounds.end());
        } else {
            // homogeneous, or a heterogeneous medium of constant extinction
            // (the kernel multiplies by the scale: medium_load)
            const glm::vec3 st = m.sigma_t.value * m.scale;
            d.kind = MEDIUM_HOMOGENEOUS;
            d.sigma_t = gpu::make_float4(m.sigma_t.value.x, m.sigma_t.value.y, m.sigma_t.value.z,
                                         m.scale);
            d.majorant = std::max({st.x, st.y, st.z});
        }
        const MediumParams p = out.params.add_medium(desc, i, grid_sigma_t ? &sigma_t_grid : nullptr,
                                                     m.albedo.grid ? &albedo_grid : nullptr);
        if (grid_sigma_t) out.grids[d.sigma_t_grid].offset = p.sigma_t;
        if (m.albedo.grid) out.grids[d.albedo_grid].offset = p.albedo;
        d.sigma_t_param = p.sigma_t;
        d.albedo_param = p.albedo;
        d.scale_param = p.scale;
        d.g_param = p.g;
        d.pad0 = 0;
        if (!std::isfinite(d.majorant))
            throw Error(where + "sigma_t times scale overflows (" + std::to_string(d.majorant) +
                        ")");
        out.media.push_back(d);
    }
}

} // namespace tandem
