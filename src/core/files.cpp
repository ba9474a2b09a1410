// cambium — output files that appear whole or not at all.
#include "core/files.h"

#include "core/error.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>

namespace cambium {

std::string temporaryPathFor(const std::string& path)
{
    return fmt::format("{}.tmp-{}", path, ::getpid());
}

void checkWritable(const std::string& path)
{
    const std::string tmp = temporaryPathFor(path);
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
    if (fd < 0)
        throw InputError(fmt::format("{}: cannot write the output: {}", path, std::strerror(errno)));
    ::close(fd);
    ::unlink(tmp.c_str());
}

void writeAtomically(const std::string& path, const std::function<void(const std::string& tmp)>& write)
{
    const std::string tmp = temporaryPathFor(path);
    try {
        write(tmp);
    } catch (const std::exception& e) {
        ::unlink(tmp.c_str());
        throw InputError(fmt::format("{}: cannot write the output: {}", path, e.what()));
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const std::string why = std::strerror(errno);
        ::unlink(tmp.c_str());
        throw InputError(fmt::format("{}: cannot write the output: {}", path, why));
    }
}

}  // namespace cambium
