// cambium — a file read with pread at any offset, from any thread: the
// .vdb readers' (io/vdb_read.cpp, io/vdb_tree.cpp).
#pragma once

#include "core/error.h"

#include <fmt/format.h>

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <string>

namespace cambium {

/// A file read with pread, closed with its owner.
class ReadFile {
public:
    explicit ReadFile(const std::string& path) : path_(path), fd_(::open(path.c_str(), O_RDONLY))
    {
        if (fd_ < 0)
            throw InputError(
                fmt::format("{}: cannot read the .vdb file: {}", path, std::strerror(errno)));
    }
    ~ReadFile() { ::close(fd_); }
    ReadFile(const ReadFile&) = delete;
    ReadFile& operator=(const ReadFile&) = delete;

    int fd() const { return fd_; }

    /// Exactly n bytes at `offset` (the structure check found the file this long).
    void read(uint64_t offset, char* out, size_t n) const
    {
        while (n > 0) {
            const ssize_t got = ::pread(fd_, out, n, off_t(offset));
            if (got < 0 && errno == EINTR)
                continue;
            if (got <= 0)
                throw InputError(fmt::format("{}: cannot read the .vdb file at byte {}: {}", path_,
                                             offset, got < 0 ? std::strerror(errno) : "it ended"));
            out += got;
            n -= size_t(got);
            offset += uint64_t(got);
        }
    }

private:
    std::string path_;
    int fd_;
};

}  // namespace cambium
