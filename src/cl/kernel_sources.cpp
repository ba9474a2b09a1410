// cambium — kernel source lookup and include expansion.
#include "cl/kernel_sources.h"

#include <fmt/format.h>

#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

namespace cambium {

namespace {

std::string embedded(const std::string& name)
{
    for (size_t i = 0; i < detail::kEmbeddedKernelCount; ++i)
        if (name == detail::kEmbeddedKernels[i].name)
            return detail::kEmbeddedKernels[i].text;
    throw std::runtime_error(fmt::format("kernel file '{}' is not embedded in this binary", name));
}

/// Files made by the build rather than kept in kernels/ (NanoVDB's header
/// prepared for OpenCL): CAMBIUM_KERNEL_DIR need not hold them.
bool isGenerated(const std::string& name)
{
    return name == "PNanoVDB.h";
}

}  // namespace

std::string kernelFile(const std::string& name)
{
    if (const char* dir = std::getenv("CAMBIUM_KERNEL_DIR"); dir && *dir) {
        const std::string path = std::string(dir) + "/" + name;
        std::ifstream in(path, std::ios::binary);
        if (!in && isGenerated(name))
            return embedded(name);
        if (!in)
            throw std::runtime_error(fmt::format(
                "kernel file {} not found (CAMBIUM_KERNEL_DIR={}); unset CAMBIUM_KERNEL_DIR to use "
                "the embedded kernels",
                path, dir));
        std::ostringstream s;
        s << in.rdbuf();
        return s.str();
    }
    return embedded(name);
}

std::vector<std::string> embeddedKernelFiles()
{
    std::vector<std::string> names;
    for (size_t i = 0; i < detail::kEmbeddedKernelCount; ++i)
        names.emplace_back(detail::kEmbeddedKernels[i].name);
    return names;
}

namespace {

void expand(const std::string& source, std::set<std::string>& seen, std::string& out)
{
    std::istringstream in(source);
    std::string line;
    while (std::getline(in, line)) {
        const auto first = line.find_first_not_of(" \t");
        if (first != std::string::npos && line.compare(first, 8, "#include") == 0) {
            const auto open = line.find('"', first);
            const auto close = open == std::string::npos ? open : line.find('"', open + 1);
            if (close != std::string::npos) {
                const std::string name = line.substr(open + 1, close - open - 1);
                if (seen.insert(name).second)
                    expand(kernelFile(name), seen, out);
                continue;
            }
            // <system> includes are host-only (guarded by __OPENCL_VERSION__).
        }
        out += line;
        out += '\n';
    }
}

}  // namespace

std::string assembleKernelSource(const std::string& source)
{
    std::set<std::string> seen;
    std::string out;
    expand(source, seen, out);
    return out;
}

}  // namespace cambium
