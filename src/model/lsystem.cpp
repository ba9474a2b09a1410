// cambium — L-systems: reading, expressions, derivation.
#include "model/lsystem.h"

#include "core/error.h"
#include "core/random.h"
#include "core/math.h"
#include "core/system.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstring>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <sstream>

namespace cambium {

// --- expressions ------------------------------------------------------------

struct Expr {
    enum Op {
        Const,
        Var,
        Neg,
        Not,
        Add,
        Sub,
        Mul,
        Div,
        Pow,
        Lt,
        Le,
        Gt,
        Ge,
        Eq,
        Ne,
        And,
        Or,
        Call
    } op = Const;
    double value = 0.0;
    int var = -1;   ///< Var: the formal parameter's index; Call: the function's in kFunctions
    int depth = 1;  ///< levels of nodes from this one down (evaluate recurses as deep)
    std::vector<std::shared_ptr<const Expr>> kids;
};

namespace {

using ExprPtr = std::shared_ptr<const Expr>;
using Rng = std::mt19937_64;

/// The functions expressions may call (trigonometry in degrees, as cpfg);
/// `ran` (no `f`) draws from the derivation's seeded generator.
struct Function {
    const char* name;
    int arity;
    double (*f)(double, double);
};
const Function kFunctions[] = {
    {"sin", 1, [](double a, double) { return std::sin(a * kDegree); }},
    {"cos", 1, [](double a, double) { return std::cos(a * kDegree); }},
    {"tan", 1, [](double a, double) { return std::tan(a * kDegree); }},
    {"asin", 1, [](double a, double) { return std::asin(a) / kDegree; }},
    {"acos", 1, [](double a, double) { return std::acos(a) / kDegree; }},
    {"atan", 1, [](double a, double) { return std::atan(a) / kDegree; }},
    {"atan2", 2, [](double a, double b) { return std::atan2(a, b) / kDegree; }},
    {"sqrt", 1, [](double a, double) { return std::sqrt(a); }},
    {"exp", 1, [](double a, double) { return std::exp(a); }},
    {"log", 1, [](double a, double) { return std::log(a); }},
    {"abs", 1, [](double a, double) { return std::abs(a); }},
    {"floor", 1, [](double a, double) { return std::floor(a); }},
    {"ceil", 1, [](double a, double) { return std::ceil(a); }},
    {"trunc", 1, [](double a, double) { return std::trunc(a); }},
    {"min", 2, [](double a, double b) { return std::min(a, b); }},
    {"max", 2, [](double a, double b) { return std::max(a, b); }},
    {"pow", 2, [](double a, double b) { return std::pow(a, b); }},
    {"ran", 1, nullptr},  // uniform in [0, x)
};

double evaluate(const Expr& e, const std::vector<double>& vars, Rng& rng)
{
    auto k = [&](size_t i) { return evaluate(*e.kids[i], vars, rng); };
    switch (e.op) {
        case Expr::Const:
            return e.value;
        case Expr::Var:
            return vars[size_t(e.var)];
        case Expr::Neg:
            return -k(0);
        case Expr::Not:
            return k(0) == 0.0 ? 1.0 : 0.0;
        case Expr::Add:
            return k(0) + k(1);
        case Expr::Sub:
            return k(0) - k(1);
        case Expr::Mul:
            return k(0) * k(1);
        case Expr::Div:
            return k(0) / k(1);
        case Expr::Pow:
            return std::pow(k(0), k(1));
        case Expr::Lt:
            return k(0) < k(1);
        case Expr::Le:
            return k(0) <= k(1);
        case Expr::Gt:
            return k(0) > k(1);
        case Expr::Ge:
            return k(0) >= k(1);
        case Expr::Eq:
            return k(0) == k(1);
        case Expr::Ne:
            return k(0) != k(1);
        case Expr::And:
            return k(0) != 0.0 && k(1) != 0.0;
        case Expr::Or:
            return k(0) != 0.0 || k(1) != 0.0;
        case Expr::Call:
            break;
    }
    const Function& f = kFunctions[e.var];
    if (!f.f) {
        const double u = uniformCanonical(rng);  // drawn before the argument's own draws
        return u * k(0);
    }
    return f.f(k(0), f.arity == 2 ? k(1) : 0.0);
}

/// Where a piece of text came from: messages say file:line:column.
struct Place {
    const std::string* source;
    int line;
    int column;  ///< of the piece's first character, 1-based
    /// The place `offset` characters further on the line.
    Place shifted(size_t offset) const { return {source, line, column + int(offset)}; }
};

[[noreturn]] void fail(const Place& at, size_t offset, const std::string& what)
{
    throw InputError(
        fmt::format("{}:{}:{}: {}", *at.source, at.line, at.column + int(offset), what));
}

/// How deep an expression may nest: parentheses, unary operators and
/// powers (the parser recurses through them), and the tree it builds (a
/// sum of many terms is a chain as deep as its terms; evaluation and its
/// destruction recurse through it).  Far beyond a hand-written expression,
/// far within a thread's stack.
constexpr int kMaxExpressionDepth = 200;

/// Recursive descent over one expression (C-like precedence, ^ for power).
class ExprParser {
public:
    ExprParser(const std::string& text, const Place& at, const std::vector<std::string>& formals,
               const std::map<std::string, double>& defines)
        : s_(text), at_(at), formals_(formals), defines_(defines)
    {
    }

