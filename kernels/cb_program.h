/* cambium — the field program: a BlobTree compiled to a flat instruction
 * stream, and its interpreter (no recursion, no pointers between nodes).
 *
 * Instructions are 4 ints { op, a, b, c }: `a` is an offset into the
 * parameter table (cb_scalar), `b` and `c` depend on the op.  The stream is
 * post-order: a primitive pushes its sample; an n-ary operator is
 *   OPEN  child ACC  child ACC ...  CLOSE
 * where OPEN pushes an accumulator, each ACC folds the child just evaluated
 * into it, and CLOSE finishes it, so the stack grows with the tree's depth and
 * not with its fan-out (a blend of 100,000 cones needs two entries).  A
 * generalized bounded blend is OPEN(gbb) child ACC ... bound-subtree CLOSE.
 * A warp is WARP subtree UNWARP: the subtree is evaluated at the warped point
 * and its gradient carried back through the warp's Jacobian.
 *
 * The parameter table starts with T, w^-1(T) and the constant 0; node blocks
 * follow (layouts below, written by src/field/program.cpp through the same
 * names).
 *
 * The same interpreter runs on the host (cb_real = double, one point: the CPU
 * path) and in kernels/sample.cl (cb_real = float8: eight voxels of a row).
 */
#ifndef CAMBIUM_CB_PROGRAM_H
#define CAMBIUM_CB_PROGRAM_H

#include "cb_common.h"
#include "cb_node_types.h"
#include "cb_operators.h"
#include "cb_primitives.h"
#include "cb_warps.h"

/* Opcodes.  Primitives use their node-type numbers (CB_SPHERE ... ), with
 * the parameter block at a and, for the host, the index of their support box
 * in c. */
#define CB_I_BARK_CONE \
    5                /* a cone with bark (cb_bark_cone_field), params at a; c as for primitives */
#define CB_I_CONST 8 /* push the constant prm[a] */
#define CB_I_OPEN                                                                                 \
    9                 /* push the accumulator of the operator whose block is at a; b = node type; \
                         c = index of the subtree's support box (host only) */
#define CB_I_ACC 10   /* fold the top entry into the accumulator below; c = 1 for the first child */
#define CB_I_CLOSE 11 /* finish the accumulator; b = node type */
#define CB_I_WARP 12  /* b = warp node type, params at a: warp the point; c as for OPEN */
#define CB_I_UNWARP 13 /* restore the point, carry the gradient back */

/* Parameter table header */
#define CB_P_T 0      /* the threshold T */
#define CB_P_XT 1     /* w^-1(T) */
#define CB_P_ZERO 2   /* the constant 0 */
#define CB_P_DETAIL 3 /* the shortest wavelength of procedural detail (bark); 0: no limit */
#define CB_P_HEADER 4

/* Node parameter blocks: the offset of every field in its block (a field of
 * three reals takes three slots), and the block's size.  The compiler in
 * src/field/program.cpp writes the blocks through these names, and the
 * interpreter below and the host's bounds read them through the same names,
 * so that a layout changes in one place.  Sizes follow from the last field. */
#define CB_CONST_VALUE 0
#define CB_CONST_SIZE (CB_CONST_VALUE + 1)

#define CB_SPHERE_CENTER 0 /* 3 */
#define CB_SPHERE_RADIUS 3
#define CB_SPHERE_SIGMA 4
#define CB_SPHERE_WEIGHT 5
#define CB_SPHERE_RGB 6 /* 3 */
#define CB_SPHERE_SIZE (CB_SPHERE_RGB + 3)

/* `cone` and `segment` (r0 == r1) */
#define CB_CONE_P0 0   /* 3 */
#define CB_CONE_AXIS 3 /* 3, unit */
#define CB_CONE_LEN 6
#define CB_CONE_R0 7
#define CB_CONE_R1 8
#define CB_CONE_SIGMA 9
#define CB_CONE_WEIGHT 10
#define CB_CONE_RGB 11 /* 3 */
#define CB_CONE_SIZE (CB_CONE_RGB + 3)

