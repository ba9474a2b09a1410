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
    for (size_t i = 0; i < text.size(); ++i) {
        const auto u = static_cast<unsigned char>(text[i]);
        // Unicode's bidirectional controls (U+202A-202E, U+2066-2069, in
        // UTF-8 E2 80 AA-AE and E2 81 A6-A9) turn the rest of a terminal's
        // line around: written as \u{...} too.
        if (u == 0xE2 && i + 2 < text.size()) {
            const auto b = static_cast<unsigned char>(text[i + 1]),
                       c = static_cast<unsigned char>(text[i + 2]);
            if ((b == 0x80 && c >= 0xAA && c <= 0xAE) || (b == 0x81 && c >= 0xA6 && c <= 0xA9)) {
                out += fmt::format("\\u{{{:04x}}}", 0x2000 + ((b & 0x3F) << 6) + (c & 0x3F));
                i += 2;
                continue;
            }
        }
        out += u < 0x20 || u == 0x7f ? fmt::format("\\x{:02x}", u) : std::string(1, text[i]);
    }
    return out;
}

std::string shortened(const std::string& text, size_t most)
{
    if (text.size() <= most)
        return text;
    // (whole UTF-8 characters: a cut does not split one)
    auto back = [&](size_t i) {
        while (i > 0 && (static_cast<unsigned char>(text[i]) & 0xC0) == 0x80)
            --i;
        return i;
    };
    const size_t head = back(most * 2 / 3), tail = back(text.size() - most / 3);
    return fmt::format("{} ... ({} characters left out) ... {}", text.substr(0, head), tail - head,
                       text.substr(tail));
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