    ExprPtr parseAll()
    {
        ExprPtr e = orExpr();
        skip();
        if (pos_ < s_.size())
            fail(at_, pos_, fmt::format("unexpected '{}' in the expression '{}'", s_[pos_], s_));
        return e;
    }

private:
    void skip()
    {
        while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_])))
            ++pos_;
    }
    bool eat(const char* tok)
    {
        skip();
        const size_t n = std::strlen(tok);
        if (s_.compare(pos_, n, tok) == 0) {
            // '<' must not take the first character of "<=", and so on.
            if (n == 1 && pos_ + 1 < s_.size() && s_[pos_ + 1] == '=' &&
                std::strchr("<>=!", tok[0]))
                return false;
            pos_ += n;
            return true;
        }
        return false;
    }
    ExprPtr node(Expr::Op op, std::vector<ExprPtr> kids) const
    {
        auto e = std::make_shared<Expr>();
        e->op = op;
        e->kids = std::move(kids);
        return deepest(std::move(e));
    }
    /// `e` with its depth, or the error when it is too deep.
    ExprPtr deepest(std::shared_ptr<Expr> e) const
    {
        for (const ExprPtr& k : e->kids)
            e->depth = std::max(e->depth, k->depth + 1);
        if (e->depth > kMaxExpressionDepth)
            tooDeep();
        return e;
    }
    [[noreturn]] void tooDeep() const
    {
        fail(at_, std::min(pos_, s_.size()),
             fmt::format("the expression nests deeper than {} levels (operators, parentheses "
                         "or terms of one sum)",
                         kMaxExpressionDepth));
    }
    /// One level of the parser's recursion, counted.
    struct Nested {
        explicit Nested(ExprParser& p) : parser(p)
        {
            if (++parser.nesting_ > kMaxExpressionDepth)
                parser.tooDeep();
        }
        ~Nested() { --parser.nesting_; }
        Nested(const Nested&) = delete;
        Nested& operator=(const Nested&) = delete;
        ExprParser& parser;
    };
    static ExprPtr constant(double v)
    {
        auto e = std::make_shared<Expr>();
        e->value = v;
        return e;
    }
    /// Left-associative binary operators by precedence, loosest first (a
    /// two-character token before its one-character prefix).
    struct Binary {
        const char* token;
        Expr::Op op;
    };
    static constexpr int kLevels = 6;
    static const std::vector<Binary>& level(int i)
    {
        static const std::vector<Binary> levels[kLevels] = {
            {{"||", Expr::Or}},
            {{"&&", Expr::And}},
            {{"==", Expr::Eq}, {"!=", Expr::Ne}},
            {{"<=", Expr::Le}, {">=", Expr::Ge}, {"<", Expr::Lt}, {">", Expr::Gt}},
            {{"+", Expr::Add}, {"-", Expr::Sub}},
            {{"*", Expr::Mul}, {"/", Expr::Div}}};
        return levels[i];
    }
    ExprPtr binary(int i)
    {
        if (i == kLevels)
            return unary();
        ExprPtr l = binary(i + 1);
        for (;;) {
            const auto& ops = level(i);
            const auto it =
                std::find_if(ops.begin(), ops.end(), [&](const Binary& b) { return eat(b.token); });
            if (it == ops.end())
                return l;
            l = node(it->op, {l, binary(i + 1)});
        }
    }
    ExprPtr orExpr()
    {
        const Nested level(*this);
        return binary(0);
    }
    ExprPtr unary()
    {
        const Nested level(*this);
        if (eat("-"))
            return node(Expr::Neg, {unary()});
        if (eat("+"))
            return unary();
        if (eat("!"))
            return node(Expr::Not, {unary()});
        return power();
    }
    ExprPtr power()
    {
        ExprPtr base = primary();
        if (eat("^"))
            return node(Expr::Pow, {base, unary()});  // right-associative
        return base;
    }
    ExprPtr primary()
    {
        skip();
        if (pos_ >= s_.size())
            fail(at_, pos_, fmt::format("the expression '{}' ends too soon", s_));
        const char c = s_[pos_];
        if (eat("(")) {
            ExprPtr e = orExpr();
            if (!eat(")"))
                fail(at_, pos_, fmt::format("missing ')' in '{}'", s_));
            return e;
        }
        if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') {
            char* end = nullptr;
            const double v = std::strtod(s_.c_str() + pos_, &end);
            if (end == s_.c_str() + pos_ || writtenInHex(s_.c_str() + pos_, end))
                fail(at_, pos_,
                     fmt::format("bad number in '{}' (numbers are decimal: 16, 1.5, 2e-3)", s_));
            pos_ = size_t(end - s_.c_str());
            return constant(v);
        }
        if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
            const size_t start = pos_;
            while (pos_ < s_.size() &&
                   (std::isalnum(static_cast<unsigned char>(s_[pos_])) || s_[pos_] == '_'))
                ++pos_;
            const std::string name = s_.substr(start, pos_ - start);
            if (eat("(")) {
                const auto f = std::find_if(std::begin(kFunctions), std::end(kFunctions),
                                            [&](const Function& g) { return name == g.name; });
                if (f == std::end(kFunctions))
                    fail(at_, start, fmt::format("unknown function '{}'", name));
                const int arity = f->arity;
                auto e = std::make_shared<Expr>();
                e->op = Expr::Call;
                e->var = int(f - std::begin(kFunctions));
                if (!eat(")")) {
                    do
                        e->kids.push_back(orExpr());
                    while (eat(","));
                    if (!eat(")"))
                        fail(at_, pos_, fmt::format("missing ')' after the arguments of {}", name));
                }
                if (int(e->kids.size()) != arity)
                    fail(at_, start,
                         fmt::format("{} takes {} argument{} (got {})", name, arity,
                                     arity == 1 ? "" : "s", e->kids.size()));
                return deepest(std::move(e));
            }
            for (size_t i = 0; i < formals_.size(); ++i)
                if (formals_[i] == name) {
                    auto e = std::make_shared<Expr>();
                    e->op = Expr::Var;
                    e->var = int(i);
                    return e;
                }
            if (const auto it = defines_.find(name); it != defines_.end())
                return constant(it->second);
            fail(at_, start,
                 fmt::format("'{}' is neither a parameter of the predecessor nor a #define", name));
        }
        fail(at_, pos_, fmt::format("unexpected '{}' in the expression '{}'", c, s_));
    }

    const std::string& s_;
    Place at_;
    const std::vector<std::string>& formals_;
    const std::map<std::string, double>& defines_;
    size_t pos_ = 0;
    int nesting_ = 0;
};

// --- module strings -----------------------------------------------------------

/// The symbols the turtle interprets (turtle.cpp), each with an optional single parameter.
bool isTurtleSymbol(char c)
{
    return c != 0 && std::strchr("FfGg+-&^\\/|$![]%#';{}.", c) != nullptr;
}

/// Splits `text` at top-level commas (outside parentheses).
std::vector<std::pair<std::string, size_t>> splitArgs(const std::string& text, size_t offset)
{
    std::vector<std::pair<std::string, size_t>> out;
    int depth = 0;
    size_t start = 0;
    for (size_t i = 0; i <= text.size(); ++i) {
        if (i == text.size() || (text[i] == ',' && depth == 0)) {
            out.emplace_back(text.substr(start, i - start), offset + start);
            start = i + 1;
        } else if (text[i] == '(')
            ++depth;
        else if (text[i] == ')')
            --depth;
    }
    return out;
}

