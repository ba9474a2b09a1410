// cambium — errors and input helpers.
#include "core/error.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sys/stat.h>

namespace cambium {

size_t optionChoice(const std::string& value, const std::vector<std::string>& names,
                    const char* option)
{
    for (size_t i = 0; i < names.size(); ++i)
        if (value == names[i])
            return i;
    std::string list;
    for (size_t i = 0; i < names.size(); ++i)
        list += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
    throw InputError(fmt::format("{} must be {} (got '{}')", option, list, value));
}

std::string InputError::withoutNul(const std::string& text)
{
    if (text.find('\0') == std::string::npos)
        return text;
    std::string out;
    for (const char c : text)
        out += c == '\0' ? std::string("\\x00") : std::string(1, c);
    return out;
}

std::string printable(const std::string& text)
{
    std::string out;
    out.reserve(text.size());
    for (const char c : text) {
        const auto u = static_cast<unsigned char>(c);
        out += u < 0x20 || u == 0x7f ? fmt::format("\\x{:02x}", u) : std::string(1, c);
    }
    return out;
}

uint64_t checkInputFile(const std::string& path, const char* what)
{
    struct stat st;
    if (path.empty())
        throw InputError(fmt::format("the {} path is empty", what));
    if (::stat(path.c_str(), &st) != 0)
        throw InputError(
            fmt::format("{}: cannot read the {}: {}", path, what, std::strerror(errno)));
    if (S_ISDIR(st.st_mode))
        throw InputError(fmt::format("{}: is a directory, not a {}", path, what));
    if (!S_ISREG(st.st_mode))
        throw InputError(fmt::format("{}: is a device, FIFO or socket, not a {}", path, what));
    return uint64_t(st.st_size);
}

std::string readTextFile(const std::string& path, const char* what)
{
    const uint64_t size = checkInputFile(path, what);
    if (size > kMaxTextFileBytes)
        throw InputError(fmt::format("{}: {:.3g} GB is more than a {} can be (at most {} GB)", path,
                                     double(size) / 1e9, what, kMaxTextFileBytes >> 30));
    std::ifstream in(path, std::ios::binary);
    if (!in)
        throw InputError(
            fmt::format("{}: cannot read the {}: {}", path, what, std::strerror(errno)));
    std::string text(size, '\0');
    in.read(text.data(), std::streamsize(size));
    text.resize(size_t(in.gcount()));
    if (text.find('\0') != std::string::npos) {
        if (text.size() >= 4 && std::memcmp(text.data(), "\x20\x42\x44\x56", 4) == 0)
            throw InputError(fmt::format(
                "{}: is a .vdb file (a baked level set), not a {}: mesh or render it", path, what));
        throw InputError(fmt::format("{}: a binary file, not a {} (a text file)", path, what));
    }
    return text;
}

}  // namespace cambium
