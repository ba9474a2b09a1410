/* cambium — field functions of the skeletal primitives.
 *
 * One definition of each formula, read by the C++ reference evaluator and by
 * the OpenCL kernels.  Every function returns the field value and writes its
 * gradient (or the partial derivatives the caller needs for the chain rule).
 * Primitive weights (negative for scars) are applied by the caller.
 *
 * Conventions (docs/field-conventions.md): fields in [0, 1] for the R-type
 * primitives, surface at F = T (default 0.5), inside where F > T.
 */
#ifndef CAMBIUM_CB_PRIMITIVES_H
#define CAMBIUM_CB_PRIMITIVES_H

#include "cb_common.h"

/* ---------------------------------------------------------------------------
 * Wyvill soft-object function (papers 002 eq. 2, 003):
 *   w(x) = 1 - 22/9 x^2 + 17/9 x^4 - 4/9 x^6  for x in [0, 1],
 *   w(x) = 1 for x <= 0 and 0 for x >= 1.
 * w(0) = 1, w(1/2) = 1/2 exactly, w(1) = 0, w'(0) = w'(1) = 0: C1 everywhere.
 * *dw receives dw/dx. */
CB_FN cb_real cb_wyvill(cb_real x, cb_real* dw)
{
    cb_real xc = cb_clamp01(x);
    cb_real y = xc * xc;
    cb_mask beyond = x >= CB_R(1.0);
    /* The polynomial vanishes at 1 and its slope vanishes at 0 and 1; the
     * selects make "zero beyond the support" exact rather than rounded. */
    *dw = CB_SELECT(
        xc * (CB_R(-44.0) / CB_R(9.0) + y * (CB_R(68.0) / CB_R(9.0) - y * CB_R(24.0) / CB_R(9.0))),
        CB_R(0.0), beyond);
    return CB_SELECT(
        CB_FMAX(CB_R(1.0) + y * (CB_R(-22.0) / CB_R(9.0) +
                                 y * (CB_R(17.0) / CB_R(9.0) - y * CB_R(4.0) / CB_R(9.0))),
                CB_R(0.0)),
        CB_R(0.0), beyond);
}

#if CB_LANES == 1
/* x in [0, 1] with w(x) = T, for T in (0, 1): w is strictly decreasing there,
 * so bisection is exact to the last bit. x(0.5) = 0.5.  (Computed once on the
 * host; a parameter for the kernels.) */
CB_FN cb_real cb_wyvill_inverse(cb_real T)
{
    cb_real lo = CB_R(0.0), hi = CB_R(1.0), dw;
    int i;
    for (i = 0; i < 64; ++i) {
        cb_real mid = CB_R(0.5) * (lo + hi);
        if (cb_wyvill(mid, &dw) > T)
            lo = mid;
        else
            hi = mid;
    }
    return CB_R(0.5) * (lo + hi);
}
#endif

/* ---------------------------------------------------------------------------
 * Skeletal falloff.  A primitive whose isolated surface lies at distance r
 * from its skeleton has field F(d) = w((d - o) / R) with
 *   R = sigma * r / xT   (support width; sigma = 1 gives R = r / xT = 2r at T = 0.5)
 *   o = r (1 - sigma)    (skeleton offset, so that F(r) = w(xT) = T for any sigma)
 * where xT = w^-1(T).  The field is zero beyond the reach o + R.
 * Writes dF/dd and dF/dr. */
CB_FN cb_real cb_skeletal_field(cb_real d, cb_real r, cb_real sigma, cb_real xT, cb_real* dFdd,
                                cb_real* dFdr)
{
    cb_real k = xT / sigma;
    cb_real u = k * (d / r - CB_R(1.0) + sigma);
    cb_real dw;
    cb_real f = cb_wyvill(u, &dw);
    *dFdd = dw * k / r;
    *dFdr = -dw * k * d / (r * r);
    return f;
}

/* Distance from the skeleton beyond which cb_skeletal_field is exactly zero. */
CB_FN cb_real cb_skeletal_reach(cb_real r, cb_real sigma, cb_real xT)
{
    return r * (CB_R(1.0) - sigma + sigma / xT);
}

/* `sphere`: point skeleton at c, surface radius r. */
CB_FN cb_real cb_sphere_field(cb_vec3 p, cb_vec3 c, cb_real r, cb_real sigma, cb_real xT,
                              cb_vec3* grad)
{
    cb_vec3 e = cb_sub(p, c);
    cb_real d = cb_length(e), fd, fr;
    cb_real f = cb_skeletal_field(d, r, sigma, xT, &fd, &fr);
    *grad = cb_scale(e, cb_div0(fd, d));
    return f;
}