/* `cone` with bark: the cone's block, then the bark's */
#define CB_BARK_REF (CB_CONE_SIZE + 0) /* 3, unit, across the axis: theta = 0 */
#define CB_BARK_S0 (CB_CONE_SIZE + 3)  /* arc length of p0 along its branch */
#define CB_BARK_A0 (CB_CONE_SIZE + 4)  /* furrow depth at p0 */
#define CB_BARK_A1 (CB_CONE_SIZE + 5)  /* and at the tip */
#define CB_BARK_AROUND (CB_CONE_SIZE + 6)
#define CB_BARK_ALONG (CB_CONE_SIZE + 7)
#define CB_BARK_PHASE (CB_CONE_SIZE + 8)
#define CB_BARK_SIZE (CB_BARK_PHASE + 1)

/* `convolution_segment` */
#define CB_CONV_P0 0   /* 3 */
#define CB_CONV_AXIS 3 /* 3, unit */
#define CB_CONV_LEN 6
#define CB_CONV_Q0 7           /* density at p0 */
#define CB_CONV_Q1 8           /* density at the far end */
#define CB_CONV_KERNEL_WIDTH 9 /* the Cauchy kernel's s */
#define CB_CONV_SUPPORT 10     /* the window's radius */
#define CB_CONV_WEIGHT 11
#define CB_CONV_RGB 12 /* 3 */
#define CB_CONV_SIZE (CB_CONV_RGB + 3)

/* An operator's combiner; each operator reads the fields it needs. */
#define CB_OP_TYPE 0        /* the node type */
#define CB_OP_N 1           /* Ricci exponent */
#define CB_OP_WIDTH 2       /* PCM propagation width */
#define CB_OP_ATTENUATION 3 /* PCM attenuation */
#define CB_OP_K 4           /* better blend's k */
#define CB_OP_DARKEN 5      /* PCM ridge darkening */
#define CB_OP_SIZE (CB_OP_DARKEN + 1)

/* A generalized bounded blend: two combiner blocks */
#define CB_GBB_B1 0
#define CB_GBB_B2 CB_OP_SIZE
#define CB_GBB_SIZE (CB_GBB_B2 + CB_OP_SIZE)

/* `transform` */
#define CB_AFFINE_M 0 /* 12: M^-1 as a row-major 3x4 matrix */
#define CB_AFFINE_SIZE (CB_AFFINE_M + 12)

/* `bend`: a cb_bend */
#define CB_BEND_P0 0 /* 3 */
#define CB_BEND_U 3  /* 3 */
#define CB_BEND_V 6  /* 3 */
#define CB_BEND_W 9  /* 3 */
#define CB_BEND_LEN 12
#define CB_BEND_THETA 13
#define CB_BEND_RHO 14
#define CB_BEND_CH 15
#define CB_BEND_SH 16
#define CB_BEND_LSCALE 17
#define CB_BEND_SIZE (CB_BEND_LSCALE + 1)

/* `twist`: a cb_twist */
#define CB_TWIST_ORIGIN 0 /* 3 */
#define CB_TWIST_AXIS 3   /* 3, unit */
#define CB_TWIST_RATE 6
#define CB_TWIST_PHASE 7
#define CB_TWIST_SIZE (CB_TWIST_PHASE + 1)

/* `taper`: a cb_taper */
#define CB_TAPER_ORIGIN 0 /* 3 */
#define CB_TAPER_AXIS 3   /* 3, unit */
#define CB_TAPER_LEN 6
#define CB_TAPER_SCALE0 7
#define CB_TAPER_SCALE1 8
#define CB_TAPER_START 9
#define CB_TAPER_SIZE (CB_TAPER_START + 1)

/* A kernel that needs values only compiles with -D CB_GRADIENT=0 -D CB_COLOR=0:
 * the gradient and colour work below is then dead code the compiler removes. */
#ifndef CB_GRADIENT
#define CB_GRADIENT 1
#endif
#ifndef CB_COLOR
#define CB_COLOR 1
#endif

#ifndef CB_STACK_DEPTH
#define CB_STACK_DEPTH 32
#endif
#ifndef CB_WARP_DEPTH
#define CB_WARP_DEPTH 8
#endif

/* Colour accumulators use this big value as "no max/min yet". */
#define CB_HUGE CB_R(1e30)

typedef struct cb_sample {
    cb_real v;
    cb_vec3 g, c;
} cb_sample;