/// A module string: each module a symbol, then optionally "(a, b, ...)".
/// `arg` turns one argument's text (and its offset in `text`) into whatever
/// the caller keeps.
template <class F>
void scanModules(const std::string& text, const Place& at, F&& module)
{
    size_t i = 0;
    int depth = 0;
    while (i < text.size()) {
        const char c = text[i];
        if (std::isspace(static_cast<unsigned char>(c))) {
            ++i;
            continue;
        }
        if (c == ',')
            fail(at, i,
                 "unexpected ',' (cpfg's colour-index decrement is not supported: set the index "
                 "with ;(n))");
        if (c == '(' || c == ')')
            fail(at, i, fmt::format("unexpected '{}'", c));
        if (c == '[')
            ++depth;
        if (c == ']' && --depth < 0)
            fail(at, i, "']' without a matching '['");
        const size_t symbol = i++;
        size_t j = i;
        while (j < text.size() && std::isspace(static_cast<unsigned char>(text[j])))
            ++j;
        std::vector<std::pair<std::string, size_t>> args;
        if (j < text.size() && text[j] == '(') {
            int d = 0;
            size_t k = j;
            for (; k < text.size(); ++k) {
                d += text[k] == '(';
                d -= text[k] == ')';
                if (d == 0)
                    break;
            }
            if (k == text.size())
                fail(at, j, "'(' without a matching ')'");
            const std::string inner = text.substr(j + 1, k - j - 1);
            if (inner.find_first_not_of(" \t") != std::string::npos)
                args = splitArgs(inner, j + 1);
            i = k + 1;
        }
        module(c, symbol, args);
    }
    if (depth != 0)
        fail(at, text.size(), fmt::format("{} '[' without a matching ']'", depth));
}

std::string trim(const std::string& s)
{
    const size_t a = s.find_first_not_of(" \t\r"), b = s.find_last_not_of(" \t\r");
    return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
}

/// Index of the first occurrence of `c` outside parentheses, or npos.
size_t findTopLevel(const std::string& s, char c, size_t from = 0)
{
    int depth = 0;
    for (size_t i = from; i < s.size(); ++i) {
        if (s[i] == '(')
            ++depth;
        else if (s[i] == ')')
            --depth;
        else if (s[i] == c && depth == 0)
            return i;
    }
    return std::string::npos;
}

class Reader {
public:
    explicit Reader(const std::string& source) { system_.source = source; }

    LSystem read(const std::string& text)
    {
        const std::string clean = stripComments(text, system_.source);
        std::istringstream in(clean);
        std::string line;
        int lineNo = 0;
        bool haveAxiom = false;
        while (std::getline(in, line)) {
            ++lineNo;
            const std::string t = trim(line);
            if (t.empty() || t.rfind("//", 0) == 0)
                continue;
            const int column = int(line.find_first_not_of(" \t")) + 1;
            const Place at{&system_.source, lineNo, column};
            if (t.rfind("#define", 0) == 0) {
                define(t, at);
                continue;
            }
            if (t.find("-->") != std::string::npos) {
                production(t, at);
                continue;
            }
            const size_t colon = t.find(':');
            std::string key = colon == std::string::npos ? t : trim(t.substr(0, colon));
            for (char& ch : key)
                ch = char(std::tolower(static_cast<unsigned char>(ch)));
            const std::string value = colon == std::string::npos ? "" : t.substr(colon + 1);
            const Place vat = at.shifted(colon + 1);
            if (key == "axiom") {
                system_.axiom = constantModules(value, vat);
                haveAxiom = true;
            } else if (key == "derivation length") {
                system_.derivationLength = int(number(value, vat, 0, kMaxSteps));
            } else if (key == "ignore") {
                for (char ch : value)
                    if (!std::isspace(static_cast<unsigned char>(ch)))
                        system_.ignore += ch;
            } else if (key == "angle") {
                system_.angle = number(value, vat, -360, 360);
            } else if (key == "step") {
                system_.step = number(value, vat, 0, 1e9);
            } else if (key == "width") {
                system_.width = number(value, vat, 0, 1e9);
            } else if (key == "width increment") {
                system_.widthIncrement = number(value, vat, 0, 1e9);
            } else if (key == "color" || key == "colour") {
                std::istringstream v(value);
                double index = -1.0;
                glm::dvec3 c;
                if (!(v >> index >> c.r >> c.g >> c.b) || !(index >= 0.0 && index <= 255.0) ||
                    std::trunc(index) != index ||
                    !(c.r >= 0.0 && c.r <= 1.0 && c.g >= 0.0 && c.g <= 1.0 && c.b >= 0.0 &&
                      c.b <= 1.0))
                    fail(vat, 0,
                         "color: expected an index from 0 to 255 and red, green, blue from 0 to 1");
                system_.colours[int(index)] = c;
            } else if (key == "seed") {
                const double seed = number(value, vat, 0, double(kMaxSeed));
                if (seed != std::floor(seed))
                    fail(vat, 0, fmt::format("seed: must be a whole number (got {})", seed));
                system_.seed = uint64_t(seed);
            } else if (key == "tropism") {
                std::istringstream v(value);
                for (double& x : system_.tropism)
                    if (!(v >> x) || !std::isfinite(x))
                        fail(vat, 0,
                             "tropism: expected four numbers, the direction (x y z) and the "
                             "strength e");
            } else if (key == "lsystem" || key == "endlsystem") {
                // cpfg structure lines: one L-system per file here; nothing to do.
            } else if (key == "homomorphism" || key == "endhomomorphism" ||
                       key == "decomposition" || key == "enddecomposition" || key == "consider" ||
                       key == "group" || key == "endgroup") {
                fail(at, 0,
                     fmt::format(
                         "cpfg's '{}' is not supported (docs/lsystem-format.md lists what is): its "
                         "productions would be read as ordinary ones",
                         key));
            } else {
                fail(
                    at, 0,
                    fmt::format(
                        "unknown line '{}' (expected #define, Axiom:, derivation length:, ignore:, "
                        "angle:, step:, width:, width increment:, color:, tropism:, seed: or a "
                        "production with -->)",
                        t));
            }
        }
        if (!haveAxiom)
            throw InputError(fmt::format("{}: no 'Axiom:' line", system_.source));
        return system_;
    }

private:
    static std::string stripComments(const std::string& text, const std::string& source)
    {
        std::string out;
        out.reserve(text.size());
        for (size_t i = 0; i < text.size(); ++i) {
            if (text.compare(i, 2, "/*") == 0) {
                const size_t end = text.find("*/", i + 2);
                if (end == std::string::npos) {  // (it would swallow the rest of the file)
                    const size_t lineStart = text.rfind('\n', i);
                    const int line =
                        1 + int(std::count(text.begin(), text.begin() + long(i), '\n'));
                    const size_t column = i - (lineStart == std::string::npos ? 0 : lineStart + 1);
                    fail(Place{&source, line, 1}, column,
                         "a comment '/*' that is never closed with '*/'");
                }
                for (size_t k = i; k < (end == std::string::npos ? text.size() : end + 2); ++k)
                    out += text[k] == '\n' ? '\n' : ' ';  // keep line and column numbers
                i = end == std::string::npos ? text.size() : end + 1;
            } else
                out += text[i];
        }
        return out;
    }

