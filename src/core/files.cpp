// cambium — output files that appear whole or not at all.
#include "core/files.h"

#include "core/error.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
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

std::string fileFormat(const std::string& path, const std::vector<std::string>& allowed, const char* kind)
{
    const size_t dot = path.rfind('.'), slash = path.rfind('/');
    std::string ext = dot == std::string::npos || (slash != std::string::npos && dot < slash) ? "" : path.substr(dot + 1);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
    if (std::find(allowed.begin(), allowed.end(), ext) != allowed.end())
        return ext;
    std::string list;
    for (size_t i = 0; i < allowed.size(); ++i)
        list += (i == 0 ? "." : (i + 1 == allowed.size() ? " or ." : ", .")) + allowed[i];
    throw InputError(fmt::format("{}: unknown {} format '.{}' (use {})", path, kind, ext, list));
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