/* The value stack.  An entry is a sample (v, g, colour c) or an accumulator:
 * running value v and gradient g, a second sum v2 with gradient h (PCM's sum
 * of deformations), colour weighted sum c with weight sum cw. */
typedef struct cb_stack {
    cb_real v[CB_STACK_DEPTH], gx[CB_STACK_DEPTH], gy[CB_STACK_DEPTH], gz[CB_STACK_DEPTH];
    cb_real v2[CB_STACK_DEPTH], hx[CB_STACK_DEPTH], hy[CB_STACK_DEPTH], hz[CB_STACK_DEPTH];
    cb_real cr[CB_STACK_DEPTH], cg[CB_STACK_DEPTH], cb[CB_STACK_DEPTH], cw[CB_STACK_DEPTH];
} cb_stack;

CB_FN cb_vec3 cb_load3(CB_GLOBAL const cb_scalar* prm, int i)
{
    return cb_v3(prm[i], prm[i + 1], prm[i + 2]);
}

CB_FN void cb_push(cb_stack* s, int i, cb_real v, cb_vec3 g, cb_vec3 c)
{
    s->v[i] = v;
    if (CB_GRADIENT) {
        s->gx[i] = g.x;
        s->gy[i] = g.y;
        s->gz[i] = g.z;
    }
    if (CB_COLOR) {
        s->cr[i] = c.x;
        s->cg[i] = c.y;
        s->cb[i] = c.z;
    }
}

/* A primitive's colour exists where its field does: black where the field
 * is zero, so that folding zero fields away never changes a colour. */
CB_FN void cb_push_primitive(cb_stack* s, int i, cb_real v, cb_vec3 g,
                             CB_GLOBAL const cb_scalar* rgb)
{
    cb_real on = CB_SELECT(CB_R(0.0), CB_R(1.0), v != CB_R(0.0));
    cb_push(s, i, v, g, cb_scale(cb_v3(rgb[0], rgb[1], rgb[2]), on));
}

/* Starts an accumulator for an operator of type `type` in entry i. */
CB_FN void cb_acc_open(cb_stack* s, int i, int type)
{
    cb_real start = CB_R(0.0);
    if (type == CB_UNION || type == CB_PCM)
        start = -CB_HUGE;
    if (type == CB_INTERSECTION || type == CB_DIFFERENCE)
        start = CB_HUGE;
    s->v[i] = start;
    s->v2[i] = CB_R(0.0);
    if (CB_GRADIENT)
        s->gx[i] = s->gy[i] = s->gz[i] = s->hx[i] = s->hy[i] = s->hz[i] = CB_R(0.0);
    if (CB_COLOR)
        s->cr[i] = s->cg[i] = s->cb[i] = s->cw[i] = CB_R(0.0);
}

/* Adds weight w of the colour of entry j to the colour sums of accumulator i. */
CB_FN void cb_acc_color(cb_stack* s, int i, int j, cb_real w)
{
    if (!CB_COLOR)
        return;
    s->cr[i] += w * s->cr[j];
    s->cg[i] += w * s->cg[j];
    s->cb[i] += w * s->cb[j];
    s->cw[i] += w;
}

/* Where mask m holds, entry i takes value v, gradient (gx, gy, gz) and the colour of entry j. */
CB_FN void cb_acc_pick(cb_stack* s, int i, int j, cb_mask m, cb_real v, cb_real gx, cb_real gy,
                       cb_real gz, int takeColor)
{
    s->v[i] = CB_SELECT(s->v[i], v, m);
    if (CB_GRADIENT) {
        s->gx[i] = CB_SELECT(s->gx[i], gx, m);
        s->gy[i] = CB_SELECT(s->gy[i], gy, m);
        s->gz[i] = CB_SELECT(s->gz[i], gz, m);
    }
    if (CB_COLOR && takeColor) {
        s->cr[i] = CB_SELECT(s->cr[i], s->cr[j], m);
        s->cg[i] = CB_SELECT(s->cg[i], s->cg[j], m);
        s->cb[i] = CB_SELECT(s->cb[i], s->cb[j], m);
    }
}