    /// The value of an expression of constants (numbers and #defines).
    double constant(const std::string& text, const Place& at) const
    {
        Rng rng(0);
        return evaluate(*ExprParser(text, at, {}, defines_).parseAll(), {}, rng);
    }

    double number(const std::string& text, const Place& at, double lo, double hi)
    {
        const double v = constant(text, at);
        if (!(v >= lo && v <= hi))
            fail(at, 0,
                 fmt::format("'{}' is {}: expected a number from {} to {}", trim(text), v, lo, hi));
        return v;
    }

    void define(const std::string& t, const Place& at)
    {
        std::istringstream s(t.substr(7));
        std::string name;
        s >> name;
        if (name.empty() || !(std::isalpha(static_cast<unsigned char>(name[0])) || name[0] == '_'))
            fail(at, 0, "#define needs a name and a value");
        std::string rest;
        std::getline(s, rest);
        defines_[name] = constant(rest, at.shifted(t.find(name, 7) + name.size()));
    }

    /// Checks that a module keeps its number of parameters across the file.
    void arity(char name, size_t count, const Place& at, size_t offset)
    {
        if (isTurtleSymbol(name)) {
            if (count > 1)
                fail(at, offset,
                     fmt::format("'{}' takes at most one parameter (got {})", name, count));
            return;
        }
        const auto [it, inserted] = arity_.emplace(name, std::make_pair(count, at.line));
        if (!inserted && it->second.first != count)
            fail(at, offset,
                 fmt::format("module {} has {} parameter{} here but {} at line {}", name, count,
                             count == 1 ? "" : "s", it->second.first, it->second.second));
    }

    ModuleString constantModules(const std::string& text, const Place& at)
    {
        ModuleString out;
        scanModules(
            text, at,
            [&](char c, size_t offset, const std::vector<std::pair<std::string, size_t>>& args) {
                arity(c, args.size(), at, offset);
                Module m;
                m.name = c;
                for (const auto& [a, o] : args) {
                    const double v = constant(a, at.shifted(o));
                    if (!std::isfinite(v))  // (the derivation checks what productions make)
                        fail(at.shifted(o), 0,
                             fmt::format("'{}' is {}: a module's parameter must be a finite "
                                         "number",
                                         trim(a), numberText(v)));
                    m.params.push_back(v);
                }
                out.push_back(m);
            });
        return out;
    }

    std::vector<ModulePattern> patterns(const std::string& text, const Place& at,
                                        std::vector<std::string>& formals)
    {
        std::vector<ModulePattern> out;
        scanModules(
            text, at,
            [&](char c, size_t offset, const std::vector<std::pair<std::string, size_t>>& args) {
                arity(c, args.size(), at, offset);
                ModulePattern p;
                p.name = c;
                for (const auto& [a, o] : args) {
                    const std::string name = trim(a);
                    if (name.empty() ||
                        !(std::isalpha(static_cast<unsigned char>(name[0])) || name[0] == '_') ||
                        name.find_first_not_of(
                            "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_") !=
                            std::string::npos)
                        fail(at, o,
                             fmt::format("a formal parameter must be a name (got '{}')", name));
                    for (const auto& f : formals)
                        if (f == name)
                            fail(at, o,
                                 fmt::format("the formal parameter '{}' appears twice", name));
                    formals.push_back(name);
                    p.formals.push_back(name);
                }
                out.push_back(p);
            });
        return out;
    }

    void production(const std::string& t, const Place& at)
    {
        Production p;
        p.line = at.line;
        const size_t arrow = t.find("-->");
        std::string lhs = t.substr(0, arrow), rhs = t.substr(arrow + 3);
        const Place rat = at.shifted(arrow + 3);
        // predecessor part : condition
        std::string cond;
        size_t condAt = 0;
        if (const size_t colon = findTopLevel(lhs, ':'); colon != std::string::npos) {
            cond = lhs.substr(colon + 1);
            condAt = colon + 1;
            lhs = lhs.substr(0, colon);
        }
        std::string left, strict = lhs, right;
        size_t strictAt = 0, rightAt = 0;
        if (const size_t lt = findTopLevel(lhs, '<'); lt != std::string::npos) {
            left = lhs.substr(0, lt);
            strict = lhs.substr(lt + 1);
            strictAt = lt + 1;
        }
        if (const size_t gt = findTopLevel(strict, '>'); gt != std::string::npos) {
            right = strict.substr(gt + 1);
            rightAt = strictAt + gt + 1;
            strict = strict.substr(0, gt);
        }
        std::vector<std::string> formals;
        p.left = patterns(left, at, formals);
        const std::vector<ModulePattern> pred = patterns(strict, at.shifted(strictAt), formals);
        if (pred.size() != 1)
            fail(at, strictAt,
                 fmt::format("a production rewrites one module (the predecessor is '{}')",
                             trim(strict)));
        p.strict = pred[0];
        // `formals` now holds the left context's, then the predecessor's, then
        // the right context's: the order in which derivation binds them.
        p.right = patterns(right, at.shifted(rightAt), formals);
        if (!trim(cond).empty())
            p.condition = ExprParser(cond, at.shifted(condAt), formals, defines_).parseAll();
        // successor : probability
        if (const size_t colon = findTopLevel(rhs, ':'); colon != std::string::npos) {
            const Place pat = rat.shifted(colon + 1);
            const std::string prob = rhs.substr(colon + 1);
            rhs = rhs.substr(0, colon);
            p.probability = constant(prob, pat);
            if (!(p.probability > 0.0 && p.probability <= 1e9))
                fail(pat, 0, fmt::format("a probability must be positive (got {})", p.probability));
        }
        scanModules(
            rhs, rat,
            [&](char c, size_t offset, const std::vector<std::pair<std::string, size_t>>& args) {
                arity(c, args.size(), rat, offset);
                ModuleTemplate m;
                m.name = c;
                for (const auto& [a, o] : args)
                    m.args.push_back(ExprParser(a, rat.shifted(o), formals, defines_).parseAll());
                p.successor.push_back(std::move(m));
            });
        system_.productions.push_back(std::move(p));
    }