/* `cone` (and `segment`, with r0 == r1): line skeleton from a along the unit
 * axis for len, surface radius r(t) = r0 + (r1 - r0) t at the closest skeleton
 * point t in [0, 1].  For a point whose closest skeleton point is interior,
 * F = w(xT d / r(t)) (sigma = 1), so the surface radius is exactly linear from
 * r0 at the base to r1 at the tip; beyond the ends the closest point is an end
 * point and the caps are spheres of radius r0 and r1 (papers 001/003: branches
 * tipped by hemispherical caps).  len == 0 degenerates to a sphere of radius r0. */
CB_FN cb_real cb_cone_field(cb_vec3 p, cb_vec3 a, cb_vec3 axis, cb_real len, cb_real r0, cb_real r1,
                            cb_real sigma, cb_real xT, cb_vec3* grad)
{
    cb_vec3 d = cb_sub(p, a);
    cb_real tt = cb_div0(cb_dot(d, axis), len);
    cb_real t = cb_clamp01(tt);
    cb_vec3 e = cb_madd(d, axis, -t * len);
    cb_real dist = cb_length(e), fd, fr;
    cb_real r = r0 + (r1 - r0) * t;
    cb_real f = cb_skeletal_field(dist, r, sigma, xT, &fd, &fr);
    cb_real slope =
        CB_SELECT(CB_R(0.0), fr * cb_div0(r1 - r0, len), tt > CB_R(0.0) && tt < CB_R(1.0));
    *grad = cb_madd(cb_scale(e, cb_div0(fd, dist)), axis, slope);
    return f;
}

/* ---------------------------------------------------------------------------
 * Bark: multi-scale furrows on a cone, in field space (docs/bark.md).  The
 * cone's surface radius is displaced, r' = r - A P(s, theta, r), by a
 * profile P of the bark's own coordinates: s, the arc length along the
 * branch, and theta, the angle around the axis from a reference direction
 * carried along the branch (both fixed to the wood, so the pattern stays
 * where it is as the branch thickens).  Octave k (k < CB_BARK_OCTAVES) has
 * n_k = around 2^k + k furrows around (whole numbers without a common
 * divisor: periodic in theta, but not within a turn), weight 2^-k, and
 * meanders along the stem with frequency along 2^k and around it k + 1
 * times a turn:
 *   psi_k = n_k theta + phi_k + 1.2 sin(along 2^k s + (k + 1) theta + chi_k),
 *   P = sum_k 2^-k w_k ((1 + cos psi_k) / 2)^4
 * (narrow deep furrows between broad plates).  Scale-limited: w_k fades an
 * octave in smoothly as its wavelength around, 2 pi r / n_k, grows from lmin
 * to 2 lmin (lmin = 4 voxels; 0: no limit).  Writes dP/ds, dP/dtheta, dP/dr. */
#define CB_BARK_OCTAVES 3
#define CB_BARK_MEANDER CB_R(1.2)

CB_FN cb_real cb_bark_profile(cb_real s, cb_real theta, cb_real r, cb_scalar around,
                              cb_scalar along, cb_scalar phase, cb_scalar lmin, cb_real* dPds,
                              cb_real* dPdtheta, cb_real* dPdr)
{
    cb_real P = CB_R(0.0), ps = CB_R(0.0), pt = CB_R(0.0), pr = CB_R(0.0);
    cb_scalar f = along, a = CB_R(1.0);
    int k;
    for (k = 0; k < CB_BARK_OCTAVES; ++k) {
        cb_scalar n = around * (cb_scalar)(1 << k) + (cb_scalar)k;
        cb_scalar m = (cb_scalar)(k + 1);
        cb_scalar phi = phase * m * CB_R(2.399963); /* golden angle steps */
        cb_scalar chi = phase * m * CB_R(1.618034) + CB_R(0.5);
        cb_real arg = f * s + m * theta + chi;
        cb_real ms = CB_SIN(arg), mc = CB_COS(arg);
        cb_real psi = n * theta + phi + CB_BARK_MEANDER * ms;
        cb_real q = CB_R(0.5) * (CB_R(1.0) + CB_COS(psi));
        cb_real q2 = q * q;
        cb_real h = q2 * q2;
        cb_real dh = CB_R(-2.0) * q2 * q * CB_SIN(psi); /* dh/dpsi */
        cb_real w = CB_R(1.0), dw = CB_R(0.0);
        if (lmin > CB_R(0.0)) {
            cb_scalar du = CB_R(2.0) * CB_PI / (n * lmin); /* du/dr */
            cb_real u = r * du - CB_R(1.0);
            cb_real uc = cb_clamp01(u);
            w = uc * uc * (CB_R(3.0) - CB_R(2.0) * uc);
            dw = CB_SELECT(CB_R(0.0), CB_R(6.0) * uc * (CB_R(1.0) - uc) * du,
                           u > CB_R(0.0) && u < CB_R(1.0));
        }
        P += a * w * h;
        pt += a * w * dh * (n + CB_BARK_MEANDER * mc * m);
        ps += a * w * dh * CB_BARK_MEANDER * f * mc;
        pr += a * dw * h;
        f *= CB_R(2.0);
        a *= CB_R(0.5);
    }
    *dPds = ps;
    *dPdtheta = pt;
    *dPdr = pr;
    return P;
}

