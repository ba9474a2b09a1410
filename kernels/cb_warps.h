/* cambium — space warps of the BlobTree.
 *
 * A warp node evaluates its child at q(p), the inverse warp of the point; the
 * warped field is F(p) = F_child(q(p)) and its gradient is J^T grad F_child(q)
 * with J = dq/dp.  Each *_apply function returns q and writes J (row-major
 * 3x3).  Parameters are passed by value so that a kernel can read them from
 * any address space.
 */
#ifndef CAMBIUM_CB_WARPS_H
#define CAMBIUM_CB_WARPS_H

#include "cb_common.h"

/* Writes J = u ra^T + v ry^T + w rz^T: the Jacobian of a map expressed in the
 * orthonormal frame (u, v, w) whose local coordinates have gradients ra, ry, rz. */
CB_FN void cb_frame_jacobian(cb_vec3 u, cb_vec3 v, cb_vec3 w, cb_vec3 ra, cb_vec3 ry, cb_vec3 rz,
                             cb_real* J)
{
    J[0] = u.x * ra.x + v.x * ry.x + w.x * rz.x;
    J[1] = u.x * ra.y + v.x * ry.y + w.x * rz.y;
    J[2] = u.x * ra.z + v.x * ry.z + w.x * rz.z;
    J[3] = u.y * ra.x + v.y * ry.x + w.y * rz.x;
    J[4] = u.y * ra.y + v.y * ry.y + w.y * rz.y;
    J[5] = u.y * ra.z + v.y * ry.z + w.y * rz.z;
    J[6] = u.z * ra.x + v.z * ry.x + w.z * rz.x;
    J[7] = u.z * ra.y + v.z * ry.y + w.z * rz.y;
    J[8] = u.z * ra.z + v.z * ry.z + w.z * rz.z;
}

/* ---------------------------------------------------------------------------
 * `transform`: q = M^-1 p for an affine M; m holds the inverse as a row-major
 * 3x4 matrix [A | b], q = A p + b, J = A. */
typedef struct cb_affine {
    cb_real m[12];
} cb_affine;

CB_FN cb_vec3 cb_affine_apply(cb_affine a, cb_vec3 p, cb_real* J)
{
    int i;
    for (i = 0; i < 3; ++i) {
        J[3 * i + 0] = a.m[4 * i + 0];
        J[3 * i + 1] = a.m[4 * i + 1];
        J[3 * i + 2] = a.m[4 * i + 2];
    }
    return cb_v3(a.m[0] * p.x + a.m[1] * p.y + a.m[2] * p.z + a.m[3],
                 a.m[4] * p.x + a.m[5] * p.y + a.m[6] * p.z + a.m[7],
                 a.m[8] * p.x + a.m[9] * p.y + a.m[10] * p.z + a.m[11]);
}

/* ---------------------------------------------------------------------------
 * `bend`: Barr's bend, parameterised so that a bent internode keeps its end
 * points (papers 001 sec. 3.5, 003 sec. 3.6).  The straight child lies along
 * p0 -> p1 (length L, unit axis u).  Bent, its axis is the circular arc from p0
 * to p1 that leaves p0 turned by theta/2 towards the bend direction v and comes
 * back to p1 turned by theta/2 the other way: radius rho = L / (2 sin(theta/2)),
 * arc length s = rho theta > L.  The child's axial coordinate a in [0, L] is
 * spread over the arc (the internode is lengthened by s/L), distances across
 * the axis are kept; beyond the ends the child continues along the end
 * tangents (Barr's rigid regions).  In the bend plane, with x along u and y
 * along v from p0, the arc's centre is (L/2, -rho cos(theta/2)).
 */
typedef struct cb_bend {
    cb_vec3 p0, u, v, w; /* origin and orthonormal frame: axis, bend direction, normal */
    cb_real len;         /* L = |p1 - p0| */
    cb_real theta;       /* total turning angle in (0, pi); 0 means no bend */
    cb_real rho;         /* arc radius */
    cb_real ch, sh;      /* cos and sin of theta/2 */
    cb_real lscale;      /* L / s: child length per arc length */
} cb_bend;