    LSystem system_;
    std::map<std::string, double> defines_;
    std::map<char, std::pair<size_t, int>> arity_;  // name -> (parameters, line first seen)
};

// --- derivation ------------------------------------------------------------------

/// For each '[' the index of its ']' and the other way round (-1 elsewhere), into
/// `match` (`stack`: its scratch; both reused from step to step).
void matchBrackets(const ModuleString& s, std::vector<long>& match, std::vector<long>& stack)
{
    match.assign(s.size(), -1);
    stack.clear();
    for (size_t i = 0; i < s.size(); ++i) {
        if (s[i].name == '[')
            stack.push_back(long(i));
        else if (s[i].name == ']' && !stack.empty()) {
            match[size_t(stack.back())] = long(i);
            match[i] = stack.back();
            stack.pop_back();
        }
    }
}

bool matches(const Module& m, const ModulePattern& p)
{
    return m.name == p.name && m.params.size() == p.formals.size();
}

/// Follows a string module by module and says which a cut keeps: each
/// module after a '%' is dropped up to the ']' that ends the '%''s branch
/// (or the string's end); the '%' stays, the mark of the cut for the turtle.
struct Cutter {
    int depth = -1;  ///< -1: keeping; else the brackets opened since the '%'
    template <class M>
    bool keeps(const M& m)
    {
        if (depth >= 0) {
            if (m.name == '[')
                ++depth;
            else if (m.name == ']' && depth-- == 0)
                return true;  // the branch's end: keeping again
            return false;
        }
        if (m.name == '%')
            depth = 0;
        return true;
    }
};

/// Whether `p`'s successor has a '%' outside every branch it opens, which
/// cuts the rest of the rewritten module's branch: other modules, kept or
/// rewritten.  (Successors balance their brackets: a '%' inside one of the
/// successor's branches cuts only the successor's own modules, the same at
/// every rewrite, as `F[&F%F]/A`'s.)
bool cutsBeyondItself(const Production& p)
{
    int depth = 0;
    for (const ModuleTemplate& m : p.successor) {
        if (m.name == '%' && depth == 0)
            return true;
        depth += m.name == '[' ? 1 : m.name == ']' ? -1 : 0;
    }
    return false;
}

class Deriver {
public:
    Deriver(const LSystem& sys, uint64_t seed, bool neverShrinks)
        : sys_(sys), rng_(seed), neverShrinks_(neverShrinks)
    {
        std::map<const Expr*, double> memo;
        const bool cuts =
            std::any_of(sys.productions.begin(), sys.productions.end(), cutsBeyondItself);
        for (const Production& p : sys.productions) {
            conditionCost_.push_back(p.condition ? evaluationCost(p.condition.get(), memo) : 0.0);
            rewriteCost_.push_back(rewriteCost(p, memo));
            tryCost_.push_back(tryCost(p));
        }
        // The modules rewritten at every step, whatever the string: the
        // largest set S of names and arities each of whose productions is
        // unconditional and context-free (so one always applies) and makes
        // a module of S (A(n) --> A(n+1), or A --> B and B --> A), where no
        // cut (%) removes them.  Each module of S has a line of descendants
        // in S, one at each step, and lines of different modules are apart.
        // (A cut within a successor's own branch removes only modules that
        // successor makes: they are not made, and nothing else is cut.)
        using Key = std::pair<char, size_t>;
        std::map<Key, std::vector<size_t>> of;  // each name and arity's productions
        for (size_t k = 0; k < sys.productions.size(); ++k)
            of[{sys.productions[k].strict.name, sys.productions[k].strict.formals.size()}]
                .push_back(k);
        std::map<Key, double> least;  // S, and what each line costs a step at least
        if (!cuts)
            for (const auto& [key, prods] : of)
                if (std::all_of(prods.begin(), prods.end(), [&](size_t k) {
                        const Production& p = sys.productions[k];
                        return !p.condition && p.left.empty() && p.right.empty();
                    })) {
                    // The rewrite, its work, and the productions tried: up
                    // to the first deterministic one (all apply).
                    double cheapest = std::numeric_limits<double>::infinity(), tries = 0.0;
                    for (size_t k : prods)
                        cheapest = std::min(cheapest, rewriteCost_[k]);
                    for (size_t k : prods) {
                        tries += tryCost_[k];
                        if (sys.productions[k].probability < 0.0)
                            break;
                    }
                    least[key] = 1.0 + cheapest + tries;
                }
        // A production's best line: the most a module of S it makes costs
        // (-1 when it makes none).
        auto best = [&](size_t k) {
            double most = -1.0;
            Cutter cutter;
            for (const ModuleTemplate& m : sys.productions[k].successor)
                if (const auto f = least.find({m.name, m.args.size()});
                    cutter.keeps(m) && f != least.end())
                    most = std::max(most, f->second);
            return most;
        };
        // Take out of S what may make none of S, and lower each cost to its
        // productions' worst best line, until nothing changes (each pass
        // takes a key out or lowers a cost to another's: at most |S|^2).
        for (bool changed = true; changed;) {
            changed = false;
            for (auto it = least.begin(); it != least.end();) {
                double worst = it->second;
                for (size_t k : of[it->first])
                    worst = std::min(worst, best(k));
                if (worst < 0.0) {
                    it = least.erase(it);
                    changed = true;
                    continue;
                }
                changed = changed || worst < it->second;
                it->second = worst;
                ++it;
            }
        }
        for (const auto& [key, cost] : least) {
            auto& costs = sustained_[size_t(static_cast<unsigned char>(key.first))];
            if (costs.size() <= key.second)
                costs.resize(key.second + 1, 0.0);
            costs[key.second] = cost;
        }
        // Modules no production matches are kept at every step, one rewrite
        // each, unless a cut removes them (a string of 100,000 X beside one
        // rewritten B(n) ran 50 s before the bound stopped it).
        noCuts_ = !cuts;
        for (const auto& [key, prods] : of) {
            auto& arities = rewritten_[size_t(static_cast<unsigned char>(key.first))];
            if (arities.size() <= key.second)
                arities.resize(key.second + 1, false);
            arities[key.second] = true;
        }
    }