/* Folds the sample in entry j into accumulator i of the operator block at op. */
CB_FN void cb_acc_fold(cb_stack* s, int i, int j, CB_GLOBAL const cb_scalar* op, cb_real T,
                       int first)
{
    int type = (int)op[CB_OP_TYPE];
    cb_real f = s->v[j], d;
    if (type == CB_BLEND) {
        s->v[i] += f;
        if (CB_GRADIENT) {
            s->gx[i] += s->gx[j];
            s->gy[i] += s->gy[j];
            s->gz[i] += s->gz[j];
        }
        cb_acc_color(s, i, j, CB_FABS(f));
    } else if (type == CB_RICCI) {
        /* The sums are kept relative to the largest child so far (v2): sum
         * (f_j / m)^n, which stays within [1, children] where f^n itself
         * would overflow (weight 1e6, n 64).  A larger child rescales them. */
        cb_real n = op[CB_OP_N], pos = CB_FMAX(f, CB_R(0.0));
        cb_real m = CB_FMAX(s->v2[i], pos);
        cb_real ka = cb_div0(s->v2[i], m), kb = cb_div0(pos, m);
        cb_real kag = CB_SELECT(CB_R(0.0), CB_POW(ka, n - CB_R(1.0)), ka > CB_R(0.0));
        cb_real kbg = CB_SELECT(CB_R(0.0), CB_POW(kb, n - CB_R(1.0)), kb > CB_R(0.0));
        cb_real kav = kag * ka, kbv = kbg * kb;
        s->v2[i] = m;
        s->v[i] = s->v[i] * kav + kbv;
        if (CB_GRADIENT) {
            s->gx[i] = s->gx[i] * kag + kbg * s->gx[j];
            s->gy[i] = s->gy[i] * kag + kbg * s->gy[j];
            s->gz[i] = s->gz[i] * kag + kbg * s->gz[j];
        }
        if (CB_COLOR) {
            s->cr[i] *= kav;
            s->cg[i] *= kav;
            s->cb[i] *= kav;
            s->cw[i] *= kav;
        }
        cb_acc_color(s, i, j, kbv);
    } else if (type == CB_UNION) {
        cb_acc_pick(s, i, j, f > s->v[i], f, s->gx[j], s->gy[j], s->gz[j], 1);
    } else if (type == CB_INTERSECTION) {
        cb_acc_pick(s, i, j, f < s->v[i], f, s->gx[j], s->gy[j], s->gz[j], 1);
    } else if (type == CB_DIFFERENCE) {
        if (first) {
            cb_acc_pick(s, i, j, f <= s->v[i], f, s->gx[j], s->gy[j], s->gz[j], 1);
        } else {
            cb_real c = cb_csg_complement(f, T);
            cb_acc_pick(s, i, j, c < s->v[i], c, -s->gx[j], -s->gy[j], -s->gz[j], 0);
        }
    } else if (type == CB_PCM) {
        /* F = f_max + sum_{j != max} D(f_j) = M - D(M) + sum_all D(f_j) */
        cb_acc_pick(s, i, j, f > s->v[i], f, s->gx[j], s->gy[j], s->gz[j], 0);
        cb_real D = cb_pcm_deformation(f, T, op[CB_OP_WIDTH], op[CB_OP_ATTENUATION], &d);
        s->v2[i] += D;
        if (CB_GRADIENT) {
            s->hx[i] += d * s->gx[j];
            s->hy[i] += d * s->gy[j];
            s->hz[i] += d * s->gz[j];
        }
        cb_acc_color(s, i, j, CB_FABS(f));
    } else if (type == CB_BETTER_BLEND) {
        cb_real g = cb_better_blend_g(f, T, op[CB_OP_K], &d);
        s->v[i] += g;
        if (CB_GRADIENT) {
            s->gx[i] += d * s->gx[j];
            s->gy[i] += d * s->gy[j];
            s->gz[i] += d * s->gz[j];
        }
        cb_acc_color(s, i, j, CB_FABS(g));
    }
}