#if CB_LANES == 1
/* theta in radians; a negative theta bends towards -dir.  dir must not be
 * parallel to p1 - p0 (the host validates).  Computed once, on the host. */
CB_FN cb_bend cb_bend_setup(cb_vec3 p0, cb_vec3 p1, cb_vec3 dir, cb_real theta)
{
    cb_bend b;
    cb_vec3 axis = cb_sub(p1, p0);
    b.p0 = p0;
    b.len = cb_length(axis);
    b.u = cb_scale(axis, CB_R(1.0) / b.len);
    b.v = cb_madd(dir, b.u, -cb_dot(dir, b.u));
    b.v = cb_scale(b.v, CB_R(1.0) / cb_length(b.v));
    if (theta < CB_R(0.0)) {
        theta = -theta;
        b.v = cb_scale(b.v, CB_R(-1.0));
    }
    if (theta < CB_R(1e-6)) /* a straight internode: no arc to speak of */
        theta = CB_R(0.0);
    b.w = cb_cross(b.u, b.v);
    b.theta = theta;
    b.ch = CB_COS(CB_R(0.5) * theta);
    b.sh = CB_SIN(CB_R(0.5) * theta);
    b.rho = theta > CB_R(0.0) ? b.len / (CB_R(2.0) * b.sh) : CB_R(0.0);
    b.lscale = theta > CB_R(0.0) ? b.len / (b.rho * theta) : CB_R(1.0);
    return b;
}

#endif

CB_FN cb_vec3 cb_bend_apply(cb_bend b, cb_vec3 p, cb_real* J)
{
    cb_vec3 d = cb_sub(p, b.p0);
    cb_real x = cb_dot(d, b.u), y = cb_dot(d, b.v), z = cb_dot(d, b.w);
    /* theta == 0 (no bend) uses the identity; the arc quantities are then
     * unused, and the guards below keep them finite. */
    cb_mask straight = b.theta <= CB_R(0.0);
    cb_real h = CB_R(0.5) * b.theta;
    /* On the arc: polar coordinates about its centre, scaled by the
     * curvature kappa = 1 / rho so that nothing is of the arc's size: a bend
     * of 1e-4 degrees has rho = 5.7e5 L, and r - rho in float lost 0.03 L.
     * (X, Y) = kappa (x - L/2, y + rho cos(theta/2)), R = kappa r, and
     * y' = r - rho = (r^2 - rho^2) / (r + rho), with rho sin(theta/2) = L/2:
     * y' = (kappa (x (x - L) + y^2) + 2 y cos(theta/2)) / (R + 1). */
    cb_real kappa = cb_div0(CB_R(2.0) * b.sh, b.len);
    cb_real X = kappa * (x - CB_R(0.5) * b.len), Y = kappa * y + b.ch;
    cb_real R2 = X * X + Y * Y;
    cb_real R = CB_SQRT(R2);
    cb_real phi = CB_ATAN2(X, Y);
    cb_mask before = phi < -h;
    cb_mask after = phi > h;
    cb_real k = cb_div0(b.len, b.theta);
    cb_real a = (phi + h) * k;
    cb_real yp = (kappa * (x * (x - b.len) + y * y) + CB_R(2.0) * y * b.ch) / (R + CB_R(1.0));
    cb_real j00 = b.lscale * cb_div0(Y, R2), j01 = -b.lscale * cb_div0(X, R2);
    cb_real j10 = cb_div0(X, R), j11 = cb_div0(Y, R);
    /* before p0: along the start tangent */
    a = CB_SELECT(a, b.lscale * (x * b.ch + y * b.sh), before);
    yp = CB_SELECT(yp, -x * b.sh + y * b.ch, before);
    j00 = CB_SELECT(j00, b.lscale * b.ch, before);
    j01 = CB_SELECT(j01, b.lscale * b.sh, before);
    j10 = CB_SELECT(j10, -b.sh, before);
    j11 = CB_SELECT(j11, b.ch, before);
    /* beyond p1: along the end tangent */
    a = CB_SELECT(a, b.len + b.lscale * ((x - b.len) * b.ch - y * b.sh), after);
    yp = CB_SELECT(yp, (x - b.len) * b.sh + y * b.ch, after);
    j00 = CB_SELECT(j00, b.lscale * b.ch, after);
    j01 = CB_SELECT(j01, -b.lscale * b.sh, after);
    j10 = CB_SELECT(j10, b.sh, after);
    j11 = CB_SELECT(j11, b.ch, after);
    /* no bend at all */
    a = CB_SELECT(a, x, straight);
    yp = CB_SELECT(yp, y, straight);
    j00 = CB_SELECT(j00, CB_R(1.0), straight);
    j01 = CB_SELECT(j01, CB_R(0.0), straight);
    j10 = CB_SELECT(j10, CB_R(0.0), straight);
    j11 = CB_SELECT(j11, CB_R(1.0), straight);
    cb_frame_jacobian(b.u, b.v, b.w, cb_add(cb_scale(b.u, j00), cb_scale(b.v, j01)),
                      cb_add(cb_scale(b.u, j10), cb_scale(b.v, j11)), b.w, J);
    return cb_madd(cb_madd(cb_madd(b.p0, b.u, a), b.v, yp), b.w, z);
}