    /// What a step over `s` costs at least, in rewrites, whatever the string
    /// has become by then: each module rewritten at every step at the least
    /// its line of descendants costs a step, and at one rewrite each module
    /// no production matches where nothing cuts, and every other module
    /// where no string is shorter than the one before.
    double leastStepCost(const ModuleString& s) const
    {
        double cost = 0.0;
        for (const Module& m : s) {
            const size_t name = size_t(static_cast<unsigned char>(m.name)), arity = m.params.size();
            const auto& costs = sustained_[name];
            const double c = arity < costs.size() ? costs[arity] : 0.0;
            const bool kept =
                noCuts_ && !(arity < rewritten_[name].size() && rewritten_[name][arity]);
            cost += c > 0.0 ? c : neverShrinks_ || kept ? 1.0 : 0.0;
        }
        return cost;
    }

    /// The modules that bind the left context, nearest last, or false.
    bool leftContext(const ModuleString& s, const std::vector<long>& match, size_t i,
                     const Production& p, std::vector<const Module*>& bound) const
    {
        long k = long(i) - 1;
        for (size_t want = p.left.size(); want-- > 0;) {
            for (;;) {
                if (k < 0)
                    return false;
                spend();
                const char c = s[size_t(k)].name;
                if (c == ']' && match[size_t(k)] >= 0)
                    k = match[size_t(k)] - 1;  // a whole branch to the left: not an ancestor
                else if (c == '[' || sys_.ignore.find(c) != std::string::npos)
                    --k;
                else
                    break;
            }
            if (!matches(s[size_t(k)], p.left[want]))
                return false;
            bound[want] = &s[size_t(k)];
            --k;
        }
        return true;
    }

    bool rightContext(const ModuleString& s, const std::vector<long>& match, size_t i,
                      const Production& p, std::vector<const Module*>& bound) const
    {
        size_t k = i + 1;
        for (size_t want = 0; want < p.right.size(); ++want) {
            for (;;) {
                if (k >= s.size())
                    return false;
                spend();
                const char c = s[k].name;
                if (c == '[' && match[k] >= 0)
                    k = size_t(match[k]) + 1;  // a lateral branch: skipped
                else if (c == ']')
                    return false;  // the end of this branch
                else if (sys_.ignore.find(c) != std::string::npos)
                    ++k;
                else
                    break;
            }
            if (!matches(s[k], p.right[want]))
                return false;
            bound[want] = &s[k];
            ++k;
        }
        return true;
    }

    /// The context searches' budget: each module a search passes counts as
    /// a rewrite, against what kMaxRewrites leaves (`B < A` over a string of
    /// many `[A]` branches skips them all for every A: cubic in the steps,
    /// hours from 56 bytes).
    void setBudget(double modules, int stepNo, double limit)
    {
        budget_ = modules;
        stepNo_ = stepNo;
        limit_ = limit;
    }
    double budgetLeft() const { return budget_; }

