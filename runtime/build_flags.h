// Kernel feature flags: an ordered set of NAME=value defines, each always passed explicitly (0 or
// 1, or a small integer), so a kernel that tests a flag it was not given fails to build.
#pragma once

#include <map>
#include <string>

namespace tandem {

class BuildFlags {
public:
    BuildFlags& set(const std::string& name, int value) {
        m_flags[name] = value;
        return *this;
    }
    int get(const std::string& name) const {
        const auto it = m_flags.find(name);
        return it == m_flags.end() ? -1 : it->second;
    }
    /// "-D A=1 -D B=0 ...", in name order (so equal sets give equal options and cache keys).
    std::string options() const {
        std::string out;
        for (const auto& [name, value] : m_flags)
            out += (out.empty() ? "" : " ") + std::string("-D ") + name + "=" + std::to_string(value);
        return out;
    }
    const std::map<std::string, int>& flags() const { return m_flags; }
    bool operator==(const BuildFlags& o) const { return m_flags == o.m_flags; }

private:
    std::map<std::string, int> m_flags;
};

} // namespace tandem