/* A cone with bark (cb_cone_field's geometry and conventions; sigma = 1 puts
 * the surface at r'): `ref` is the unit direction of theta = 0, across the
 * axis; s0 the arc length of a along its branch; the depth A runs linearly
 * from A0 at a to A1 at the tip, like the radius. */
CB_FN cb_real cb_bark_cone_field(cb_vec3 p, cb_vec3 a, cb_vec3 axis, cb_real len, cb_real r0,
                                 cb_real r1, cb_real sigma, cb_real xT, cb_vec3 ref, cb_scalar s0,
                                 cb_scalar A0, cb_scalar A1, cb_scalar around, cb_scalar along,
                                 cb_scalar phase, cb_scalar lmin, cb_vec3* grad)
{
    cb_vec3 d = cb_sub(p, a);
    cb_real tt = cb_div0(cb_dot(d, axis), len);
    cb_real t = cb_clamp01(tt);
    cb_vec3 e = cb_madd(d, axis, -t * len);
    cb_real dist = cb_length(e), fd, fr, Ps, Pt, Pr;
    cb_real r = r0 + (r1 - r0) * t;
    /* s runs on past the ends: the caps and the junctions between cones
     * carry on the branch's pattern (s is the skeleton's arc length there too) */
    cb_real s = s0 + tt * len;
    cb_vec3 side = cb_cross(axis, ref);
    cb_real ex = cb_dot(e, ref), ey = cb_dot(e, side);
    cb_real theta = CB_ATAN2(ey, ex);
    cb_real P = cb_bark_profile(s, theta, r, around, along, phase, lmin, &Ps, &Pt, &Pr);
    cb_real A = A0 + (A1 - A0) * t;
    cb_real rb = r - A * P;
    cb_real f = cb_skeletal_field(dist, rb, sigma, xT, &fd, &fr);
    /* d rb along the axis: through r and A (interior only) and through s
     * (everywhere); d rb / d theta across it. */
    cb_mask interior = tt > CB_R(0.0) && tt < CB_R(1.0);
    cb_real drdt = (r1 - r0) * (CB_R(1.0) - A * Pr) - (A1 - A0) * P;
    cb_real axial = fr * (CB_SELECT(CB_R(0.0), cb_div0(drdt, len), interior) - A * Ps);
    cb_vec3 g = cb_madd(cb_scale(e, cb_div0(fd, dist)), axis, axial);
    /* grad theta = (ex side - ey ref) / (ex^2 + ey^2) (e leaves the axis's
     * normal plane beyond the ends) */
    cb_vec3 dtheta = cb_madd(cb_scale(side, ex), ref, -ey);
    *grad = cb_madd(g, dtheta, -fr * A * Pt * cb_div0(CB_R(1.0), ex * ex + ey * ey));
    return f;
}

/* ---------------------------------------------------------------------------
 * Convolution line segment with linearly varying density (paper 002 eq. 3-5,
 * after Jin et al.), Cauchy kernel k(r) = 1 / (1 + s^2 r^2)^2, in closed form.
 *
 * With the segment a + t*axis, t in [0, len], density q(t) = q0 + (q1 - q0) t/len,
 * x = (p - a).axis, h the distance from p to the line, P^2 = 1 + s^2 h^2 and
 * tau = x - t (so D = P^2 + s^2 tau^2 = 1 + s^2 |p - c(t)|^2):
 *   F = int q(t) / D^2 dt = (q0 + m x) [I2] - m [M2]        (m = (q1 - q0)/len)
 * where [G] = G(x) - G(x - len) and, as antiderivatives in tau,
 *   I1 = atan(s tau / P) / (P s)
 *   I2 = int D^-2   = tau / (2 P^2 D) + I1 / (2 P^2)
 *   I3 = int D^-3   = tau / (4 P^2 D^2) + 3 I2 / (4 P^2)
 *   M2 = int tau D^-2 = -1 / (2 s^2 D),   M3 = int tau D^-3 = -1 / (4 s^2 D^2)
 *   J3 = int tau^2 D^-3 = (I2 - P^2 I3) / s^2.
 * The gradient is grad F = int q grad k = -4 s^2 int q (tau axis + hvec) / D^3 dt:
 *   grad F = -4 s^2 ( hvec [(q0 + m x) I3 - m M3] + axis [(q0 + m x) M3 - m J3] ).
 */
