/* Test kernels: evaluate the shared per-operation math on the device, one
 * work-item per input, for comparison with the host's double-precision
 * evaluation of the same headers (tests/test_kernel_parity.cpp). */
#include "cb_primitives.h"
#include "cb_operators.h"
#include "cb_warps.h"

static cb_vec3 load3(__global const float* p, int i)
{
    return cb_v3(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
}

static void store4(__global float* out, int i, float f, cb_vec3 g)
{
    out[4 * i] = f;
    out[4 * i + 1] = g.x;
    out[4 * i + 2] = g.y;
    out[4 * i + 3] = g.z;
}

/* prim: 0 sphere, 1 cone, 2 convolution segment.
 * params: a[3], b[3], r0, r1, sigma, xT, s, support, q0, q1 */
__kernel void primitives(__global const float* points, int prim, __global const float* prm,
                         __global float* out)
{
    int i = get_global_id(0);
    cb_vec3 p = load3(points, i);
    cb_vec3 a = cb_v3(prm[0], prm[1], prm[2]);
    cb_vec3 b = cb_v3(prm[3], prm[4], prm[5]);
    cb_vec3 g;
    float f;
    if (prim == 0) {
        f = cb_sphere_field(p, a, prm[6], prm[8], prm[9], &g);
    } else {
        cb_vec3 axis = cb_sub(b, a);
        float len = cb_length(axis);
        axis = cb_scale(axis, 1.0f / len);
        if (prim == 1)
            f = cb_cone_field(p, a, axis, len, prm[6], prm[7], prm[8], prm[9], &g);
        else
            f = cb_convolution_field(p, a, axis, len, prm[12], prm[13], prm[10], prm[11], &g);
    }
    store4(out, i, f, g);
}

/* Scalar operator steps on (f0, f1): out = pcm D(f1) and dD, better-blend g(f0)
 * and g', Ricci of (f0, f1) and its partial in f0, gbb(f0 as bound, f1, 0.3) and
 * its partial.  params: T, width, attenuation, k, n */
__kernel void operators(__global const float* in, __global const float* prm, __global float* out)
{
    int i = get_global_id(0);
    float f0 = in[2 * i], f1 = in[2 * i + 1];
    float T = prm[0], d;
    out[8 * i + 0] = cb_pcm_deformation(f1, T, prm[1], prm[2], &d);
    out[8 * i + 1] = d;
    out[8 * i + 2] = cb_better_blend_g(f0, T, prm[3], &d);
    out[8 * i + 3] = d;
    float F = cb_ricci_finish(cb_ricci_term(f0, prm[4]) + cb_ricci_term(f1, prm[4]), prm[4]);
    out[8 * i + 4] = F;
    out[8 * i + 5] = cb_ricci_partial(f0, F, prm[4]);
    out[8 * i + 6] = cb_gbb(f0, f1, 0.3f, &d);
    out[8 * i + 7] = d;
}

/* warp: 0 bend (p0, p1, dir, angle), 1 twist (origin, axis, rate), 2 taper
 * (origin, axis, length, scale0, scale1).  out: q (3) then J (9). */
__kernel void warps(__global const float* points, int warp, __global const float* prm,
                    __global float* out)
{
    int i = get_global_id(0), k;
    cb_vec3 p = load3(points, i);
    float J[9];
    cb_vec3 q;
    if (warp == 0) {
        cb_bend b = cb_bend_setup(cb_v3(prm[0], prm[1], prm[2]), cb_v3(prm[3], prm[4], prm[5]),
                                  cb_v3(prm[6], prm[7], prm[8]), prm[9]);
        q = cb_bend_apply(b, p, J);
    } else if (warp == 1) {
        cb_twist t =
            cb_twist_setup(cb_v3(prm[0], prm[1], prm[2]), cb_v3(prm[3], prm[4], prm[5]), prm[6]);
        q = cb_twist_apply(t, p, J);
    } else {
        cb_taper t = cb_taper_setup(cb_v3(prm[0], prm[1], prm[2]), cb_v3(prm[3], prm[4], prm[5]),
                                    prm[6], prm[7], prm[8]);
        q = cb_taper_apply(t, p, J);
    }
    out[12 * i + 0] = q.x;
    out[12 * i + 1] = q.y;
    out[12 * i + 2] = q.z;
    for (k = 0; k < 9; ++k)
        out[12 * i + 3 + k] = J[k];
}