    /// The next string; `s` is consumed (its unrewritten modules are moved,
    /// not copied: a long string of which a few modules change costs what
    /// those do, not a copy of every module's parameters).
    ModuleString step(ModuleString&& s, int stepNo, size_t maxModules)
    {
        matchBrackets(s, match_, stack_);
        const std::vector<long>& match = match_;
        // Choose every module's production first: the limit is checked before
        // the new string is made.  (The buffers live from step to step: made
        // anew, each step's were fresh pages, faulted in, and a long string's
        // steps went to the kernel.)
        auto& chosen = chosen_;
        chosen.clear();
        chosen.resize(s.size());
        size_t total = 0;
        // The string now, the bindings and the next string, in bytes; the
        // expression nodes the next string's parameters evaluate.
        double made = 0.0, work = 0.0;
        size_t params = 0;  // (counted, not summed in doubles: a chain of additions through
                            // memory was a fifth of a long string's step)
        for (const Module& m : s)
            params += m.params.size();
        double held = double(params) * sizeof(double) + double(s.size()) * kModuleBytes;
        std::vector<const Production*> applicable;
        std::vector<std::vector<double>> bindings;
        for (size_t i = 0; i < s.size(); ++i) {
            // The step's memory as it grows, whichever way each module
            // goes: the modules' parameters are held too (--max-modules
            // counts modules; 600 parameters each reached 8 GB under the
            // limit, then ran out of memory).
            if ((i & 4095) == 4095)
                checkStepMemory(stepNo, total, held + made);
            applicable.clear();
            bindings.clear();
            for (const Production& p : sys_.productions) {
                if (!matches(s[i], p.strict))
                    continue;
                // Each production tried binds its parameters, whether it
                // applies or not (3,000 stochastic or falsely conditioned
                // productions of A(n) ran for hours within the bound).
                budget_ -= tryCost_[size_t(&p - sys_.productions.data())];
                if (budget_ < 0.0)
                    spend();
                std::vector<const Module*> left(p.left.size()), right(p.right.size());
                if (!leftContext(s, match, i, p, left) || !rightContext(s, match, i, p, right))
                    continue;
                std::vector<double> vars;
                for (const Module* m : left)
                    vars.insert(vars.end(), m->params.begin(), m->params.end());
                vars.insert(vars.end(), s[i].params.begin(), s[i].params.end());
                for (const Module* m : right)
                    vars.insert(vars.end(), m->params.begin(), m->params.end());
                if (p.condition) {
                    budget_ -= conditionCost_[size_t(&p - sys_.productions.data())];
                    if (budget_ < 0.0)
                        spend();
                    if (evaluate(*p.condition, vars, rng_) == 0.0)
                        continue;
                }
                applicable.push_back(&p);
                bindings.push_back(std::move(vars));
                if (p.probability < 0.0)
                    break;  // a deterministic production: the first that applies
            }
            if (applicable.empty()) {
                ++total;
                continue;
            }
            size_t pick = applicable.size() - 1;
            if (applicable.back()->probability > 0.0 || applicable.size() > 1) {
                // Stochastic: weights of the applicable stochastic productions.
                double sum = 0.0;
                for (const Production* p : applicable)
                    sum += std::max(p->probability, 0.0);
                double u = uniformReal(rng_, 0.0, sum);
                for (pick = 0; pick + 1 < applicable.size(); ++pick) {
                    u -= std::max(applicable[pick]->probability, 0.0);
                    if (u < 0.0)
                        break;
                }
            }
            const Production* chosenProduction = applicable[pick];
            const size_t index = size_t(chosenProduction - sys_.productions.data());
            work += rewriteCost_[index];
            held += double(bindings[pick].size()) * sizeof(double) + kModuleBytes;
            for (const ModuleTemplate& t : chosenProduction->successor)
                made += double(t.args.size()) * sizeof(double) + kModuleBytes;
            chosen[i] = {chosenProduction, std::move(bindings[pick])};
            total += chosenProduction->successor.size();
        }
        checkStepMemory(stepNo, total, held + made);
        if (total > maxModules)
            throw InputError(fmt::format(
                "{}: derivation step {} would make {} modules, more than the limit of {} "
                "(--max-modules; fewer --steps?)",
                sys_.source, stepNo, total, maxModules));
        // Its rewrites' modules, parameters and expressions, before they are
        // made (a million modules of 19-term sums ran 45 minutes within the
        // rewrite limit; 8,000 modules A(n) --> A(n+1) over 100,000 steps ran
        // past a minute when each counted one rewrite).
        budget_ -= work;
        if (budget_ < 0.0)
            throw InputError(fmt::format(
                "{}: derivation step {}: its parameters' expressions, with the rewrites and "
                "context searches before, are more than {:g} modules' work in all (minutes of "
                "work): fewer --steps, or fewer or simpler parameters",
                sys_.source, stepNo, limit_));
        ModuleString out = std::move(spare_);
        out.clear();
        if (out.capacity() < total)  // (grown by doubling: a string growing a module a step
                                     // must not be moved every step)
            out.reserve(std::max(total, 2 * out.capacity()));
        // The cuts are made as the string is: a module after a '%' is
        // dropped up to its branch's ']' (a second pass into a fresh string
        // tripled a cut system's steps: 28 ns a module against 13).  A
        // dropped module's parameters are still evaluated, so the random
        // numbers drawn stay those of the whole string.
        Cutter cutter;
        for (size_t i = 0; i < s.size(); ++i) {
            const Production* p = chosen[i].first;
            if (!p) {
                if (cutter.keeps(s[i]))
                    out.push_back(std::move(s[i]));
                continue;
            }
            for (const ModuleTemplate& t : p->successor) {
                Module m;
                m.name = t.name;
                for (const auto& e : t.args) {
                    const double v = evaluate(*e, chosen[i].second, rng_);
                    if (!std::isfinite(v))
                        throw InputError(
                            fmt::format("{}:{}: derivation step {}: a parameter of {} is {}",
                                        sys_.source, p->line, stepNo, t.name, numberText(v)));
                    m.params.push_back(v);
                }
                if (cutter.keeps(m))
                    out.push_back(std::move(m));
            }
        }
        spare_ = std::move(s);
        return out;
    }

    /// Removes the rest of each '%''s branch (up to the branch's ']').
    static ModuleString cut(ModuleString&& s)
    {
        ModuleString out;
        out.reserve(s.size());
        Cutter cutter;
        for (Module& m : s)
            if (cutter.keeps(m))
                out.push_back(std::move(m));
        return out;
    }

private:
    /// A module's bytes beside its parameters (its name, its vector and the
    /// vector's heap block); an expression node's evaluation in rewrites,
    /// and a function call's or power's.
    // (Measured here: about 2e8 expression nodes a second, against 1e8
    // rewrites; at a tenth of a rewrite a thousand modules of 3,300-node
    // expressions ran past 100 s within the bound.  A call costs up to 70 ns:
    // sin and tan of arguments beyond 1e15 take 50-70 ns against 10 for
    // small ones, pow 15-18: sums of sin(n * 1e300) ran 76 and 82 s within
    // the bound at half a rewrite a node.)
    static constexpr double kModuleBytes = sizeof(Module) + 32.0, kNodeRewrites = 0.5,
                            kCallRewrites = 7.0;

    /// What rewriting a module by `p` costs beyond the rewrite itself, in
    /// rewrites (a module kept as it is, moved to the next string: 13 ns
    /// here).  Measured over 4,000 modules and 20,000 steps: A --> A 27 ns
    /// a module, A(n) --> A(n+1) 77 ns, A(a,b,c,d) --> A(a+1,b,c,d) 142 ns.
    /// So: each module made, each parameter value made and its vector, and
    /// the expressions' nodes; the bindings count as the production's try
    /// (tryCost).
    static double rewriteCost(const Production& p, std::map<const Expr*, double>& memo)
    {
        double cost = double(p.successor.size());
        for (const ModuleTemplate& t : p.successor) {
            cost += double(t.args.size()) + (t.args.empty() ? 0.0 : 1.0);
            for (const ExprPtr& e : t.args)
                cost += evaluationCost(e.get(), memo);
        }
        return cost;
    }

    /// What trying `p` on a module of its name and arity costs, in
    /// rewrites, before its condition: the bindings of its parameters and
    /// contexts' (a value each, a vector of them, the contexts' lists), and
    /// one for the try (3,000 productions tried cost 33 ns each).
    static double tryCost(const Production& p)
    {
        double bound = double(p.strict.formals.size());
        for (const auto& m : p.left)
            bound += double(m.formals.size());
        for (const auto& m : p.right)
            bound += double(m.formals.size());
        return 1.0 + bound + (bound > 0.0 ? 1.0 : 0.0) + (p.left.empty() ? 0.0 : 1.0) +
               (p.right.empty() ? 0.0 : 1.0);
    }

