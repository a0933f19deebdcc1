// The parameter state and its generic save/restore.
#include "core/inverse/param_state.h"

#include <algorithm>
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

void ParamState::set_buffer_bytes(const std::string& name, const std::string& bytes) {
    AnyBuffer* b = find(name);
    if (bytes.size() != b->element_size() * b->count())
        throw Error("parameter state: " + std::to_string(bytes.size()) + " bytes for buffer '" +
                    name + "' of " + std::to_string(b->element_size() * b->count()));
    b->set_bytes(bytes.data(), b->count());
}

std::vector<std::pair<std::string, ParamState::AnyBuffer*>> ParamState::saved() const {
    std::vector<std::pair<std::string, AnyBuffer*>> out;
    for (const auto& [name, b] : m_members)
        out.emplace_back(name, b.get());
    for (const auto& [name, b] : m_named)
        out.emplace_back(name, b.get());
    return out;
}

void ParamState::save(SectionWriter& out) const {
    const auto buffers = saved();
    std::string head;
    put_bytes<std::uint32_t>(head, m_steps);
    put_bytes<std::uint64_t>(head, buffers.size());
    for (const auto& [name, b] : buffers)
        put_string(head, name);
    out.add("state", std::move(head));
    for (const auto& [name, b] : buffers) {
        std::string section;
        put_bytes<std::uint64_t>(section, b->element_size());
        put_bytes<std::uint64_t>(section, b->count());
        section += b->bytes();
        out.add("state:" + name, std::move(section));
    }
}

void ParamState::load(const SectionReader& in) {
    const std::string where = in.where("state");
    const std::string_view head = in.payload("state");
    std::size_t at = 0;
    const auto steps = take_bytes<std::uint32_t>(head, at, where);
    const auto buffers = saved();
    const auto n = take_bytes<std::uint64_t>(head, at, where);
    std::vector<std::string> names;
    for (std::uint64_t i = 0; i < n && i <= buffers.size(); ++i)
        names.push_back(take_string(head, at, where));
    for (std::size_t i = 0; i < std::max<std::size_t>(names.size(), buffers.size()); ++i) {
        if (i >= names.size())
            throw Error(where + ": the checkpoint has no state '" + buffers[i].first +
                        "', which this run has");
        if (i >= buffers.size())
            throw Error(where + ": the checkpoint holds state '" + names[i] +
                        "', which this run has not");
        if (names[i] != buffers[i].first)
            throw Error(where + ": the checkpoint holds state '" + names[i] +
                        "' where this run has '" + buffers[i].first + "'");
    }
    // Check every buffer first, then restore: a mismatch leaves the state as it was.
    std::vector<const char*> bytes;
    std::vector<std::size_t> counts;
    for (const auto& [name, b] : buffers) {
        const std::string section = "state:" + name;
        const std::string w = in.where(section);
        const std::string_view data = in.payload(section);
        std::size_t pos = 0;
        const auto element = take_bytes<std::uint64_t>(data, pos, w);
        const auto count = take_bytes<std::uint64_t>(data, pos, w);
        if (element != b->element_size())
            throw Error(w + ": " + std::to_string(element) + "-byte elements where this run has " +
                        std::to_string(b->element_size()));
        if (count != b->count() && !(b->any_size && count > 0))
            throw Error(w + ": " + std::to_string(count) + " values where this run has " +
                        std::to_string(b->count()));
        // (a count of any size comes from the file: no product that could wrap)
        if ((data.size() - pos) % element != 0 || (data.size() - pos) / element != count)
            throw Error(w + ": " + std::to_string(data.size() - pos) + " bytes for " +
                        std::to_string(count) + " values");
        bytes.push_back(data.data() + pos);
        counts.push_back(std::size_t(count));
    }
    for (std::size_t i = 0; i < buffers.size(); ++i)
        buffers[i].second->set_bytes(bytes[i], counts[i]);
    m_steps = steps;
}

} // namespace tandem