/* Turns accumulator i into a sample. */
CB_FN void cb_acc_close(cb_stack* s, int i, CB_GLOBAL const cb_scalar* op, cb_real T)
{
    int type = (int)op[CB_OP_TYPE];
    if (type == CB_RICCI) {
        /* F = m sum^(1/n); dF = sum^((1 - n) / n) sum_j (f_j / m)^(n-1) df_j */
        cb_real n = op[CB_OP_N], sum = s->v[i];
        cb_real F = s->v2[i] * cb_ricci_finish(sum, n);
        cb_real k = CB_SELECT(CB_R(0.0), CB_POW(CB_FMAX(sum, CB_TINY), (CB_R(1.0) - n) / n),
                              sum > CB_R(0.0));
        s->v[i] = F;
        if (CB_GRADIENT) {
            s->gx[i] *= k;
            s->gy[i] *= k;
            s->gz[i] *= k;
        }
    } else if (type == CB_PCM) {
        cb_real d;
        cb_real D = cb_pcm_deformation(s->v[i], T, op[CB_OP_WIDTH], op[CB_OP_ATTENUATION], &d);
        if (CB_GRADIENT) {
            s->gx[i] += s->hx[i] - d * s->gx[i];
            s->gy[i] += s->hy[i] - d * s->gy[i];
            s->gz[i] += s->hz[i] - d * s->gz[i];
        }
        if (CB_COLOR) {
            /* v2 - D: how much the other children deform the strongest one */
            cb_real k = cb_pcm_ridge_shade(op[CB_OP_DARKEN], s->v2[i] - D, op[CB_OP_WIDTH]);
            s->cr[i] *= k;
            s->cg[i] *= k;
            s->cb[i] *= k;
        }
        s->v[i] += s->v2[i] - D;
    }
    if (CB_COLOR) {
        /* Field-weighted colour (CSG picked one child's already).  Like a
         * primitive's, a node's colour exists where its field does: black
         * where the value is zero, so folding a zero subtree to the constant 0
         * never changes a colour. */
        cb_real inv = CB_R(1.0);
        if (type != CB_UNION && type != CB_INTERSECTION && type != CB_DIFFERENCE)
            inv = cb_div0(CB_R(1.0), s->cw[i]);
        inv = CB_SELECT(inv, CB_R(0.0), s->v[i] == CB_R(0.0));
        s->cr[i] *= inv;
        s->cg[i] *= inv;
        s->cb[i] *= inv;
    }
}

/* Computes the warp of type `type` (params at w) at p: returns q, writes J. */
CB_FN cb_vec3 cb_warp_apply(int type, CB_GLOBAL const cb_scalar* w, cb_vec3 p, cb_real* J)
{
    int k;
    if (type == CB_TRANSFORM) {
        cb_affine a;
        for (k = 0; k < 12; ++k)
            a.m[k] = w[CB_AFFINE_M + k];
        return cb_affine_apply(a, p, J);
    }
    if (type == CB_BEND) {
        cb_bend b;
        b.p0 = cb_load3(w, CB_BEND_P0);
        b.u = cb_load3(w, CB_BEND_U);
        b.v = cb_load3(w, CB_BEND_V);
        b.w = cb_load3(w, CB_BEND_W);
        b.len = w[CB_BEND_LEN];
        b.theta = w[CB_BEND_THETA];
        b.rho = w[CB_BEND_RHO];
        b.ch = w[CB_BEND_CH];
        b.sh = w[CB_BEND_SH];
        b.lscale = w[CB_BEND_LSCALE];
        return cb_bend_apply(b, p, J);
    }
    if (type == CB_TWIST) {
        cb_twist t;
        t.o = cb_load3(w, CB_TWIST_ORIGIN);
        t.a = cb_load3(w, CB_TWIST_AXIS);
        t.rate = w[CB_TWIST_RATE];
        t.phase = w[CB_TWIST_PHASE];
        return cb_twist_apply(t, p, J);
    }
    {
        cb_taper t;
        t.o = cb_load3(w, CB_TAPER_ORIGIN);
        t.a = cb_load3(w, CB_TAPER_AXIS);
        t.len = w[CB_TAPER_LEN];
        t.scale0 = w[CB_TAPER_SCALE0];
        t.scale1 = w[CB_TAPER_SCALE1];
        t.start = w[CB_TAPER_START];
        return cb_taper_apply(t, p, J);
    }
}

/* Evaluates the program code[0 .. 4n) at p: field value, gradient and colour.
 * The host checks stack and warp depths when it compiles a program. */