    /// What an evaluation of `e` costs in rewrites: each node it visits (a
    /// shared subtree, as `#define` folds make, counts each time it is
    /// reached), saturating.
    static double evaluationCost(const Expr* e, std::map<const Expr*, double>& memo)
    {
        if (const auto f = memo.find(e); f != memo.end())
            return f->second;
        double n = e->op == Expr::Call || e->op == Expr::Pow ? kCallRewrites : kNodeRewrites;
        for (const ExprPtr& k : e->kids)
            n = std::min(n + evaluationCost(k.get(), memo), 1e18);
        memo[e] = n;
        return n;
    }

    void checkStepMemory(int stepNo, size_t modules, double bytes)
    {
        if (room_ < 0.0)
            room_ = availableMemoryBytes();
        if (bytes > 0.5 * room_)  // (what else a step holds: its bindings, spare room)
            throw InputError(fmt::format(
                "{}: derivation step {} would hold {} or more of modules and their parameters "
                "({} modules so far), more than half the {} this process has: fewer --steps, "
                "--max-modules or parameters",
                sys_.source, stepNo, formatBytes(bytes), modules, formatBytes(room_)));
    }

    void spend() const
    {
        if (--budget_ < 0.0)
            throw InputError(fmt::format(
                "{}: derivation step {}: its context searches and conditions, with the "
                "rewrites, are more than {:g} modules' work in all (minutes of work): fewer "
                "--steps, simpler conditions, or contexts that skip fewer branches",
                sys_.source, stepNo_, limit_));
    }

    const LSystem& sys_;
    Rng rng_;
    mutable double budget_ = kMaxRewrites;
    int stepNo_ = 0;
    double limit_ = kMaxRewrites;
    std::vector<std::pair<const Production*, std::vector<double>>> chosen_;
    std::vector<double> conditionCost_, rewriteCost_, tryCost_;  ///< each production's
    /// leastStepCost()'s modules: by name, then by arity (0: not one of them).
    std::array<std::vector<double>, 256> sustained_;
    /// By name, then by arity: whether a production matches such modules.
    std::array<std::vector<bool>, 256> rewritten_;
    bool noCuts_ = false;
    bool neverShrinks_ = false;
    double room_ = -1.0;  ///< memory available (once)
    ModuleString spare_;  ///< the string before last, its room for the next
    std::vector<long> match_, stack_;
};

}  // namespace

LSystem parseLSystem(const std::string& text, const std::string& source)
{
    return Reader(source).read(text);
}

LSystem loadLSystem(const std::string& path)
{
    return parseLSystem(readTextFile(path, "L-system file"), path);
}

ModuleString derive(const LSystem& system, int steps, uint64_t seed, size_t maxModules,
                    const std::function<void(const char*, double)>& progress, double maxRewrites)
{
    if (steps < 0 || steps > kMaxSteps)
        throw InputError(fmt::format(
            "{}: {} derivation steps (--steps or the file's derivation length): must be "
            "from 0 to {}",
            system.source, steps, kMaxSteps));
    if (maxModules < 1 || maxModules > kMaxModulesLimit)
        throw InputError(fmt::format("--max-modules must be from 1 to {} (got {})",
                                     kMaxModulesLimit, maxModules));
    if (system.axiom.size() > maxModules)
        throw InputError(fmt::format("{}: the axiom has {} modules, more than the limit of {}",
                                     system.source, system.axiom.size(), maxModules));
    // Where no successor is empty and none cuts (%) beyond its own
    // modules, no string is shorter than the one before (a cut within the
    // successor's own branch, as F[&F%F]/A's, leaves the '[' and '%' at
    // least: a sweep's 100,000 such steps ran 61 s before the whole bound
    // stopped them at step 23,904): the steps left rewrite at least this one's
    // modules each, known now.  (A million modules kept by A --> A over
    // 100,000 steps ran for minutes before the bound stopped it.)  Modules
    // rewritten at every step cost their production's work at each
    // (leastStepCost: 8,000 modules A(n) --> A(n+1) over 100,000 steps ran
    // past a minute).
    const bool neverShrinks = std::none_of(
        system.productions.begin(), system.productions.end(),
        [](const Production& p) { return p.successor.empty() || cutsBeyondItself(p); });
    Deriver d(system, seed, neverShrinks);
    ModuleString s = Deriver::cut(ModuleString(system.axiom));
    double rewrites = 0.0;
    for (int i = 1; i <= steps; ++i) {
        rewrites += double(s.size());
        const double atLeast = rewrites + d.leastStepCost(s) * double(steps - i);
        if (atLeast > maxRewrites)
            throw InputError(
                fmt::format("{}: {} steps would rewrite more than {:g} modules' work in all "
                            "(rewrites, context searches and parameter expressions: minutes of "
                            "work; known before step {}): fewer --steps",
                            system.source, steps, maxRewrites, i));
        d.setBudget(maxRewrites - rewrites, i, maxRewrites);
        s = d.step(std::move(s), i, maxModules);
        rewrites = maxRewrites - d.budgetLeft();  // (with the context searches)
        if (progress)
            progress("deriving", double(i) / steps);
    }
    return s;
}

size_t branchEnd(const ModuleString& s, size_t from)
{
    int depth = 0;
    for (size_t i = from + 1; i < s.size(); ++i) {
        if (s[i].name == '[')
            ++depth;
        else if (s[i].name == ']' && depth-- == 0)
            return i;
    }
    return s.size();
}

void formatModules(const ModuleString& s, const std::function<void(std::string_view, double)>& sink)
{
    std::string out;
    for (size_t k = 0; k < s.size(); ++k) {
        const Module& m = s[k];
        out += m.name;
        if (!m.params.empty()) {
            out += '(';
            for (size_t i = 0; i < m.params.size(); ++i) {
                if (i)
                    out += ',';
                fmt::format_to(std::back_inserter(out), "{}", m.params[i]);
            }
            out += ')';
        }
        if (out.size() >= (1u << 16)) {
            sink(out, double(k + 1) / double(s.size()));
            out.clear();
        }
    }
    if (!out.empty())
        sink(out, 1.0);
}

std::string formatModules(const ModuleString& s)
{
    std::string out;
    formatModules(s, [&](std::string_view part, double) { out += part; });
    return out;
}

}  // namespace cambium
