// cambium — the JSON input parser.
#include "core/json.h"

#include "core/error.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <cmath>
#include <filesystem>
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

    void start(bool array)
    {
        if (frames_.size() >= size_t(kMaxJsonDepth))
            fail(fmt::format("nested more than {} levels deep", kMaxJsonDepth));
        frames_.push_back({array, 0, {}, {}});
    }
    void key(const std::string& k)
    {
        Frame& f = frames_.back();
        f.key = k;
        if (!f.keys.insert(f.key).second)
            fail(fmt::format("duplicate key '{}' (JSON keeps one of them silently: remove "
                             "the other)",
                             f.key),
                 false);
    }
    void value() { elementDone(); }
    void end()
    {
        frames_.pop_back();
        elementDone();
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

/// The parser's SAX events into nlohmann's own DOM builder, the path kept
/// beside it.  (nlohmann's callback parser, which this replaces, scans the
/// whole parent at every object's end for values a callback discarded: a
/// blend of 100,000 children took 3 s to read, 400,000 over a minute.)
class CheckedDom {
public:
    CheckedDom(json& result, JsonPath& path) : dom_(result, true), path_(path) {}
    bool null() { return path_.value(), dom_.null(); }
    bool boolean(bool v) { return path_.value(), dom_.boolean(v); }
    bool number_integer(json::number_integer_t v) { return path_.value(), dom_.number_integer(v); }
    bool number_unsigned(json::number_unsigned_t v)
    {
        return path_.value(), dom_.number_unsigned(v);
    }
    bool number_float(json::number_float_t v, const std::string& s)
    {
        return path_.value(), dom_.number_float(v, s);
    }
    bool string(json::string_t& v) { return path_.value(), dom_.string(v); }
    bool binary(json::binary_t& v) { return path_.value(), dom_.binary(v); }
    bool start_object(std::size_t n) { return path_.start(false), dom_.start_object(n); }
    bool key(json::string_t& k) { return path_.key(k), dom_.key(k); }
    bool end_object() { return path_.end(), dom_.end_object(); }
    bool start_array(std::size_t n) { return path_.start(true), dom_.start_array(n); }
    bool end_array() { return path_.end(), dom_.end_array(); }
    bool parse_error(std::size_t at, const std::string& token, const nlohmann::detail::exception& e)
    {
        return dom_.parse_error(at, token, e);  // (throws: exceptions allowed)
    }

private:
    nlohmann::detail::json_sax_dom_parser<json> dom_;
    JsonPath& path_;
};

}  // namespace

json parseJson(const std::string& text, const std::string& source)
{
    JsonPath path(source);
    try {
        json result;
        CheckedDom sax(result, path);
        json::sax_parse(text, &sax, nlohmann::detail::input_format_t::json, /*strict=*/true,
                        /*ignore_comments=*/true);
        return result;
    } catch (const json::exception& e) {
        // e.what() reads "[json.exception.parse_error.101] parse error at line L, column C: ..."
        std::string what = e.what();
        const auto bracket = what.find("] ");
        if (bracket != std::string::npos)
            what = what.substr(bracket + 2);
        // A number too large for a double ("number overflow parsing '1e999'")
        // comes without a position: find the literal in the text.
        const auto q0 = what.find('\''),
                   q1 = q0 == std::string::npos ? q0 : what.find('\'', q0 + 1);
        if (what.find(" at line ") == std::string::npos && q1 != std::string::npos) {
            const auto at = text.find(what.substr(q0 + 1, q1 - q0 - 1));
            if (at != std::string::npos) {
                const size_t line =
                    size_t(std::count(text.begin(), text.begin() + long(at), '\n')) + 1;
                const auto lineStart = text.rfind('\n', at);
                const size_t column = at - (lineStart == std::string::npos ? 0 : lineStart + 1) + 1;
                what += fmt::format(" at line {}, column {}", line, column);
            }
        }
        throw InputError(fmt::format("{}: JSON syntax error: {}", source, what));
    }
}

namespace {

/// Steps over JSON text (known to parse) by position.
struct JsonScanner {
    const std::string& t;
    size_t i = 0;

