// cambium — the JSON input parser.
#include "core/json.h"

#include "core/error.h"

#include <fmt/format.h>

#include <algorithm>
#include <set>
#include <vector>

namespace cambium {

namespace {

using json = nlohmann::json;

/// Where the parser is: one frame per open object or array, so that a
/// problem is named by its JSON path (root.children[1].radius).
class JsonPath {
public:
    explicit JsonPath(const std::string& source) : source_(source) {}

    bool operator()(int /*depth*/, json::parse_event_t event, json& parsed)
    {
        switch (event) {
        case json::parse_event_t::object_start:
        case json::parse_event_t::array_start:
            if (frames_.size() >= size_t(kMaxJsonDepth))
                fail(fmt::format("nested more than {} levels deep", kMaxJsonDepth));
            frames_.push_back({event == json::parse_event_t::array_start, 0, {}, {}});
            break;
        case json::parse_event_t::key: {
            Frame& f = frames_.back();
            f.key = parsed.get<std::string>();
            if (!f.keys.insert(f.key).second)
                fail(fmt::format("duplicate key '{}' (JSON keeps one of them silently: remove the other)", f.key),
                     false);
            break;
        }
        case json::parse_event_t::value:
            elementDone();
            break;
        case json::parse_event_t::object_end:
        case json::parse_event_t::array_end:
            frames_.pop_back();
            elementDone();
            break;
        }
        return true;
    }

private:
    struct Frame {
        bool array;
        size_t index;
        std::string key;
        std::set<std::string> keys;
    };

    void elementDone()
    {
        if (!frames_.empty() && frames_.back().array)
            ++frames_.back().index;
    }

    /// Throws naming the JSON path of the current element (without the
    /// innermost key when `withLast` is false: the message names that key).
    [[noreturn]] void fail(const std::string& what, bool withLast = true) const
    {
        std::string path;
        for (size_t i = 0; i < frames_.size(); ++i) {
            const Frame& f = frames_[i];
            if (i + 1 == frames_.size() && !withLast)
                break;
            if (f.array)
                path += fmt::format("[{}]", f.index);
            else if (!f.key.empty())
                path += (path.empty() ? "" : ".") + f.key;
        }
        if (path.size() > 160)  // deep nesting: its beginning and its end
            path = path.substr(0, 70) + " ... " + path.substr(path.size() - 70);
        throw InputError(fmt::format("{}: {}{}", source_, path.empty() ? "" : path + ": ", what));
    }

    std::string source_;
    std::vector<Frame> frames_;
};

}  // namespace

json parseJson(const std::string& text, const std::string& source)
{
    JsonPath path(source);
    try {
        return json::parse(text, std::ref(path), /*allow_exceptions=*/true, /*ignore_comments=*/true);
    } catch (const json::exception& e) {
        // e.what() reads "[json.exception.parse_error.101] parse error at line L, column C: ..."
        std::string what = e.what();
        const auto bracket = what.find("] ");
        if (bracket != std::string::npos)
            what = what.substr(bracket + 2);
        // A number too large for a double ("number overflow parsing '1e999'")
        // comes without a position: find the literal in the text.
        const auto q0 = what.find('\''), q1 = q0 == std::string::npos ? q0 : what.find('\'', q0 + 1);
        if (what.find(" at line ") == std::string::npos && q1 != std::string::npos) {
            const auto at = text.find(what.substr(q0 + 1, q1 - q0 - 1));
            if (at != std::string::npos) {
                const size_t line = size_t(std::count(text.begin(), text.begin() + long(at), '\n')) + 1;
                const auto lineStart = text.rfind('\n', at);
                const size_t column = at - (lineStart == std::string::npos ? 0 : lineStart + 1) + 1;
                what += fmt::format(" at line {}, column {}", line, column);
            }
        }
        throw InputError(fmt::format("{}: JSON syntax error: {}", source, what));
    }
}

}  // namespace cambium
