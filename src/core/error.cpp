// cambium — errors and input helpers.
#include "core/error.h"

#include "core/math.h"

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
    auto byte = [&](size_t i) { return static_cast<unsigned char>(text[i]); };
    for (size_t i = 0; i < text.size();) {
        const unsigned u = byte(i);
        if (u < 0x80) {
            out += u < 0x20 || u == 0x7f ? fmt::format("\\x{:02x}", u) : std::string(1, text[i]);
            ++i;
            continue;
        }
        // One UTF-8 sequence, decoded strictly (no overlong forms, no
        // surrogates, nothing past U+10FFFF); a byte that starts none is
        // written as \x.., so a terminal never sees a broken sequence.
        const size_t n = u >= 0xC2 && u <= 0xDF   ? 2
                         : u >= 0xE0 && u <= 0xEF ? 3
                         : u >= 0xF0 && u <= 0xF4 ? 4
                                                  : 0;
        uint32_t cp = n == 2 ? u & 0x1F : n == 3 ? u & 0x0F : u & 0x07;
        bool valid = n != 0 && i + n <= text.size();
        for (size_t k = 1; valid && k < n; ++k) {
            valid = (byte(i + k) & 0xC0) == 0x80;
            cp = (cp << 6) | (byte(i + k) & 0x3F);
        }
        valid = valid && !(n == 3 && cp < 0x800) && !(n == 4 && (cp < 0x10000 || cp > 0x10FFFF)) &&
                !(cp >= 0xD800 && cp <= 0xDFFF);
        if (!valid) {
            out += fmt::format("\\x{:02x}", u);
            ++i;
            continue;
        }
        // C1 controls and Unicode's bidirectional controls (U+202A-202E,
        // U+2066-2069, which turn the rest of a terminal's line around)
        // are written as \u{...}.
        if (cp < 0xA0 || (cp >= 0x202A && cp <= 0x202E) || (cp >= 0x2066 && cp <= 0x2069))
            out += fmt::format("\\u{{{:04x}}}", cp);
        else
            out += text.substr(i, n);
        i += n;
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
    // (the marker within `most` too: a message of 1000 bytes at most)
    const size_t marker = fmt::format(" ... ({} characters left out) ... ", text.size()).size();
    const size_t room = most > marker ? most - marker : 0;
    const size_t head = back(room * 2 / 3), tail = back(text.size() - room / 3);
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
    // A UTF-8 byte-order mark, as some editors write, is read past (an
    // L-system's first line was "unknown", a skeleton's id no number).
    if (text.rfind("\xEF\xBB\xBF", 0) == 0)
        text.erase(0, 3);
    return text;
}

void checkVoxelsFromOrigin(double far, double h, const std::string& what)
{
    if (!(far / h < kMaxVoxelsFromOrigin))
        throw InputError(
            fmt::format("{} reaches {:.4g} from the origin, {:.3g} voxels of {:g}: "
                        "beyond {:.0f} voxels, {}",
                        what, far, far / h, h, kMaxVoxelsFromOrigin, kFloatPrecisionReason));
}

std::string numberText(double v)
{
    return std::isnan(v) ? std::string("not a number") : fmt::format("{:g}", v);
}

}  // namespace cambium
