// cambium — reading JSON input files: one parser for scenes and growth
// parameter files that names syntax errors by line and column, refuses
// duplicate keys and caps the nesting depth, and one set of checks of the
// parsed values that names each problem by its JSON path.
#pragma once

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace cambium {

/// Deeper nesting than this is refused (a scene node takes two levels: the
/// object and its "children" array).
constexpr int kMaxJsonDepth = 512;

/// Parses `text` (comments allowed) read from `source`.  InputError
/// "SOURCE: JSON syntax error: ... at line L, column C", "SOURCE: PATH: duplicate
/// key 'K' (JSON keeps one of them silently: remove the other)" or
/// "SOURCE: PATH: nested more than N levels deep".
nlohmann::json parseJson(const std::string& text, const std::string& source);

/// Where in `text` (JSON that parseJson reads, comments allowed) the value
/// at `keys` lies: the object member keys[0], in it keys[1], ...; [begin,
/// end) of its text, or none when a key is not there.  For edits that keep
/// the rest of a file as its author wrote it.
std::optional<std::pair<size_t, size_t>> jsonValueSpan(const std::string& text,
                                                       const std::vector<std::string>& keys);

/// What a JSON value is, for messages: "null", "a boolean", "a string",
/// "an array", "an object" or "a number".
const char* jsonKind(const nlohmann::json& j);

/// " (did you mean 'K'?)" when a word of `known` is fewer than three edits
/// from `word` (the first of the closest), else "".
std::string didYouMean(const std::string& word, const std::vector<std::string>& known);

/// The words separated by ", ".
std::string joinWords(const std::vector<std::string>& words);

/// The JSON path of member `key` of the value at `path`: "PATH.KEY", or "KEY"
/// when `path` is empty (the top level).
std::string jsonPath(const std::string& path, const std::string& key);

/// The checks of a parsed JSON document that its reader shares with the
/// other readers (scenes, growth parameters), so that every reader words a
/// problem alike: InputError "SOURCE: PATH: PROBLEM".  A reader derives from
/// it (or holds one) and adds the checks of its own format.
class JsonValidator {
public:
    explicit JsonValidator(std::string source) : source_(std::move(source)) {}

    /// The file (or other source) named in the messages.
    const std::string& source() const { return source_; }

    /// Throws InputError "SOURCE: PATH: WHAT".
    [[noreturn]] void fail(const std::string& path, const std::string& what) const;

    /// Refuses the first key of `obj` (in key order) that is not `allowed`:
    /// "PATH.KEY: unknown NOUN (did you mean 'K'?)" followed by
    /// "; allowed here: A, B, ..." or, when `listedIn` is given (a document
    /// listing them, for long lists), " (LISTEDIN lists them)".  The
    /// suggestion is there only when an allowed key is close.
    void checkKeys(const nlohmann::json& obj, const std::string& path,
                   const std::vector<std::string>& allowed, const char* noun = "field",
                   const char* listedIn = nullptr) const;

    /// Member `key` of `obj`; "PATH.KEY: missing" (or "missing: WHY") without it.
    const nlohmann::json& required(const nlohmann::json& obj, const std::string& key,
                                   const std::string& path, const char* why = nullptr) const;

    /// `j` when it is an object, else "PATH: WHAT (got KIND)".
    const nlohmann::json& object(const nlohmann::json& j, const std::string& path,
                                 const char* what) const;

    /// `j` when it is an array of `size` values, else "PATH: WHAT (got KIND)"
    /// (for an array, "an array of N").
    const nlohmann::json& array(const nlohmann::json& j, const std::string& path, size_t size,
                                const char* what) const;

    /// `j` as a number: "must be a number (got KIND)", "must be a finite number".
    double number(const nlohmann::json& j, const std::string& path) const;

    /// `j` as a number in [lo, hi]: also "must be between LO and HI (got X)".
    double number(const nlohmann::json& j, const std::string& path, double lo, double hi) const;

    /// Member `key` of `obj` as a number (number(), path "PATH.KEY"), nothing
    /// when it is absent.
    std::optional<double> optNumber(const nlohmann::json& obj, const std::string& key,
                                    const std::string& path) const;

    /// Member `key` of `obj` as a number; "PATH.KEY: missing" without it.
    double reqNumber(const nlohmann::json& obj, const std::string& key,
                     const std::string& path) const;

    /// `j` as a string: "must be a string (got KIND)".
    std::string string(const nlohmann::json& j, const std::string& path) const;

    /// `j` as a boolean: "must be true or false (got KIND)".
    bool boolean(const nlohmann::json& j, const std::string& path) const;

    /// The index in `names` of the string `j`: "must be \"A\" or \"B\" (got
    /// 'X')" (for more names, "one of ...") otherwise.
    size_t choice(const nlohmann::json& j, const std::string& path,
                  const std::vector<std::string>& names) const;

    /// The file named by the string `j` ("must name a file" when empty),
    /// relative to `directory` (that of the document) unless absolute or
    /// `directory` is empty, checked readable (checkInputFile, its message
    /// after "PATH: ").
    std::string inputFile(const nlohmann::json& j, const std::string& path,
                          const std::string& directory, const char* what) const;

private:
    std::string source_;
};

}  // namespace cambium
