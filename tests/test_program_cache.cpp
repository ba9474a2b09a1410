// The OpenCL program cache (OpenCLContext::build): a program built once is
// loaded from its binary, keyed by the whole source and options, and a
// damaged or foreign file costs a rebuild, never a wrong kernel.
#include "cl/runtime.h"
#include "core/hash.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace {

using namespace cambium;
namespace fs = std::filesystem;

const char kSource[] =
    "__kernel void affine(__global float* x) { int i = get_global_id(0); x[i] = 2.0f * x[i] + "
    "K; }\n";

/// The program built with -D K=k, run on x = 3: 6 + k.
float runAffine(const OpenCLContext& ctx, int k)
{
    cl_program program = ctx.build(kSource, "-D K=" + std::to_string(k));
    cl_int err = CL_SUCCESS;
    cl_kernel kernel = clCreateKernel(program, "affine", &err);
    EXPECT_EQ(err, CL_SUCCESS);
    float x[4] = {3.0f, 3.0f, 3.0f, 3.0f};
    cl_mem buf =
        clCreateBuffer(ctx.context(), CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, sizeof x, x, &err);
    EXPECT_EQ(err, CL_SUCCESS);
    clSetKernelArg(kernel, 0, sizeof buf, &buf);
    const size_t global = 4, local = 4;
    EXPECT_EQ(clEnqueueNDRangeKernel(ctx.queue(), kernel, 1, nullptr, &global, &local, 0, nullptr,
                                     nullptr),
              CL_SUCCESS);
    EXPECT_EQ(clEnqueueReadBuffer(ctx.queue(), buf, CL_TRUE, 0, sizeof x, x, 0, nullptr, nullptr),
              CL_SUCCESS);
    clReleaseMemObject(buf);
    clReleaseKernel(kernel);
    clReleaseProgram(program);
    return x[0];
}

std::string contents(const fs::path& p)
{
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

void write(const fs::path& p, const std::string& bytes)
{
    std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
}

/// A cache file split into its stored key and its binary (between them the
/// binary's length and checksum, made again by bytes()).
struct CacheFile {
    std::string key, binary;
    explicit CacheFile(const std::string& bytes)
    {
        uint64_t n = 0;
        std::memcpy(&n, bytes.data(), sizeof n);
        key = bytes.substr(sizeof n, n);
        binary = bytes.substr(sizeof n + n + 16);
    }
    std::string bytes() const
    {
        Checksum64 sum;
        sum.update(binary.data(), binary.size());
        const uint64_t n = key.size(), tail[] = {binary.size(), sum.value()};
        return std::string(reinterpret_cast<const char*>(&n), sizeof n) + key +
               std::string(reinterpret_cast<const char*>(tail), sizeof tail) + binary;
    }
};

TEST(ProgramCache, AProgramIsLoadedFromItsBinaryKeyedByItsOptionsAndADamagedFileIsRebuilt)
{
    const fs::path dir =
        fs::temp_directory_path() / ("cambium_cache_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    ::setenv("CAMBIUM_CACHE_DIR", dir.c_str(), 1);
    const fs::path programs = dir / "opencl";
    EXPECT_EQ(programCacheDirectory(), programs.string());
    OpenCLContext ctx;

    // Built from source, its binary kept: one file per program.
    EXPECT_EQ(runAffine(ctx, 1), 7.0f);
    ASSERT_TRUE(fs::is_directory(programs));
    fs::path one;
    for (const auto& e : fs::directory_iterator(programs))
        one = e.path();
    EXPECT_EQ(runAffine(ctx, 2), 8.0f);  // other options: another program, another file
    fs::path two;
    int files = 0;
    for (const auto& e : fs::directory_iterator(programs)) {
        ++files;
        if (e.path() != one)
            two = e.path();
    }
    ASSERT_EQ(files, 2);
    const std::string oneBytes = contents(one), twoBytes = contents(two);
    EXPECT_NE(CacheFile(oneBytes).key.find("-D K=1"), std::string::npos);
    EXPECT_NE(CacheFile(oneBytes).key.find(kSource), std::string::npos);  // the whole source

    // The binary is what runs: K=1's file holding K=2's binary under K=1's
    // key makes the K=1 program compute 6 + 2.
    CacheFile swapped(oneBytes);
    swapped.binary = CacheFile(twoBytes).binary;
    write(one, swapped.bytes());
    EXPECT_EQ(runAffine(ctx, 1), 8.0f);

    // A file under the right name whose stored key differs (another
    // program's) is not used, and is replaced by the right one.
    write(one, twoBytes);
    EXPECT_EQ(runAffine(ctx, 1), 7.0f);
    EXPECT_TRUE(CacheFile(contents(one)).key == CacheFile(oneBytes).key);

    // A damaged binary: rebuilt from source and replaced.
    CacheFile damaged(oneBytes);
    damaged.binary = std::string(damaged.binary.size() / 3, 'x');
    write(one, damaged.bytes());
    EXPECT_EQ(runAffine(ctx, 1), 7.0f);
    const CacheFile rebuilt(contents(one));
    EXPECT_TRUE(rebuilt.key == damaged.key);
    EXPECT_FALSE(rebuilt.binary == damaged.binary);

    // A binary cut short, or with bytes changed, under its file's length
    // and checksum (a disk error, a farm's cache copied in part): PoCL
    // asserted or crashed on it, on every run (sweep 18).  Rebuilt.
    const std::string good = contents(one);
    ASSERT_TRUE(CacheFile(good).binary.size() > 1000);
    auto whole = [&] {  // (its length and checksum those of its binary)
        const std::string now = contents(one);
        return CacheFile(now).bytes() == now && CacheFile(now).key == CacheFile(good).key;
    };
    write(one, good.substr(0, good.size() * 9 / 10));
    EXPECT_EQ(runAffine(ctx, 1), 7.0f);
    EXPECT_TRUE(whole());
    std::string changed = good;
    for (size_t k = 0; k < 20; ++k)
        changed[good.size() - 1 - 37 * k] = char(~changed[good.size() - 1 - 37 * k]);
    write(one, changed);
    EXPECT_EQ(runAffine(ctx, 1), 7.0f);
    EXPECT_TRUE(whole());

    // An empty CAMBIUM_CACHE_DIR keeps nothing.
    ::setenv("CAMBIUM_CACHE_DIR", "", 1);
    EXPECT_EQ(programCacheDirectory(), "");
    fs::remove_all(dir);
    EXPECT_EQ(runAffine(ctx, 3), 9.0f);
    EXPECT_FALSE(fs::exists(dir));
    ::unsetenv("CAMBIUM_CACHE_DIR");
}

}  // namespace