    bool at(const char* s) const { return t.compare(i, std::strlen(s), s) == 0; }
    void space()
    {
        for (;;) {
            while (i < t.size() && std::isspace(static_cast<unsigned char>(t[i])))
                ++i;
            if (at("//")) {
                i = t.find('\n', i);
                i = i == std::string::npos ? t.size() : i;
            } else if (at("/*")) {
                i = t.find("*/", i + 2);
                i = i == std::string::npos ? t.size() : i + 2;
            } else {
                return;
            }
        }
    }
    /// A string: its raw text between the quotes.
    std::string string()
    {
        const size_t begin = ++i;
        while (i < t.size() && t[i] != '"')
            i += t[i] == '\\' ? 2 : 1;
        return t.substr(begin, i++ - begin);
    }
    /// Steps over a value (after space()).
    void value()
    {
        if (i >= t.size())
            return;
        const char c = t[i];
        if (c == '"') {
            string();
        } else if (c == '{' || c == '[') {
            const char close = c == '{' ? '}' : ']';
            ++i;
            for (space(); i < t.size() && t[i] != close; space()) {
                if (t[i] == ',') {
                    ++i;
                    continue;
                }
                value();
                space();
                if (c == '{' && i < t.size() && t[i] == ':') {  // (a key, then its value)
                    ++i;
                    space();
                    value();
                }
            }
            ++i;
        } else {
            while (i < t.size() && !std::isspace(static_cast<unsigned char>(t[i])) &&
                   !std::strchr(",]}", t[i]) && !at("//") && !at("/*"))
                ++i;
        }
    }
};

}  // namespace

namespace {

/// A key's text between its quotes as the parser reads it: escapes decoded
/// ("G\u0068" is the key Gh).
std::string decodedKey(const std::string& raw)
{
    if (raw.find('\\') == std::string::npos)
        return raw;
    const json j = json::parse("\"" + raw + "\"", nullptr, /*allow_exceptions=*/false);
    return j.is_string() ? j.get<std::string>() : raw;
}

}  // namespace

std::optional<std::pair<size_t, size_t>> jsonValueSpan(const std::string& text,
                                                       const std::vector<std::string>& keys)
{
    JsonScanner s{text};
    s.space();
    for (const std::string& key : keys) {
        if (s.i >= text.size() || text[s.i] != '{')
            return std::nullopt;
        ++s.i;
        bool found = false;
        for (s.space(); s.i < text.size() && text[s.i] != '}'; s.space()) {
            if (text[s.i] == ',') {
                ++s.i;
                continue;
            }
            const std::string name = decodedKey(s.string());
            s.space();
            ++s.i;  // ':'
            s.space();
            if (name == key) {
                found = true;
                break;
            }
            s.value();
        }
        if (!found)
            return std::nullopt;
    }
    const size_t begin = s.i;
    s.value();
    return std::pair{begin, s.i};
}

const char* jsonKind(const json& j)
{
    switch (j.type()) {
        case json::value_t::null:
            return "null";
        case json::value_t::boolean:
            return "a boolean";
        case json::value_t::string:
            return "a string";
        case json::value_t::array:
            return "an array";
        case json::value_t::object:
            return "an object";
        case json::value_t::number_integer:
        case json::value_t::number_unsigned:
        case json::value_t::number_float:
            return "a number";
        default:
            return "something else";
    }
}

namespace {

size_t editDistance(const std::string& a, const std::string& b)
{
    std::vector<size_t> row(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j)
        row[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
        size_t diag = row[0];
        row[0] = i;
        for (size_t j = 1; j <= b.size(); ++j) {
            const size_t up = row[j];
            row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] != b[j - 1])});
            diag = up;
        }
    }
    return row[b.size()];
}

}  // namespace

std::string didYouMean(const std::string& word, const std::vector<std::string>& known)
{
    std::string best;
    size_t bestDistance = 3;
    for (const auto& k : known) {
        const size_t d = editDistance(word, k);
        if (d < bestDistance) {
            bestDistance = d;
            best = k;
        }
    }
    return best.empty() ? std::string() : fmt::format(" (did you mean '{}'?)", best);
}

std::string joinWords(const std::vector<std::string>& words)
{
    std::string s;
    for (const auto& w : words)
        s += (s.empty() ? "" : ", ") + w;
    return s;
}

std::string jsonPath(const std::string& path, const std::string& key)
{
    return path.empty() ? key : path + "." + key;
}

