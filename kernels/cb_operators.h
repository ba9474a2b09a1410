/* cambium — per-operation math of the BlobTree operators.
 *
 * Each function gives the value of one step of an operator and the partial
 * derivatives with respect to its inputs, so that an evaluator can carry
 * gradients by the chain rule (grad F = sum dF/df_i grad f_i) or drop them.
 * See docs/field-conventions.md for the definitions and their sources.
 */
#ifndef CAMBIUM_CB_OPERATORS_H
#define CAMBIUM_CB_OPERATORS_H

#include "cb_common.h"

/* ---------------------------------------------------------------------------
 * Super-elliptic (Ricci) blend, paper 003 eq. 2:  F = (sum f_i^n)^(1/n).
 * Negative child values (scars) are clamped to 0 first: the power of a
 * negative field is not defined for real n.  Accumulate cb_ricci_term over
 * the children, then finish; dF/df_i = (f_i / F)^(n-1) for f_i > 0. */
CB_FN cb_real cb_ricci_term(cb_real f, cb_real n)
{
    return CB_POW(CB_FMAX(f, CB_R(0.0)), n);
}
CB_FN cb_real cb_ricci_finish(cb_real sum, cb_real n)
{
    return CB_POW(CB_FMAX(sum, CB_R(0.0)), CB_R(1.0) / n);
}
CB_FN cb_real cb_ricci_partial(cb_real f, cb_real F, cb_real n)
{
    return CB_SELECT(CB_R(0.0), CB_POW(cb_div0(CB_FMAX(f, CB_R(0.0)), F), n - CB_R(1.0)),
                     f > CB_R(0.0) && F > CB_R(0.0));
}

/* ---------------------------------------------------------------------------
 * CSG on fields where inside is F > T: union = max, intersection = min,
 * difference A - B = min(F_A, 2T - F_B).  2T - F reflects a field about the
 * threshold, so it is the complement solid with the same surface. */
CB_FN cb_real cb_csg_complement(cb_real f, cb_real T)
{
    return CB_R(2.0) * T - f;
}

/* ---------------------------------------------------------------------------
 * Precise Contact Modeling (Gascuel 1993; papers 001 sec. 2.3, 002 sec. 3.3,
 * 003 sec. 2.3).  The deformation that a field f_j (the "other" object) adds
 * to the field it presses on, as a function of s = T - f_j:
 *   s <= 0        (inside the other object, interpenetration): D = s = T - f_j,
 *                 so the deformed field f_i + T - f_j equals T exactly where
 *                 f_i = f_j: the contact surface.
 *   0 < s < w     (propagation region, width w in field units):
 *                 D = s (1 - s/w)^k  > 0, a bulge,
 *   s >= w        D = 0 (undeformed).
 * D and dD/ds are continuous at s = 0 (value 0, slope 1) and at s = w (value 0,
 * slope 0 for k > 1), so the deformed field is C1 wherever f_j is.  k is the
 * attenuation: the bulge peaks at s = w/(k+1) with height w k^k/(k+1)^(k+1)
 * (4w/27 for k = 2) and larger k pulls it closer to the contact and lower.
 * Requires 0 < w <= T so that D vanishes where f_j = 0.  *dD receives dD/df_j. */
CB_FN cb_real cb_pcm_deformation(cb_real f_other, cb_real T, cb_real w, cb_real k, cb_real* dD)
{
    cb_real s = T - f_other;
    cb_real x = cb_clamp01(s / w);
    cb_real om = CB_R(1.0) - x;
    cb_real pk1 = CB_POW(om, k - CB_R(1.0));
    cb_mask inside = s <= CB_R(0.0);
    /* d/ds [s (1-x)^k] = (1-x)^(k-1) (1 - (k+1) x), zero from s = w on */
    *dD = CB_SELECT(pk1 * ((k + CB_R(1.0)) * x - CB_R(1.0)), CB_R(-1.0), inside);
    return CB_SELECT(s * pk1 * om, s, inside);
}

/* The PCM colour ridge (paper 000 section 3.2): where the other children
 * deform the strongest one by `deformation` (pressing it in at the contact,
 * swelling it around), its colour darkens by up to `darken`, fully where the
 * deformation reaches a tenth of the propagation width w.  Returns the factor
 * the colour is multiplied by, 1 - darken clamp(10 |deformation| / w, 0, 1):
 * one expression, so that a compiler that fuses multiply-adds (OpenCL's
 * contraction, -cl-mad-enable) fuses the kernel's and the host's alike. */
CB_FN cb_real cb_pcm_ridge_shade(cb_real darken, cb_real deformation, cb_real w)
{
    return CB_R(1.0) - darken * cb_clamp01(CB_R(10.0) * CB_FABS(deformation) / w);
}

/* ---------------------------------------------------------------------------
 * "Better blending" remapping, paper 002 eq. 6 (after Wyvill & Wyvill 2000):
 *   g_k(t) = 0                   t < k
 *          = h_k(t)              k <= t <= c,      h_k(t) = c ((t - k)/(c - k))^2
 *          = 2c - h_k(2c - t)    c < t <= 2c - k
 *          = 2c                  t > 2c - k
 * with c = T.  g_k(c) = c keeps each isolated surface where it was; values
 * below k (the far field that makes blends bulge) vanish.  C1.  Negative
 * values (scars) use the odd extension g(-t) = -g(t).  *dg receives g'(t). */
CB_FN cb_real cb_better_blend_g(cb_real t, cb_real c, cb_real k, cb_real* dg)
{
    cb_real a = CB_FABS(t);
    cb_mask low = a <= c;
    /* b folds the upper half onto the lower: h_k is evaluated at a or 2c - a. */
    cb_real b = CB_SELECT(CB_R(2.0) * c - a, a, low);
    cb_real u = cb_clamp01((b - k) / (c - k));
    cb_real h = c * u * u;
    *dg = CB_R(2.0) * c * u / (c - k);
    return CB_SELECT(CB_R(1.0), CB_R(-1.0), t < CB_R(0.0)) * CB_SELECT(CB_R(2.0) * c - h, h, low);
}

/* ---------------------------------------------------------------------------
 * Generalized bounded blending, paper 000 eq. 2-4:
 *   Fg = b B1 + (1 - b) B2,  b = clamp(Fb, 0, 1).
 * Writes dFg/dFb (zero where the bound is clamped). */
CB_FN cb_real cb_gbb(cb_real fb, cb_real b1, cb_real b2, cb_real* dFb)
{
    cb_real b = cb_clamp01(fb);
    *dFb = CB_SELECT(CB_R(0.0), b1 - b2, fb > CB_R(0.0) && fb < CB_R(1.0));
    return b * b1 + (CB_R(1.0) - b) * b2;
}

#endif /* CAMBIUM_CB_OPERATORS_H */
