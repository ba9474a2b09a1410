// Parity of the shared per-operation math on the OpenCL device (PoCL here)
// with the host's double-precision evaluation of the same headers, on random
// and adversarial inputs (on skeletons, at end planes, at region borders).
#include "cl/runtime.h"
#include "cl/kernel_sources.h"

#include "cb_operators.h"
#include "cb_primitives.h"
#include "cb_warps.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>

namespace {

using namespace cambium;

class KernelParity : public ::testing::Test {
protected:
    static void SetUpTestSuite()
    {
        ctx_ = new OpenCLContext();  // fails the suite with a clear message if no platform
        std::ifstream in(CAMBIUM_SOURCE_DIR "/tests/kernels/parity.cl");
        std::stringstream s;
        s << in.rdbuf();
        program_ = ctx_->build(assembleKernelSource(s.str()), "-cl-std=CL1.2");
    }
    static void TearDownTestSuite()
    {
        clReleaseProgram(program_);
        delete ctx_;
    }

    /// Runs `name` over n work-items with float buffers: in (read), prm (read), out (write).
    std::vector<float> launch(const char* name, const std::vector<float>& in, int mode,
                              const std::vector<float>& prm, size_t n, size_t outPerItem,
                              bool hasMode = true)
    {
        cl_int err;
        cl_kernel k = clCreateKernel(program_, name, &err);
        checkCL(err, "clCreateKernel");
        auto buffer = [&](const std::vector<float>& v, cl_mem_flags flags) {
            cl_mem m = clCreateBuffer(ctx_->context(), flags | CL_MEM_COPY_HOST_PTR,
                                      v.size() * sizeof(float), const_cast<float*>(v.data()), &err);
            checkCL(err, "clCreateBuffer");
            return m;
        };
        std::vector<float> out(n * outPerItem, 0.0f);
        cl_mem bin = buffer(in, CL_MEM_READ_ONLY), bprm = buffer(prm, CL_MEM_READ_ONLY),
               bout = buffer(out, CL_MEM_WRITE_ONLY);
        int arg = 0;
        clSetKernelArg(k, cl_uint(arg++), sizeof(cl_mem), &bin);
        if (hasMode)
            clSetKernelArg(k, cl_uint(arg++), sizeof(int), &mode);
        clSetKernelArg(k, cl_uint(arg++), sizeof(cl_mem), &bprm);
        clSetKernelArg(k, cl_uint(arg++), sizeof(cl_mem), &bout);
        const size_t local = 1;
        checkCL(
            clEnqueueNDRangeKernel(ctx_->queue(), k, 1, nullptr, &n, &local, 0, nullptr, nullptr),
            "clEnqueueNDRangeKernel");
        checkCL(clEnqueueReadBuffer(ctx_->queue(), bout, CL_TRUE, 0, out.size() * sizeof(float),
                                    out.data(), 0, nullptr, nullptr),
                "clEnqueueReadBuffer");
        clReleaseMemObject(bin);
        clReleaseMemObject(bprm);
        clReleaseMemObject(bout);
        clReleaseKernel(k);
        return out;
    }