/* ---------------------------------------------------------------------------
 * `twist`: rotation about the axis (origin o, unit a) by an angle proportional
 * to the height h = a.(p - o): the child is evaluated at
 *   q = o + R(-rate h) (p - o),   J = R - rate (a x R(p - o)) a^T
 * (Rodrigues: d/dalpha R(alpha) v = a x R(alpha) v). */
typedef struct cb_twist {
    cb_vec3 o, a;
    cb_real rate;  /* radians per unit length */
    cb_real phase; /* the angle at o, in [-2 pi, 2 pi] (setup) */
} cb_twist;

#if CB_LANES == 1
/* The origin moved along the axis to the point nearest the frame's origin
 * and the angle it turned by kept as the phase: the same warp, whose
 * heights a.(p - o) stay as small as the model.  (Twisting about an origin
 * 1e7 away along the axis, the float angle lost 1000 degrees.)  a: unit. */
CB_FN cb_twist cb_twist_setup(cb_vec3 o, cb_vec3 a, cb_real rate)
{
    cb_twist t;
    cb_real along = cb_dot(o, a);
    t.o = cb_madd(o, a, -along);
    t.a = a;
    t.rate = rate;
    t.phase = CB_FMOD(rate * along, CB_R(6.283185307179586));
    return t;
}
#endif

CB_FN cb_vec3 cb_twist_apply(cb_twist t, cb_vec3 p, cb_real* J)
{
    cb_vec3 d = cb_sub(p, t.o);
    cb_real alpha = t.phase - t.rate * cb_dot(d, t.a);
    cb_real c = CB_COS(alpha), s = CB_SIN(alpha), oc = CB_R(1.0) - c;
    cb_vec3 a = t.a;
    cb_real R[9];
    R[0] = c + oc * a.x * a.x;
    R[1] = oc * a.x * a.y - s * a.z;
    R[2] = oc * a.x * a.z + s * a.y;
    R[3] = oc * a.y * a.x + s * a.z;
    R[4] = c + oc * a.y * a.y;
    R[5] = oc * a.y * a.z - s * a.x;
    R[6] = oc * a.z * a.x - s * a.y;
    R[7] = oc * a.z * a.y + s * a.x;
    R[8] = c + oc * a.z * a.z;
    cb_vec3 rd = cb_mat3_mul(R, d);
    cb_vec3 k = cb_scale(cb_cross(a, rd), -t.rate);
    J[0] = R[0] + k.x * a.x;
    J[1] = R[1] + k.x * a.y;
    J[2] = R[2] + k.x * a.z;
    J[3] = R[3] + k.y * a.x;
    J[4] = R[4] + k.y * a.y;
    J[5] = R[5] + k.y * a.z;
    J[6] = R[6] + k.z * a.x;
    J[7] = R[7] + k.z * a.y;
    J[8] = R[8] + k.z * a.z;
    return cb_add(t.o, rd);
}

