/* Compiles the shared per-operation headers as strict C99 (-std=c99 -pedantic
 * -Werror) and exposes a few entry points, so the C++ tests can check that the
 * C translation computes what the C++ one does. */
#include "cb_node_types.h"
#include "cb_operators.h"
#include "cb_primitives.h"
#include "cb_warps.h"

double cb_c99_wyvill(double x)
{
    double dw;
    return cb_wyvill(x, &dw);
}

double cb_c99_cone(const double p[3], const double a[3], const double b[3], double r0, double r1)
{
    cb_vec3 axis = cb_sub(cb_v3(b[0], b[1], b[2]), cb_v3(a[0], a[1], a[2]));
    cb_real len = cb_length(axis);
    cb_vec3 g;
    return cb_cone_field(cb_v3(p[0], p[1], p[2]), cb_v3(a[0], a[1], a[2]),
                         cb_scale(axis, 1.0 / len), len, r0, r1, 1.0, 0.5, &g);
}

double cb_c99_pcm_deformation(double f_other, double T, double w, double k)
{
    double d;
    return cb_pcm_deformation(f_other, T, w, k, &d);
}

int cb_c99_opcode_pcm(void)
{
    return CB_PCM;
}