    static OpenCLContext* ctx_;
    static cl_program program_;
};

OpenCLContext* KernelParity::ctx_ = nullptr;
cl_program KernelParity::program_ = nullptr;

std::vector<float> pointsFor(std::mt19937& rng, const std::vector<cb_vec3>& special, int random,
                             double lo, double hi)
{
    std::uniform_real_distribution<double> u(lo, hi);
    std::vector<float> pts;
    for (const auto& s : special)
        pts.insert(pts.end(), {float(s.x), float(s.y), float(s.z)});
    for (int i = 0; i < random; ++i)
        pts.insert(pts.end(), {float(u(rng)), float(u(rng)), float(u(rng))});
    return pts;
}

/// |device - host| within rel * scale + abs.
#define EXPECT_CLOSE(dev, host, rel, abs_, scale)                       \
    EXPECT_LE(std::abs(double(dev) - (host)), (rel) * (scale) + (abs_)) \
        << "host " << (host) << " device " << (dev)

TEST_F(KernelParity, Primitives)
{
    std::mt19937 rng(20);
    const double a[3] = {0.1, -0.2, 0.05}, b[3] = {0.6, 1.3, -0.2};
    const double r0 = 0.3, r1 = 0.12, sigma = 1.0, xT = 0.5, s = 1.0 / 0.3, support = 0.9;
    const double q0 = cb_convolution_density(r0, s, 0.5), q1 = cb_convolution_density(r1, s, 0.5);
    const std::vector<float> prm = {float(a[0]),  float(a[1]), float(a[2]), float(b[0]),
                                    float(b[1]),  float(b[2]), float(r0),   float(r1),
                                    float(sigma), float(xT),   float(s),    float(support),
                                    float(q0),    float(q1)};
    const cb_vec3 A = cb_v3(a[0], a[1], a[2]), B = cb_v3(b[0], b[1], b[2]);
    cb_vec3 axis = cb_sub(B, A);
    const double len = cb_length(axis);
    axis = cb_scale(axis, 1.0 / len);
    // Adversarial points: on the skeleton, at the end points and end planes, on the surface.
    const std::vector<cb_vec3> special = {A,
                                          B,
                                          cb_madd(A, axis, 0.5 * len),
                                          cb_madd(A, axis, -0.1),
                                          cb_madd(B, axis, 0.2),
                                          cb_add(A, cb_v3(0.3, 0, 0)),
                                          cb_add(A, cb_v3(0, 0, 0.6)),
                                          cb_add(B, cb_v3(0.12, 0, 0))};
    const std::vector<float> pts = pointsFor(rng, special, 2000, -1.0, 2.0);
    const size_t n = pts.size() / 3;
    for (int prim = 0; prim < 3; ++prim) {
        SCOPED_TRACE(prim == 0 ? "sphere" : prim == 1 ? "cone" : "convolution_segment");
        const std::vector<float> dev = launch("primitives", pts, prim, prm, n, 4);
        for (size_t i = 0; i < n; ++i) {
            // Host evaluation at the very float point the device saw.
            const cb_vec3 p = cb_v3(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
            cb_vec3 g;
            double f;
            if (prim == 0)
                f = cb_sphere_field(p, A, r0, sigma, xT, &g);
            else if (prim == 1)
                f = cb_cone_field(p, A, axis, len, r0, r1, sigma, xT, &g);
            else
                f = cb_convolution_field(p, A, axis, len, q0, q1, s, support, &g);
            const double gscale = std::max(1.0, cb_length(g));
            EXPECT_CLOSE(dev[4 * i], f, 2e-5, 2e-6, std::max(1.0, std::abs(f))) << " point " << i;
            EXPECT_CLOSE(dev[4 * i + 1], g.x, 2e-4, 1e-4, gscale) << " point " << i;
            EXPECT_CLOSE(dev[4 * i + 2], g.y, 2e-4, 1e-4, gscale) << " point " << i;
            EXPECT_CLOSE(dev[4 * i + 3], g.z, 2e-4, 1e-4, gscale) << " point " << i;
        }
    }
}

TEST_F(KernelParity, Operators)
{
    std::mt19937 rng(21);
    const double T = 0.5, w = 0.2, att = 2.5, k = 0.3, n = 3.0;
    std::vector<float> in = {0.5f, 0.5f, 0.3f,  0.3f, 0.7f, 0.2f,
                             0.0f, 0.0f, -0.4f, 0.9f, 1.2f, 0.31f};
    std::uniform_real_distribution<double> u(-0.5, 1.3);
    for (int i = 0; i < 2000; ++i)
        in.push_back(float(u(rng)));
    const size_t count = in.size() / 2;
    const std::vector<float> prm = {float(T), float(w), float(att), float(k), float(n)};
    const std::vector<float> dev = launch("operators", in, 0, prm, count, 8, false);
    for (size_t i = 0; i < count; ++i) {
        const double f0 = in[2 * i], f1 = in[2 * i + 1];
        double d, host[8];
        host[0] = cb_pcm_deformation(f1, T, w, att, &d);
        host[1] = d;
        host[2] = cb_better_blend_g(f0, T, k, &d);
        host[3] = d;
        host[4] = cb_ricci_finish(cb_ricci_term(f0, n) + cb_ricci_term(f1, n), n);
        host[5] = cb_ricci_partial(f0, host[4], n);
        host[6] = cb_gbb(f0, f1, 0.3, &d);
        host[7] = d;
        for (int j = 0; j < 8; ++j)
            EXPECT_CLOSE(dev[8 * i + size_t(j)], host[j], 1e-5, 1e-5,
                         std::max(1.0, std::abs(host[j])))
                << "input (" << f0 << ", " << f1 << ") output " << j;
    }
}

TEST_F(KernelParity, Warps)
{
    std::mt19937 rng(22);
    const std::vector<std::vector<float>> params = {
        {0.1f, 0.0f, 0.2f, 0.5f, 1.6f, 0.1f, 1.0f, 0.0f, 0.3f, 1.3f},  // bend
        {0.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 1.1f},                    // twist
        {0.0f, 0.2f, 0.0f, 0.0f, 1.0f, 0.0f, 1.5f, 1.0f, 0.4f},        // taper
    };
    const std::vector<cb_vec3> special = {cb_v3(0.1, 0.0, 0.2), cb_v3(0.5, 1.6, 0.1),
                                          cb_v3(0, 0.2, 0), cb_v3(0, 1.7, 0)};
    const std::vector<float> pts = pointsFor(rng, special, 2000, -1.5, 2.5);
    const size_t count = pts.size() / 3;
    for (int warp = 0; warp < 3; ++warp) {
        SCOPED_TRACE(warp == 0 ? "bend" : warp == 1 ? "twist" : "taper");
        const std::vector<float>& pr = params[size_t(warp)];
        const std::vector<float> dev = launch("warps", pts, warp, pr, count, 12);
        for (size_t i = 0; i < count; ++i) {
            const cb_vec3 p = cb_v3(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
            double J[9];
            cb_vec3 q;
            if (warp == 0) {
                q = cb_bend_apply(
                    cb_bend_setup(cb_v3(pr[0], pr[1], pr[2]), cb_v3(pr[3], pr[4], pr[5]),
                                  cb_v3(pr[6], pr[7], pr[8]), pr[9]),
                    p, J);
            } else if (warp == 1) {
                const cb_twist t =
                    cb_twist_setup(cb_v3(pr[0], pr[1], pr[2]), cb_v3(pr[3], pr[4], pr[5]), pr[6]);
                q = cb_twist_apply(t, p, J);
            } else {
                const cb_taper t = cb_taper_setup(cb_v3(pr[0], pr[1], pr[2]),
                                                  cb_v3(pr[3], pr[4], pr[5]), pr[6], pr[7], pr[8]);
                q = cb_taper_apply(t, p, J);
            }
            const double host[3] = {q.x, q.y, q.z};
            for (int j = 0; j < 3; ++j)
                EXPECT_CLOSE(dev[12 * i + size_t(j)], host[j], 2e-5, 2e-5, 1.0 + std::abs(host[j]))
                    << " point " << i;
            for (int j = 0; j < 9; ++j)
                EXPECT_CLOSE(dev[12 * i + 3 + size_t(j)], J[j], 2e-4, 2e-4, 1.0 + std::abs(J[j]))
                    << " point " << i;
        }
    }
}

}  // namespace