typedef struct cb_conv_terms {
    cb_real i2, i3, m2, m3, j3;
} cb_conv_terms;

CB_FN cb_conv_terms cb_conv_antiderivatives(cb_real tau, cb_real P2, cb_real P, cb_real s)
{
    cb_conv_terms t;
    cb_real s2 = s * s;
    cb_real D = P2 + s2 * tau * tau;
    cb_real i1 = CB_ATAN(s * tau / P) / (P * s);
    t.i2 = tau / (CB_R(2.0) * P2 * D) + i1 / (CB_R(2.0) * P2);
    t.i3 = tau / (CB_R(4.0) * P2 * D * D) + CB_R(3.0) * t.i2 / (CB_R(4.0) * P2);
    t.m2 = CB_R(-1.0) / (CB_R(2.0) * s2 * D);
    t.m3 = CB_R(-1.0) / (CB_R(4.0) * s2 * D * D);
    t.j3 = (t.i2 - P2 * t.i3) / s2;
    return t;
}

/* The raw (unbounded) convolution integral and its gradient. len > 0. */
CB_FN cb_real cb_convolution_raw(cb_vec3 p, cb_vec3 a, cb_vec3 axis, cb_real len, cb_real q0,
                                 cb_real q1, cb_real s, cb_vec3* grad)
{
    cb_vec3 d = cb_sub(p, a);
    cb_real x = cb_dot(d, axis);
    cb_vec3 hv = cb_madd(d, axis, -x);
    cb_real P2 = CB_R(1.0) + s * s * cb_dot(hv, hv);
    cb_real P = CB_SQRT(P2);
    cb_conv_terms hi = cb_conv_antiderivatives(x, P2, P, s);
    cb_conv_terms lo = cb_conv_antiderivatives(x - len, P2, P, s);
    cb_real m = (q1 - q0) / len;
    cb_real qx = q0 + m * x;
    cb_real A = qx * (hi.i3 - lo.i3) - m * (hi.m3 - lo.m3);
    cb_real B = qx * (hi.m3 - lo.m3) - m * (hi.j3 - lo.j3);
    *grad = cb_scale(cb_madd(cb_scale(hv, A), axis, B), CB_R(-4.0) * s * s);
    return qx * (hi.i2 - lo.i2) - m * (hi.m2 - lo.m2);
}

/* Density that gives an infinite line (or a straight polyline of segments
 * with continuous density) the surface radius r at threshold T:
 *   int_R dtau / (P^2 + s^2 tau^2)^2 = pi / (2 s P^3)  =>  q = 2 s T P^3 / pi. */
CB_FN cb_real cb_convolution_density(cb_real r, cb_real s, cb_real T)
{
    cb_real P2 = CB_R(1.0) + s * s * r * r;
    return CB_R(2.0) * s * T * P2 * CB_SQRT(P2) / CB_PI;
}

/* `convolution_segment`: the Cauchy kernel never reaches zero, so the primitive
 * multiplies the closed form by a C1 window of the distance d to the segment,
 *   W(d) = w(clamp(2 d / R - 1, 0, 1)),
 * equal to 1 up to R/2 and 0 from R on.  R (the support) is at least twice the
 * largest surface radius, so the window never moves the isolated surface. */
CB_FN cb_real cb_convolution_field(cb_vec3 p, cb_vec3 a, cb_vec3 axis, cb_real len, cb_real q0,
                                   cb_real q1, cb_real s, cb_real support, cb_vec3* grad)
{
    cb_vec3 d = cb_sub(p, a);
    cb_real t = cb_clamp01(cb_dot(d, axis) / len);
    cb_vec3 e = cb_madd(d, axis, -t * len);
    cb_real dist = cb_length(e);
    if (CB_ALL(dist >= support)) { /* the whole batch of points is beyond the window */
        *grad = cb_v3(CB_R(0.0), CB_R(0.0), CB_R(0.0));
        return CB_R(0.0);
    }
    cb_vec3 graw;
    cb_real raw = cb_convolution_raw(p, a, axis, len, q0, q1, s, &graw);
    cb_real dW;
    cb_real W = cb_wyvill(CB_R(2.0) * dist / support - CB_R(1.0), &dW);
    *grad =
        cb_madd(cb_scale(graw, W), e, raw * dW * CB_R(2.0) * cb_div0(CB_R(1.0), support * dist));
    return raw * W;
}

#endif /* CAMBIUM_CB_PRIMITIVES_H */
