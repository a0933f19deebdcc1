// The parameter state and its generic save/restore.
#include "core/inverse/param_state.h"

#include <cstring>

#include "core/io/binary.h"
#include "runtime/error.h"

namespace tandem {

ParamState::ParamState(Context& ctx, const ParamRegistry& registry)
    : m_ctx(&ctx), m_theta(ctx, "parameters", at_least_one(registry.values())),
      m_theta_prev(ctx, "parameters (previous state)", at_least_one(registry.values())),
      m_lr(ctx, "learning rates", std::vector<float>(m_theta.size())),
      m_lower(ctx, "lower bounds", at_least_one(registry.lower_bounds())),
      m_upper(ctx, "upper bounds", at_least_one(registry.upper_bounds())),
      m_gradient(ctx, registry.size()) {
    // What a checkpoint restores besides the named buffers (which follow them, by name: the
    // optimizer's moments "adam.m" and "adam.v" come right after these, as when they were
    // members). The learning rates and ranges come from the configuration and the scene, and the
    // gradient is recomputed every iteration.
    m_members.emplace_back("theta", std::make_unique<Typed<float>>(m_theta));
    m_members.emplace_back("theta_prev", std::make_unique<Typed<float>>(m_theta_prev));
}

void ParamState::insert(const std::string& name, std::unique_ptr<AnyBuffer> b) {
    for (const auto& [member, _] : m_members)
        if (member == name) throw Error("parameter state: '" + name + "' is a reserved name");
    if (!m_named.emplace(name, std::move(b)).second)
        throw Error("parameter state: a buffer named '" + name + "' exists already");
}

ParamState::AnyBuffer* ParamState::find(const std::string& name) {
    const auto it = m_named.find(name);
    if (it == m_named.end()) throw Error("parameter state: no buffer named '" + name + "'");
    return it->second.get();
}

std::vector<std::pair<std::string, ParamState::AnyBuffer*>> ParamState::saved() const {
    std::vector<std::pair<std::string, AnyBuffer*>> out;
    for (const auto& [name, b] : m_members)
        out.emplace_back(name, b.get());
    for (const auto& [name, b] : m_named)
        out.emplace_back(name, b.get());
    return out;
}

void ParamState::save(std::string& out) const {
    put_bytes<std::uint32_t>(out, m_steps);
    const auto buffers = saved();
    put_bytes<std::uint64_t>(out, buffers.size());
    for (const auto& [name, b] : buffers) {
        put_bytes<std::uint64_t>(out, name.size());
        out += name;
        put_bytes<std::uint64_t>(out, b->element_size());
        put_bytes<std::uint64_t>(out, b->count());
        out += b->bytes();
    }
}

void ParamState::load(const std::string& data, std::size_t& pos, const std::string& path) {
    std::size_t at = pos; // `pos` moves only when everything is restored
    const auto steps = take_bytes<std::uint32_t>(data, at, path);
    const auto buffers = saved();
    const auto n = take_bytes<std::uint64_t>(data, at, path);
    if (n != buffers.size())
        throw Error(path + ": the checkpoint holds " + std::to_string(n) +
                    " state buffers where this run has " + std::to_string(buffers.size()));
    // Check every entry first, then restore: a mismatch leaves the state as it was.
    std::vector<std::size_t> offsets;
    for (const auto& [name, b] : buffers) {
        const auto length = take_bytes<std::uint64_t>(data, at, path);
        if (length > data.size() - at) throw Error(path + ": truncated checkpoint");
        const std::string saved_name = data.substr(at, length);
        at += length;
        const auto element = take_bytes<std::uint64_t>(data, at, path);
        const auto count = take_bytes<std::uint64_t>(data, at, path);
        if (saved_name != name)
            throw Error(path + ": the checkpoint holds state '" + saved_name +
                        "' where this run has '" + name + "'");
        if (element != b->element_size())
            throw Error(path + ": checkpoint state '" + name + "' has " + std::to_string(element) +
                        "-byte elements where this run has " + std::to_string(b->element_size()));
        if (count != b->count())
            throw Error(path + ": checkpoint state '" + name + "' holds " + std::to_string(count) +
                        " values where this run has " + std::to_string(b->count()));
        if (count > (data.size() - at) / element) throw Error(path + ": truncated checkpoint");
        offsets.push_back(at);
        at += element * count;
    }
    for (std::size_t i = 0; i < buffers.size(); ++i)
        buffers[i].second->set_bytes(data.data() + offsets[i]);
    m_steps = steps;
    pos = at;
}

} // namespace tandem
