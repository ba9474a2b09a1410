// cambium — OpenCL kernel sources, embedded in the binary at build time.
//
// The files of kernels/ are compiled into the binary (cmake/EmbedKernels.cmake)
// so that an installed cambium needs nothing beside it.  For development,
// CAMBIUM_KERNEL_DIR=/path/to/kernels makes cambium read them from disk instead.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace cambium {

namespace detail {
struct EmbeddedKernel {
    const char* name;
    const char* text;
};
extern const EmbeddedKernel kEmbeddedKernels[];
extern const size_t kEmbeddedKernelCount;
}  // namespace detail

/// The text of one file of kernels/ ("cb_primitives.h", "sample.cl", ...):
/// from $CAMBIUM_KERNEL_DIR when set, else the embedded copy.  "PNanoVDB.h",
/// which the build prepares from NanoVDB's header, is always the embedded copy
/// unless that directory holds one.  Throws
/// std::runtime_error naming the file when it exists in neither place.
std::string kernelFile(const std::string& name);

/// Names of the embedded kernel files.
std::vector<std::string> embeddedKernelFiles();

/// `source` with every line `#include "name"` replaced by kernelFile(name),
/// recursively and once per file (the headers have include guards anyway):
/// an OpenCL program is built from a single string.
std::string assembleKernelSource(const std::string& source);

}  // namespace cambium
