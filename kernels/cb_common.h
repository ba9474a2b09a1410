/* cambium — portable scalar and vector helpers shared by the C++ reference
 * evaluator and the OpenCL kernels.
 *
 * Plain C99 that OpenCL C 1.2 also accepts (the same idea as NanoVDB's
 * PNanoVDB.h).  Two types:
 *
 * - cb_scalar: one number, a parameter read from a table;
 * - cb_real: the value at the points being evaluated.  On the host one point
 *   (double, so the reference evaluator is the precise oracle); in a kernel
 *   compiled with -D CB_LANES=8 or 16, that many points at once (float8,
 *   float16), because PoCL vectorises only what is written as vectors.
 *
 * The math is written without data-dependent branches (CB_SELECT instead of
 * if/?:) so the same text is correct for scalars and for vectors.  Scalars
 * widen implicitly where a cb_real is expected.
 *
 * Define CB_REAL_IS_FLOAT on the host to compile the float flavour.
 */
#ifndef CAMBIUM_CB_COMMON_H
#define CAMBIUM_CB_COMMON_H

#if defined(__OPENCL_VERSION__)
#ifndef CB_LANES
#define CB_LANES 1
#endif
typedef float cb_scalar;
#if CB_LANES == 16
typedef float16 cb_real;
typedef int16 cb_mask;
#elif CB_LANES == 8
typedef float8 cb_real;
typedef int8 cb_mask;
#elif CB_LANES == 4
typedef float4 cb_real;
typedef int4 cb_mask;
#elif CB_LANES == 1
typedef float cb_real;
typedef int cb_mask;
#else
#error "CB_LANES must be 1, 4, 8 or 16"
#endif
#define CB_R(x) (x##f)
#define CB_TINY 1e-37f /* smallest divisor worth dividing by */
#define CB_MATH(f) f   /* OpenCL's built-ins are overloaded */
/* select(a, b, c): b where c is true, a elsewhere */
#define CB_SELECT(a, b, c) select((cb_real)(a), (cb_real)(b), (c))
#if CB_LANES > 1
#define CB_ALL(c) all(c)
#define CB_ANY(c) any(c)
#else
#define CB_ALL(c) (c)
#define CB_ANY(c) (c)
#endif
#define CB_GLOBAL __global
#else /* host */
#include <math.h>
#define CB_LANES 1
#if defined(CB_REAL_IS_FLOAT)
typedef float cb_scalar;
#define CB_R(x) (x##f)
#define CB_TINY 1e-37f
#define CB_MATH(fn) fn##f /* sqrtf, atanf, ... */
#else
typedef double cb_scalar;
#define CB_R(x) (x)
#define CB_TINY 1e-300
#define CB_MATH(f) f
#endif
typedef cb_scalar cb_real;
typedef int cb_mask;
#define CB_SELECT(a, b, c) ((c) ? (cb_real)(b) : (cb_real)(a))
#define CB_ALL(c) (c)
#define CB_ANY(c) (c)
#define CB_GLOBAL
#endif

#define CB_SQRT CB_MATH(sqrt)
#define CB_ATAN CB_MATH(atan)
#define CB_ATAN2 CB_MATH(atan2)
#define CB_POW CB_MATH(pow)
#define CB_FMOD CB_MATH(fmod)
#define CB_FABS CB_MATH(fabs)
#define CB_SIN CB_MATH(sin)
#define CB_COS CB_MATH(cos)
#define CB_FMIN CB_MATH(fmin)
#define CB_FMAX CB_MATH(fmax)

/* Every helper is a static inline function: no symbols leak, and OpenCL C 1.2
 * accepts `static` on non-kernel functions. */
#define CB_FN static inline

#define CB_PI CB_R(3.14159265358979323846)

typedef struct cb_vec3 {
    cb_real x, y, z;
} cb_vec3;

CB_FN cb_vec3 cb_v3(cb_real x, cb_real y, cb_real z)
{
    cb_vec3 r;
    r.x = x;
    r.y = y;
    r.z = z;
    return r;
}
CB_FN cb_vec3 cb_add(cb_vec3 a, cb_vec3 b)
{
    return cb_v3(a.x + b.x, a.y + b.y, a.z + b.z);
}
CB_FN cb_vec3 cb_sub(cb_vec3 a, cb_vec3 b)
{
    return cb_v3(a.x - b.x, a.y - b.y, a.z - b.z);
}
CB_FN cb_vec3 cb_scale(cb_vec3 a, cb_real s)
{
    return cb_v3(a.x * s, a.y * s, a.z * s);
}
/* a + b * s */
CB_FN cb_vec3 cb_madd(cb_vec3 a, cb_vec3 b, cb_real s)
{
    return cb_v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s);
}
CB_FN cb_real cb_dot(cb_vec3 a, cb_vec3 b)
{
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
CB_FN cb_vec3 cb_cross(cb_vec3 a, cb_vec3 b)
{
    return cb_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
CB_FN cb_real cb_length(cb_vec3 a)
{
    return CB_SQRT(cb_dot(a, a));
}
CB_FN cb_real cb_clamp01(cb_real x)
{
    return CB_FMIN(CB_FMAX(x, CB_R(0.0)), CB_R(1.0));
}
/* x / y where y > 0, else 0: a division guarded lane by lane. */
CB_FN cb_real cb_div0(cb_real x, cb_real y)
{
    return CB_SELECT(CB_R(0.0), x / CB_FMAX(y, CB_TINY), y > CB_R(0.0));
}
CB_FN cb_vec3 cb_select3(cb_vec3 a, cb_vec3 b, cb_mask c)
{
    return cb_v3(CB_SELECT(a.x, b.x, c), CB_SELECT(a.y, b.y, c), CB_SELECT(a.z, b.z, c));
}

/* 3x3 matrices are row-major arrays of 9 reals: m[3*row + col]. */
CB_FN cb_vec3 cb_mat3_mul(const cb_real* m, cb_vec3 v)
{
    return cb_v3(m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
                 m[6] * v.x + m[7] * v.y + m[8] * v.z);
}
/* transpose(m) * v: how a gradient travels back through a warp whose
 * Jacobian is m (grad_p F(q(p)) = J^T grad_q F). */
CB_FN cb_vec3 cb_mat3_tmul(const cb_real* m, cb_vec3 v)
{
    return cb_v3(m[0] * v.x + m[3] * v.y + m[6] * v.z, m[1] * v.x + m[4] * v.y + m[7] * v.z,
                 m[2] * v.x + m[5] * v.y + m[8] * v.z);
}

#endif /* CAMBIUM_CB_COMMON_H */