void JsonValidator::fail(const std::string& path, const std::string& what) const
{
    // (the document itself has no path: "plan.json: : a farm plan")
    if (path.empty())
        throw InputError(fmt::format("{}: {}", source_, what));
    throw InputError(fmt::format("{}: {}: {}", source_, path, what));
}

void JsonValidator::checkKeys(const json& obj, const std::string& path,
                              const std::vector<std::string>& allowed, const char* noun,
                              const char* listedIn) const
{
    for (auto it = obj.begin(); it != obj.end(); ++it) {
        const std::string& key = it.key();
        if (std::find(allowed.begin(), allowed.end(), key) != allowed.end())
            continue;
        // A long list is better left to the format's document than spelled out.
        const std::string where = listedIn ? fmt::format(" ({} lists them)", listedIn)
                                           : fmt::format("; allowed here: {}", joinWords(allowed));
        fail(jsonPath(path, key),
             fmt::format("unknown {}{}{}", noun, didYouMean(key, allowed), where));
    }
}

const json& JsonValidator::required(const json& obj, const std::string& key,
                                    const std::string& path, const char* why) const
{
    if (!obj.contains(key))
        fail(jsonPath(path, key), why ? fmt::format("missing: {}", why) : std::string("missing"));
    return obj[key];
}

const json& JsonValidator::object(const json& j, const std::string& path, const char* what) const
{
    if (!j.is_object())
        fail(path, fmt::format("{} (got {})", what, jsonKind(j)));
    return j;
}

const json& JsonValidator::array(const json& j, const std::string& path, size_t size,
                                 const char* what) const
{
    if (!j.is_array() || j.size() != size)
        fail(path, fmt::format("{} (got {}{})", what, jsonKind(j),
                               j.is_array() ? fmt::format(" of {}", j.size()) : ""));
    return j;
}

double JsonValidator::number(const json& j, const std::string& path) const
{
    if (!j.is_number())
        fail(path, fmt::format("must be a number (got {})", jsonKind(j)));
    const double v = j.get<double>();
    if (!std::isfinite(v))
        fail(path, "must be a finite number");
    return v;
}

double JsonValidator::number(const json& j, const std::string& path, double lo, double hi) const
{
    const double v = number(j, path);
    if (!(v >= lo && v <= hi))
        fail(path, fmt::format("must be between {} and {} (got {})", lo, hi, v));
    return v;
}

std::optional<double> JsonValidator::optNumber(const json& obj, const std::string& key,
                                               const std::string& path) const
{
    if (!obj.contains(key))
        return std::nullopt;
    return number(obj[key], jsonPath(path, key));
}

double JsonValidator::reqNumber(const json& obj, const std::string& key,
                                const std::string& path) const
{
    return number(required(obj, key, path), jsonPath(path, key));
}

std::string JsonValidator::string(const json& j, const std::string& path) const
{
    if (!j.is_string())
        fail(path, fmt::format("must be a string (got {})", jsonKind(j)));
    return j.get<std::string>();
}

size_t JsonValidator::choice(const json& j, const std::string& path,
                             const std::vector<std::string>& names) const
{
    const std::string s = string(j, path);
    const auto it = std::find(names.begin(), names.end(), s);
    if (it != names.end())
        return size_t(it - names.begin());
    std::vector<std::string> quoted;
    for (const std::string& n : names)
        quoted.push_back("\"" + n + "\"");
    const std::string list =
        names.size() == 2 ? quoted[0] + " or " + quoted[1] : "one of " + joinWords(quoted);
    fail(path, fmt::format("must be {} (got '{}')", list, s));
}

std::string JsonValidator::inputFile(const json& j, const std::string& path,
                                     const std::string& directory, const char* what) const
{
    const std::string f = string(j, path);
    if (f.empty())
        fail(path, "must name a file");
    const std::filesystem::path fp(f);
    const std::string file = fp.is_absolute() || directory.empty()
                                 ? f
                                 : (std::filesystem::path(directory) / fp).string();
    try {
        checkInputFile(file, what);
    } catch (const InputError& e) {
        fail(path, e.what());
    }
    return file;
}

bool JsonValidator::boolean(const json& j, const std::string& path) const
{
    if (!j.is_boolean())
        fail(path, fmt::format("must be true or false (got {})", jsonKind(j)));
    return j.get<bool>();
}

}  // namespace cambium
