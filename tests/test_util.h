// cambium tests — shared helpers.
#pragma once

#include "blobtree/blobtree.h"
#include "blobtree/evaluator.h"
#include "model/skeleton.h"

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "core/error.h"
#include "core/system.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <mutex>
#include <new>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace cambium::test {

/// Records `text` as a measured value of the running test: a property
/// ("measured", "measured_2", ...) in GoogleTest's XML report
/// (--gtest_output=xml), not a line on stdout.  Thread-safe.
inline void recordMeasured(const std::string& text)
{
    static std::mutex mutex;
    static const ::testing::TestInfo* test = nullptr;
    static int count = 0;
    std::lock_guard<std::mutex> lock(mutex);
    const ::testing::TestInfo* now = ::testing::UnitTest::GetInstance()->current_test_info();
    count = now == test ? count + 1 : 1;
    test = now;
    ::testing::Test::RecordProperty(count == 1 ? "measured" : "measured_" + std::to_string(count),
                                    text);
}

/// recordMeasured of a formatted line.
template <class... Args>
void report(fmt::format_string<Args...> format, Args&&... args)
{
    recordMeasured(fmt::format(format, std::forward<Args>(args)...));
}

/// Same active voxels, same values, bit for bit.
template <class Grid>
void expectIdentical(const Grid& a, const Grid& b, const std::string& what)
{
    ASSERT_EQ(a.activeVoxelCount(), b.activeVoxelCount()) << what;
    ASSERT_EQ(a.tree().leafCount(), b.tree().leafCount()) << what;
    size_t differ = 0;
    for (auto it = a.cbeginValueOn(); it; ++it)
        if (!b.tree().isValueOn(it.getCoord()) || b.tree().getValue(it.getCoord()) != *it)
            ++differ;
    EXPECT_EQ(differ, 0u) << what;
}

/// An internode of a hand-made skeleton (age: years since it began, or unknown).
inline Internode internode(long long id, long long parent, glm::dvec3 p0, glm::dvec3 p1, double r0,
                           double r1, double age = -1.0)
{
    Internode n;
    n.id = id;
    n.parent = parent;
    n.p0 = p0;
    n.p1 = p1;
    n.r0 = r0;
    n.r1 = r1;
    n.age = age;
    return n;
}

/// Finalised BlobTrees, each named for a test's trace, each built by a
/// function of an empty tree that returns its root.
struct NamedTrees {
    std::vector<std::pair<const char*, BlobTree>> trees;
    template <class Build>
    void add(const char* name, Build build)
    {
        BlobTree t;
        t.setRoot(build(t));
        t.finalize();
        trees.emplace_back(name, std::move(t));
    }
};

inline glm::dvec3 randomUnit(std::mt19937& rng)
{
    std::normal_distribution<double> n(0.0, 1.0);
    glm::dvec3 v;
    do {
        v = {n(rng), n(rng), n(rng)};
    } while (glm::length(v) < 1e-6);
    return glm::normalize(v);
}

inline glm::dvec3 randomIn(std::mt19937& rng, const glm::dvec3& lo, const glm::dvec3& hi)
{
    std::uniform_real_distribution<double> u(0.0, 1.0);
    return lo + (hi - lo) * glm::dvec3(u(rng), u(rng), u(rng));
}

/// Central-difference gradient of f at p with step h.
inline glm::dvec3 finiteDifference(const std::function<double(const glm::dvec3&)>& f,
                                   const glm::dvec3& p, double h)
{
    glm::dvec3 g;
    for (int k = 0; k < 3; ++k) {
        glm::dvec3 e(0.0);
        e[k] = h;
        g[k] = (f(p + e) - f(p - e)) / (2.0 * h);
    }
    return g;
}

/// Outcome of comparing an analytic gradient with finite differences.
enum class GradientCheck { Agrees, Disagrees, NotSmooth };

