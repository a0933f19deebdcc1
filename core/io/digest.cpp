// Content digests through libxxhash's streaming XXH3.
#include "core/io/digest.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

#include <xxhash.h>

#include "runtime/error.h"

namespace tandem {

std::uint64_t digest(const void* data, std::size_t size) {
    return XXH3_64bits(data, size);
}

std::uint64_t digest_file(const std::string& path) {
    const std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"),
                                                            &std::fclose);
    if (!f) throw Error(path + ": cannot open (" + std::strerror(errno) + ")");
    const std::unique_ptr<XXH3_state_t, XXH_errorcode (*)(XXH3_state_t*)> state(XXH3_createState(),
                                                                                &XXH3_freeState);
    if (!state || XXH3_64bits_reset(state.get()) != XXH_OK)
        throw Error(path + ": cannot digest (out of memory)");
    std::vector<char> block(1 << 20);
    for (;;) {
        const std::size_t n = std::fread(block.data(), 1, block.size(), f.get());
        if (n > 0) XXH3_64bits_update(state.get(), block.data(), n);
        if (n < block.size()) break;
    }
    if (std::ferror(f.get())) throw Error(path + ": read failed (" + std::strerror(errno) + ")");
    return XXH3_64bits_digest(state.get());
}

std::string digest_hex(std::uint64_t d) {
    char s[17];
    std::snprintf(s, sizeof(s), "%016llx", static_cast<unsigned long long>(d));
    return s;
}

} // namespace tandem