/* ---------------------------------------------------------------------------
 * `taper`: the cross-section is scaled by s(h), linear from scale0 at h = 0 to
 * scale1 at h = len along the axis (origin o, unit a) and constant beyond.
 *   q = o + h a + d_perp / s(h),   d_perp = (p - o) - h a
 *   J = a a^T + (I - a a^T) / s - (s'/s^2) d_perp a^T. */
typedef struct cb_taper {
    cb_vec3 o, a;
    cb_real len, scale0, scale1;
    cb_real start; /* the height where the taper begins, from o (setup) */
} cb_taper;

#if CB_LANES == 1
/* As a twist's, the origin moved along the axis to the point nearest the
 * frame's origin, the taper's start kept as a height from it.  (With the
 * origin 1.4e7 away, the float distance from the axis lost whole units.) */
CB_FN cb_taper cb_taper_setup(cb_vec3 o, cb_vec3 a, cb_real len, cb_real scale0, cb_real scale1)
{
    cb_taper t;
    t.start = cb_dot(o, a);
    t.o = cb_madd(o, a, -t.start);
    t.a = a;
    t.len = len;
    t.scale0 = scale0;
    t.scale1 = scale1;
    return t;
}
#endif

/* The taper's scale at height h along its axis, from its origin o (the
 * host's bounds use it too). */
CB_FN cb_real cb_taper_scale(cb_real scale0, cb_real scale1, cb_real len, cb_real start, cb_real h)
{
    return scale0 + (scale1 - scale0) * cb_clamp01((h - start) / len);
}

CB_FN cb_vec3 cb_taper_apply(cb_taper t, cb_vec3 p, cb_real* J)
{
    cb_vec3 d = cb_sub(p, t.o);
    cb_real h = cb_dot(d, t.a);
    cb_real u = (h - t.start) / t.len;
    cb_real s = cb_taper_scale(t.scale0, t.scale1, t.len, t.start, h);
    cb_real ds =
        CB_SELECT(CB_R(0.0), (t.scale1 - t.scale0) / t.len, u > CB_R(0.0) && u < CB_R(1.0));
    cb_vec3 dp = cb_madd(d, t.a, -h);
    cb_vec3 a = t.a;
    cb_real is = CB_R(1.0) / s, k = -ds * is * is;
    cb_real aa[9];
    aa[0] = a.x * a.x;
    aa[1] = a.x * a.y;
    aa[2] = a.x * a.z;
    aa[3] = a.y * a.x;
    aa[4] = a.y * a.y;
    aa[5] = a.y * a.z;
    aa[6] = a.z * a.x;
    aa[7] = a.z * a.y;
    aa[8] = a.z * a.z;
    J[0] = aa[0] + (CB_R(1.0) - aa[0]) * is + k * dp.x * a.x;
    J[1] = aa[1] * (CB_R(1.0) - is) + k * dp.x * a.y;
    J[2] = aa[2] * (CB_R(1.0) - is) + k * dp.x * a.z;
    J[3] = aa[3] * (CB_R(1.0) - is) + k * dp.y * a.x;
    J[4] = aa[4] + (CB_R(1.0) - aa[4]) * is + k * dp.y * a.y;
    J[5] = aa[5] * (CB_R(1.0) - is) + k * dp.y * a.z;
    J[6] = aa[6] * (CB_R(1.0) - is) + k * dp.z * a.x;
    J[7] = aa[7] * (CB_R(1.0) - is) + k * dp.z * a.y;
    J[8] = aa[8] + (CB_R(1.0) - aa[8]) * is + k * dp.z * a.z;
    return cb_add(cb_madd(t.o, a, h), cb_scale(dp, is));
}

#endif /* CAMBIUM_CB_WARPS_H */