/// Compares `analytic` with central differences of f at p.  Where the field
/// has a crease within a step (a CSG switch, a PCM ridge, a cone's end plane)
/// the two difference quotients with steps h and h/2 disagree: that point is
/// reported NotSmooth instead of failing.
inline GradientCheck checkGradient(const std::function<double(const glm::dvec3&)>& f,
                                   const glm::dvec3& p, const glm::dvec3& analytic, double h,
                                   double tol)
{
    const glm::dvec3 g1 = finiteDifference(f, p, h);
    const glm::dvec3 g2 = finiteDifference(f, p, 0.5 * h);
    const double scale = std::max({1.0, glm::length(g1), glm::length(analytic)});
    if (glm::length(g1 - g2) > tol * scale)
        return GradientCheck::NotSmooth;
    return glm::length(g2 - analytic) <= tol * scale ? GradientCheck::Agrees
                                                     : GradientCheck::Disagrees;
}

/// Runs f, which must throw InputError with `message` in its text
/// (`what` says which case failed).
template <class F>
void expectInputError(F&& f, const std::string& message, const std::string& what)
{
    try {
        f();
        ADD_FAILURE() << what << ": no error, expected " << message;
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(message), std::string::npos)
            << what << ": " << e.what();
    }
}

/// Whether this build runs under AddressSanitizer, whose allocator reserves
/// terabytes of address space (no address-space limit can be tried).
constexpr bool addressSanitized()
{
#if defined(__SANITIZE_ADDRESS__)
    return true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
    return true;
#endif
#endif
    return false;
}

/// The exit status of `body()` (an int from 0 to 98) run in a forked child
/// under an address-space limit `headroom` bytes above what the process
/// maps; -1 where that cannot be tried (ASan's allocator reserves address
/// space of its own, or a limit is set already): the caller skips.
template <class F>
int statusUnderAddressSpaceLimit(double headroom, F&& body)
{
    if (addressSanitized())
        return -1;
    constexpr int kNoLimit = 99;
    const pid_t child = ::fork();
    if (child == 0) {
        const MemoryLimits now = memoryLimits();
        const rlimit limit{rlim_t(now.addressSpaceUsed + headroom),
                           rlim_t(now.addressSpaceUsed + headroom)};
        if (now.addressSpaceLimit < HUGE_VAL || ::setrlimit(RLIMIT_AS, &limit) != 0)
            ::_exit(kNoLimit);
        ::_exit(body());
    }
    int status = 0;
    if (::waitpid(child, &status, 0) != child || !WIFEXITED(status))
        return 128;  // (a signal: no exit status)
    return WEXITSTATUS(status) == kNoLimit ? -1 : WEXITSTATUS(status);
}

/// `work()` under an address-space limit `headroom` bytes above what the
/// process maps must throw InputError whose message `named` accepts, not
/// run out of memory (skipped where the limit cannot be tried).
template <class F>
void expectRefusedUnderAddressSpaceLimit(double headroom, F&& work,
                                         const std::function<bool(const std::string&)>& named)
{
    const int status = statusUnderAddressSpaceLimit(headroom, [&] {
        try {
            work();
        } catch (const InputError& e) {
            return named(e.what()) ? 0 : 4;
        } catch (const std::bad_alloc&) {
            return 5;
        }
        return 1;
    });
    if (status == -1)
        GTEST_SKIP() << "no address-space limit to try (ASan, or a limit set already)";
    EXPECT_EQ(status, 0) << "4: another message, 5: out of memory, 1: it fitted, 128: a signal";
}

/// The root of f on [a, b] by bisection (f(a) and f(b) of opposite signs).
inline double bisect(const std::function<double(double)>& f, double a, double b, int iters = 200)
{
    double fa = f(a);
    for (int i = 0; i < iters; ++i) {
        const double m = 0.5 * (a + b);
        const double fm = f(m);
        if ((fm > 0) == (fa > 0)) {
            a = m;
            fa = fm;
        } else {
            b = m;
        }
    }
    return 0.5 * (a + b);
}

/// Distance from p along dir at which the tree's field crosses its threshold
/// (searching outwards from p, which must be inside, up to maxDist).
inline double surfaceDistance(const ReferenceEvaluator& eval, double T, const glm::dvec3& p,
                              const glm::dvec3& dir, double maxDist)
{
    return bisect([&](double t) { return eval.value(p + t * dir) - T; }, 0.0, maxDist);
}

}  // namespace cambium::test