CB_FN cb_sample cb_run_program(CB_GLOBAL const int* code, int n, CB_GLOBAL const cb_scalar* prm,
                               cb_vec3 p)
{
    cb_stack s;
    cb_vec3 wp[CB_WARP_DEPTH];
    cb_real wj[9 * CB_WARP_DEPTH];
    cb_real T = prm[CB_P_T], xT = prm[CB_P_XT];
    int top = -1, wtop = -1, pc;
    for (pc = 0; pc < n; ++pc) {
        int op = code[4 * pc], a = code[4 * pc + 1], b = code[4 * pc + 2];
        CB_GLOBAL const cb_scalar* q = prm + a;
        if (op == CB_SPHERE) {
            cb_vec3 g;
            cb_real f = cb_sphere_field(p, cb_load3(q, CB_SPHERE_CENTER), q[CB_SPHERE_RADIUS],
                                        q[CB_SPHERE_SIGMA], xT, &g);
            ++top;
            cb_push_primitive(&s, top, q[CB_SPHERE_WEIGHT] * f, cb_scale(g, q[CB_SPHERE_WEIGHT]),
                              q + CB_SPHERE_RGB);
        } else if (op == CB_SEGMENT || op == CB_CONE) {
            cb_vec3 g;
            cb_real f =
                cb_cone_field(p, cb_load3(q, CB_CONE_P0), cb_load3(q, CB_CONE_AXIS), q[CB_CONE_LEN],
                              q[CB_CONE_R0], q[CB_CONE_R1], q[CB_CONE_SIGMA], xT, &g);
            ++top;
            cb_push_primitive(&s, top, q[CB_CONE_WEIGHT] * f, cb_scale(g, q[CB_CONE_WEIGHT]),
                              q + CB_CONE_RGB);
        } else if (op == CB_I_BARK_CONE) {
            cb_vec3 g;
            cb_real f = cb_bark_cone_field(
                p, cb_load3(q, CB_CONE_P0), cb_load3(q, CB_CONE_AXIS), q[CB_CONE_LEN],
                q[CB_CONE_R0], q[CB_CONE_R1], q[CB_CONE_SIGMA], xT, cb_load3(q, CB_BARK_REF),
                q[CB_BARK_S0], q[CB_BARK_A0], q[CB_BARK_A1], q[CB_BARK_AROUND], q[CB_BARK_ALONG],
                q[CB_BARK_PHASE], prm[CB_P_DETAIL], &g);
            ++top;
            cb_push_primitive(&s, top, q[CB_CONE_WEIGHT] * f, cb_scale(g, q[CB_CONE_WEIGHT]),
                              q + CB_CONE_RGB);
        } else if (op == CB_CONVOLUTION_SEGMENT) {
            cb_vec3 g;
            cb_real f = cb_convolution_field(p, cb_load3(q, CB_CONV_P0), cb_load3(q, CB_CONV_AXIS),
                                             q[CB_CONV_LEN], q[CB_CONV_Q0], q[CB_CONV_Q1],
                                             q[CB_CONV_KERNEL_WIDTH], q[CB_CONV_SUPPORT], &g);
            ++top;
            cb_push_primitive(&s, top, q[CB_CONV_WEIGHT] * f, cb_scale(g, q[CB_CONV_WEIGHT]),
                              q + CB_CONV_RGB);
        } else if (op == CB_I_CONST) {
            ++top;
            cb_push(&s, top, q[CB_CONST_VALUE], cb_v3(CB_R(0.0), CB_R(0.0), CB_R(0.0)),
                    cb_v3(CB_R(0.0), CB_R(0.0), CB_R(0.0)));
        } else if (op == CB_I_OPEN) {
            if (b == CB_GBB) {
                cb_acc_open(&s, top + 1, (int)q[CB_GBB_B1 + CB_OP_TYPE]);
                cb_acc_open(&s, top + 2, (int)q[CB_GBB_B2 + CB_OP_TYPE]);
                top += 2;
            } else {
                ++top;
                cb_acc_open(&s, top, b);
            }
        } else if (op == CB_I_ACC) {
            if (b == CB_GBB) {
                cb_acc_fold(&s, top - 2, top, q + CB_GBB_B1, T, code[4 * pc + 3]);
                cb_acc_fold(&s, top - 1, top, q + CB_GBB_B2, T, code[4 * pc + 3]);
            } else {
                cb_acc_fold(&s, top - 1, top, q, T, code[4 * pc + 3]);
            }
            --top;
        } else if (op == CB_I_CLOSE) {
            if (b == CB_GBB) {
                /* stack: B1 accumulator, B2 accumulator, bounding field */
                int i1 = top - 2, i2 = top - 1;
                cb_real fb = s.v[top], dFb, bb;
                cb_acc_close(&s, i1, q + CB_GBB_B1, T);
                cb_acc_close(&s, i2, q + CB_GBB_B2, T);
                bb = cb_clamp01(fb);
                s.v[i1] = cb_gbb(fb, s.v[i1], s.v[i2], &dFb);
                if (CB_GRADIENT) {
                    s.gx[i1] = bb * s.gx[i1] + (CB_R(1.0) - bb) * s.gx[i2] + dFb * s.gx[top];
                    s.gy[i1] = bb * s.gy[i1] + (CB_R(1.0) - bb) * s.gy[i2] + dFb * s.gy[top];
                    s.gz[i1] = bb * s.gz[i1] + (CB_R(1.0) - bb) * s.gz[i2] + dFb * s.gz[top];
                }
                if (CB_COLOR) {
                    cb_real on = CB_SELECT(CB_R(1.0), CB_R(0.0), s.v[i1] == CB_R(0.0));
                    s.cr[i1] = on * (bb * s.cr[i1] + (CB_R(1.0) - bb) * s.cr[i2]);
                    s.cg[i1] = on * (bb * s.cg[i1] + (CB_R(1.0) - bb) * s.cg[i2]);
                    s.cb[i1] = on * (bb * s.cb[i1] + (CB_R(1.0) - bb) * s.cb[i2]);
                }
                top -= 2;
            } else {
                cb_acc_close(&s, top, q, T);
            }
        } else if (op == CB_I_WARP) {
            ++wtop;
            wp[wtop] = p;
            p = cb_warp_apply(b, q, p, wj + 9 * wtop);
        } else if (op == CB_I_UNWARP) {
            if (CB_GRADIENT) {
                cb_vec3 g = cb_mat3_tmul(wj + 9 * wtop, cb_v3(s.gx[top], s.gy[top], s.gz[top]));
                s.gx[top] = g.x;
                s.gy[top] = g.y;
                s.gz[top] = g.z;
            }
            p = wp[wtop];
            --wtop;
        }
    }
    {
        cb_sample out;
        out.v = s.v[0];
        out.g = out.c = cb_v3(CB_R(0.0), CB_R(0.0), CB_R(0.0));
        if (CB_GRADIENT)
            out.g = cb_v3(s.gx[0], s.gy[0], s.gz[0]);
        if (CB_COLOR)
            out.c = cb_v3(s.cr[0], s.cg[0], s.cb[0]);
        return out;
    }
}

