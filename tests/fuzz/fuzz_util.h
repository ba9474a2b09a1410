// cambium fuzzing — what every harness shares: an input is either read or
// refused with an InputError; any other exception, a crash, a sanitizer
// report, a leak of time or memory beyond libFuzzer's limits is a finding.
#pragma once

#include "core/error.h"

#include <cstdint>
#include <cstdio>
#include <string>
#include <unistd.h>

namespace cambium::fuzz {

inline std::string text(const uint8_t* data, size_t size)
{
    return std::string(reinterpret_cast<const char*>(data), size);
}

/// Runs `read`; an InputError (the input was refused by name) is a fine end.
template <class F>
void readOrRefuse(F&& read)
{
    try {
        read();
    } catch (const InputError&) {
    }
}

/// A file of this process holding `data`, for readers that take a path.
inline std::string asFile(const uint8_t* data, size_t size, const char* extension)
{
    static const std::string path = [&] {
        const char* dir = ::access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
        return std::string(dir) + "/cambium_fuzz_" + std::to_string(::getpid()) + extension;
    }();
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f) {
        std::fwrite(data, 1, size, f);
        std::fclose(f);
    }
    return path;
}

}  // namespace cambium::fuzz