/* A surface voxel's sample (sample_surface and its CPU reference, the
 * sampler's CPU path): one Newton step from p toward F = T along the
 * gradient, at most `reach` long, into *step, and the program's sample where
 * it lands.  The field's first-order distance at p is off by a fifth of a
 * voxel where F is far from linear across a voxel (twigs a voxel or two
 * thick, blends); a second step from the landing point (the host's, with the
 * sample returned) is off by a fiftieth, and its gradient is the surface's
 * normal there rather than the field's at the voxel.  The loop evaluates the
 * program from one place in the code, not two. */
CB_FN cb_sample cb_surface_step(CB_GLOBAL const int* code, int n, CB_GLOBAL const cb_scalar* prm,
                                cb_vec3 p, cb_real reach, cb_vec3* step)
{
    cb_sample s;
    int i;
    *step = cb_v3(CB_R(0.0), CB_R(0.0), CB_R(0.0));
    for (i = 0; i < 2; ++i) {
        if (i == 1) {
            cb_real g2 = cb_dot(s.g, s.g);
            cb_real k = cb_div0(prm[CB_P_T] - s.v, g2); /* the step is k grad F */
            cb_real len = CB_FABS(k) * CB_SQRT(g2);
            k = CB_SELECT(k, k * cb_div0(reach, len), len > reach);
            *step = cb_scale(s.g, k);
        }
        s = cb_run_program(code, n, prm, cb_add(p, *step));
    }
    return s;
}

#endif /* CAMBIUM_CB_PROGRAM_H */
