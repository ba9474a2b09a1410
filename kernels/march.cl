/* cambium — ray marching a level set through NanoVDB's hierarchical DDA.
 *
 * One work-item per ray.  The grid is a NanoVDB copy of the baked level set
 * (signed distance, negative inside), read through PNanoVDB.h.  A ray is
 * taken to index space (the grid's own map), clipped to the bounding box of
 * the active voxels, and walked with PNanoVDB's HDDA: a step spans a whole
 * empty node (4096^3 root tile, 128^3 or 8^3 tile) where the tree has no
 * leaf, and one voxel cell inside leaves.  A lower node whose active bounds
 * the ray misses is stepped over, one it meets further on jumped to, and a
 * leaf more than two voxels from the surface stepped over as a tile
 * (cb_locate, cb_node_dim).  In a leaf the trilinear
 * interpolant of the distances is evaluated where the ray leaves each cell;
 * where its sign changes, the crossing is refined by regula falsi (Illinois)
 * on the interpolant along the ray.  This is the linear search of OpenVDB's
 * LevelSetRayIntersector, the CPU reference (src/use/render.cpp), which
 * tests/test_render.cpp compares it with.
 *
 * Output per ray (8 floats): the world-space distance to the hit (-1 when the
 * ray misses), the unit world-space normal (the gradient of the trilinear
 * interpolant, OpenVDB's BoxStencil gradient), and the albedo (trilinear Cd
 * when a colour grid is given, else `albedo`).
 */
#include "cb_pnanovdb.h"

#define CB_INLINE static inline __attribute__((always_inline))

typedef struct {
    pnanovdb_buf_t buf;
    pnanovdb_readaccessor_t acc;
    pnanovdb_grid_type_t type;
    /* The last leaf read (float grids): its origin and its value table. */
    int3 leafOrigin;
    __global const float* leafTable;
} cb_nano_t;

CB_INLINE cb_nano_t cb_nano_open(__global const uint* data, pnanovdb_grid_type_t type)
{
    cb_nano_t g;
    g.buf.data = data;
    g.type = type;
    pnanovdb_grid_handle_t grid = {pnanovdb_address_null()};
    pnanovdb_readaccessor_init(&g.acc,
                               pnanovdb_tree_get_root(g.buf, pnanovdb_grid_get_tree(g.buf, grid)));
    g.leafOrigin = (int3)(1); /* no leaf: leaf origins are multiples of 8 */
    g.leafTable = 0;
    return g;
}

/* The value of a float grid at voxel c: from the last leaf's table when c is
 * in it, else through the accessor (which then caches c's leaf). */
CB_INLINE float cb_value(cb_nano_t* g, int3 c)
{
    if (all((c & ~7) == g->leafOrigin))
        return g->leafTable[((c.x & 7) << 6) | ((c.y & 7) << 3) | (c.z & 7)];
    pnanovdb_uint32_t level = 0;
    const pnanovdb_coord_t ijk = {c.x, c.y, c.z};
    const pnanovdb_address_t a =
        pnanovdb_readaccessor_get_value_address_and_level(g->type, g->buf, &g->acc, &ijk, &level);
    __global const float* v = (__global const float*)g->buf.data + (a.byte_offset >> 2);
    if (level == 0) {
        g->leafOrigin = c & ~7;
        g->leafTable = v - (((c.x & 7) << 6) | ((c.y & 7) << 3) | (c.z & 7));
    }
    return *v;
}

CB_INLINE pnanovdb_address_t cb_nano_address(cb_nano_t* g, int x, int y, int z)
{
    pnanovdb_coord_t ijk = {x, y, z};
    return pnanovdb_readaccessor_get_value_address(g->type, g->buf, &g->acc, &ijk);
}

CB_INLINE float3 cb_nano_vec3(cb_nano_t* g, int x, int y, int z)
{
    const pnanovdb_address_t a = cb_nano_address(g, x, y, z);
    return (float3)(pnanovdb_read_float(g->buf, a),
                    pnanovdb_read_float(g->buf, pnanovdb_address_offset(a, 4u)),
                    pnanovdb_read_float(g->buf, pnanovdb_address_offset(a, 8u)));
}

/* The trilinear interpolant of a float grid at index-space p, and its
 * gradient there when `grad` is not null. */
CB_INLINE float cb_trilinear(cb_nano_t* g, float3 p, float3* grad)
{
    const float3 f0 = floor(p);
    const float3 u = p - f0;
    const int3 c = convert_int3(f0);
    float v000, v001, v010, v011, v100, v101, v110, v111;
    if (all((c & ~7) == g->leafOrigin) && all((c & 7) != 7)) {
        /* All eight corners in the last leaf: its table, x-major. */
        __global const float* t = g->leafTable + (((c.x & 7) << 6) | ((c.y & 7) << 3) | (c.z & 7));
        v000 = t[0];
        v001 = t[1];
        v010 = t[8];
        v011 = t[9];
        v100 = t[64];
        v101 = t[65];
        v110 = t[72];
        v111 = t[73];
    } else {
        v000 = cb_value(g, c);
        v001 = cb_value(g, c + (int3)(0, 0, 1));
        v010 = cb_value(g, c + (int3)(0, 1, 0));
        v011 = cb_value(g, c + (int3)(0, 1, 1));
        v100 = cb_value(g, c + (int3)(1, 0, 0));
        v101 = cb_value(g, c + (int3)(1, 0, 1));
        v110 = cb_value(g, c + (int3)(1, 1, 0));
        v111 = cb_value(g, c + (int3)(1, 1, 1));
    }
    const float a00 = mix(v000, v001, u.z), a01 = mix(v010, v011, u.z);
    const float a10 = mix(v100, v101, u.z), a11 = mix(v110, v111, u.z);
    const float b0 = mix(a00, a01, u.y), b1 = mix(a10, a11, u.y);
    if (grad) {
        const float gz =
            mix(mix(v001 - v000, v011 - v010, u.y), mix(v101 - v100, v111 - v110, u.y), u.x);
        const float gy = mix(a01 - a00, a11 - a10, u.x);
        *grad = (float3)(b1 - b0, gy, gz);
    }
    return mix(b0, b1, u.x);
}

CB_INLINE float3 cb_trilinear3(cb_nano_t* g, float3 p)
{
    const float3 f0 = floor(p);
    const float3 u = p - f0;
    const int x = (int)f0.x, y = (int)f0.y, z = (int)f0.z;
    const float3 a00 = mix(cb_nano_vec3(g, x, y, z), cb_nano_vec3(g, x, y, z + 1), u.z);
    const float3 a01 = mix(cb_nano_vec3(g, x, y + 1, z), cb_nano_vec3(g, x, y + 1, z + 1), u.z);
    const float3 a10 = mix(cb_nano_vec3(g, x + 1, y, z), cb_nano_vec3(g, x + 1, y, z + 1), u.z);
    const float3 a11 =
        mix(cb_nano_vec3(g, x + 1, y + 1, z), cb_nano_vec3(g, x + 1, y + 1, z + 1), u.z);
    return mix(mix(a00, a01, u.y), mix(a10, a11, u.y), u.x);
}

/* The interpolant at p, a point on the face of voxel cell `cell` where the
 * ray leaves it across `axis` (towards +axis when `up`): the bilinear
 * interpolant of the face's four corners, which is the trilinear one there. */
CB_INLINE float cb_face(cb_nano_t* g, int3 cell, int axis, int up, float3 p)
{
    const float3 u = clamp(p - convert_float3(cell), 0.0f, 1.0f);
    int3 c = cell, e1, e2;
    float u1, u2;
    if (axis == 0) {
        c.x += up;
        e1 = (int3)(0, 1, 0);
        e2 = (int3)(0, 0, 1);
        u1 = u.y;
        u2 = u.z;
    } else if (axis == 1) {
        c.y += up;
        e1 = (int3)(1, 0, 0);
        e2 = (int3)(0, 0, 1);
        u1 = u.x;
        u2 = u.z;
    } else {
        c.z += up;
        e1 = (int3)(1, 0, 0);
        e2 = (int3)(0, 1, 0);
        u1 = u.x;
        u2 = u.y;
    }
    const float v00 = cb_value(g, c), v10 = cb_value(g, c + e1);
    const float v01 = cb_value(g, c + e2), v11 = cb_value(g, c + e1 + e2);
    return mix(mix(v00, v10, u1), mix(v01, v11, u1), u2);
}

static pnanovdb_vec3_t cb_pv(float3 v)
{
    pnanovdb_vec3_t r = {v.x, v.y, v.z};
    return r;
}

static float3 cb_fv(pnanovdb_vec3_t v)
{
    return (float3)(v.x, v.y, v.z);
}

static float3 cb_world_to_index(pnanovdb_buf_t buf, float3 w)
{
    const pnanovdb_grid_handle_t grid = {pnanovdb_address_null()};
    const pnanovdb_vec3_t p = cb_pv(w);
    return cb_fv(pnanovdb_grid_world_to_indexf(buf, grid, &p));
}

/* Points the DDA at the node of size `dim` that holds voxel ijk: its corner,
 * and the ray parameters at which it leaves the node through each axis
 * (pnanovdb_hdda_update recomputes the node from the ray's position instead;
 * on a node's face that position can round into the neighbour, whose size
 * was not looked up, and a leaf would be skipped). */
static void cb_hdda_enter(pnanovdb_hdda_t* h, float3 o, float3 inv, pnanovdb_coord_t ijk, int dim)
{
    h->dim = dim;
    h->voxel.x = ijk.x & ~(dim - 1);
    h->voxel.y = ijk.y & ~(dim - 1);
    h->voxel.z = ijk.z & ~(dim - 1);
    h->next.x = h->step.x == 0
                    ? PNANOVDB_HDDA_FLOAT_MAX
                    : ((float)(h->step.x > 0 ? h->voxel.x + dim : h->voxel.x) - o.x) * inv.x;
    h->next.y = h->step.y == 0
                    ? PNANOVDB_HDDA_FLOAT_MAX
                    : ((float)(h->step.y > 0 ? h->voxel.y + dim : h->voxel.y) - o.y) * inv.y;
    h->next.z = h->step.z == 0
                    ? PNANOVDB_HDDA_FLOAT_MAX
                    : ((float)(h->step.z > 0 ? h->voxel.z + dim : h->voxel.z) - o.z) * inv.z;
}

/* The voxel at o + t d, kept inside [lo, lo + size). */
static pnanovdb_coord_t cb_voxel_in(float3 o, float3 d, float t, int3 lo, int size)
{
    const int3 v = clamp(convert_int3_rtn(o + t * d), lo, lo + (size - 1));
    const pnanovdb_coord_t c = {v.x, v.y, v.z};
    return c;
}

/* The size of the node the DDA steps through at voxel ijk: 1 in a leaf
 * (cell by cell), the tile's size elsewhere.  A leaf whose smallest value is
 * above `skip` is stepped over as a tile: two voxel sizes from the surface
 * everywhere, no cell it starts can hold a crossing, even with neighbours'
 * corners (the values are distances, adjacent ones differ by about a voxel). */
CB_INLINE int cb_node_dim(cb_nano_t* g, pnanovdb_coord_t ijk, float skip)
{
    const int dim = (int)pnanovdb_readaccessor_get_dim(g->type, g->buf, &g->acc, &ijk);
    if (dim == 1 && pnanovdb_read_float(
                        g->buf, pnanovdb_leaf_get_min_address(g->type, g->buf, g->acc.leaf)) > skip)
        return 8;
    return dim;
}

/* Where the ray is at h->tmin: the voxel (kept inside the node [lo, lo +
 * size) the DDA is in) and the size of its node.  Entering a lower node
 * (128^3) the ray is clipped to the bounds of its active voxels: when it
 * misses them the whole node is stepped over, and when it meets them further
 * on it jumps there (h->tmin moves; nothing between can cross the surface). */
CB_INLINE int cb_locate(cb_nano_t* g, pnanovdb_hdda_t* h, float3 o, float3 d, float3 inv,
                        float tmax, float skip, int3 lo, int size, int3* lower,
                        pnanovdb_coord_t* ijk)
{
    for (;;) {
        *ijk = cb_voxel_in(o, d, h->tmin, lo, size);
        const int dim = cb_node_dim(g, *ijk, skip);
        const int3 node = (int3)(ijk->x, ijk->y, ijk->z) & ~127;
        if (dim > 8 || all(node == *lower))
            return dim;
        /* A new lower node: the slab test against its active bounds. */
        *lower = node;
        const pnanovdb_coord_t bmin = pnanovdb_lower_get_bbox_min(g->buf, g->acc.lower);
        const pnanovdb_coord_t bmax = pnanovdb_lower_get_bbox_max(g->buf, g->acc.lower);
        const float3 t0 = ((float3)(bmin.x, bmin.y, bmin.z) - o) * inv;
        const float3 t1 = ((float3)(bmax.x + 1, bmax.y + 1, bmax.z + 1) - o) * inv;
        const float3 tn = fmin(t0, t1), tf = fmax(t0, t1);
        const float enter = fmax(fmax(tn.x, tn.y), tn.z), leave = fmin(fmin(tf.x, tf.y), tf.z);
        if (!(enter <= leave) || leave < h->tmin || enter > tmax)
            return 128; /* misses the node's voxels: step over the node */
        if (!(enter > h->tmin + 1.0f))
            return dim;
        h->tmin = enter; /* jump to its voxels, then look again */
        lo = node;
        size = 128;
    }
}

/* The first zero crossing of the interpolant along o + t d (index space, d a
 * unit vector) for t in [tmin, tmax]: its t, or -1. */
static float cb_march(cb_nano_t* g, float3 o, float3 d, float tmin, float tmax, float skip)
{
    const pnanovdb_vec3_t po = cb_pv(o), pd = cb_pv(d);
    /* The cells whose corners are all inside the active voxels' bounds. */
    const pnanovdb_coord_t bmin = pnanovdb_root_get_bbox_min(g->buf, g->acc.root);
    const pnanovdb_coord_t bmax = pnanovdb_root_get_bbox_max(g->buf, g->acc.root);
    const pnanovdb_vec3_t lo = {bmin.x, bmin.y, bmin.z}, hi = {bmax.x, bmax.y, bmax.z};
    if (!pnanovdb_hdda_ray_clip(&lo, &hi, &po, &tmin, &pd, &tmax) || !(tmin <= tmax))
        return -1.0f;
    const float3 inv = 1.0f / d;

    /* Step directions and increments from PNanoVDB, then the node at the start. */
    pnanovdb_hdda_t h;
    pnanovdb_hdda_init(&h, &po, tmin, &pd, tmax, 1);
    const int3 bbLo = (int3)(bmin.x, bmin.y, bmin.z);
    const int bbSize = max(max(bmax.x - bmin.x, bmax.y - bmin.y), bmax.z - bmin.z) + 1;
    int3 lower = (int3)(1); /* the last lower node whose bounds were tested */
    pnanovdb_coord_t ijk;
    int dim = cb_locate(g, &h, o, d, inv, tmax, skip, bbLo, bbSize, &lower, &ijk);
    cb_hdda_enter(&h, o, inv, ijk, dim);
    float tA = h.tmin;
    float vA = dim == 1 ? cb_trilinear(g, o + tA * d, 0) : cb_value(g, (int3)(ijk.x, ijk.y, ijk.z));
    int3 leaf = (int3)(ijk.x, ijk.y, ijk.z) & ~7;
    for (;;) {
        if (h.dim == 1) {
            /* A voxel cell: the interpolant where the ray leaves it. */
            const int axis =
                h.next.x < h.next.y ? (h.next.x < h.next.z ? 0 : 2) : (h.next.y < h.next.z ? 1 : 2);
            const float tExit = axis == 0 ? h.next.x : axis == 1 ? h.next.y : h.next.z;
            const int up = (axis == 0 ? h.step.x : axis == 1 ? h.step.y : h.step.z) > 0;
            const int3 cell = (int3)(h.voxel.x, h.voxel.y, h.voxel.z);
            const float tB = fmin(tExit, tmax);
            const float vB = tExit <= tmax ? cb_face(g, cell, axis, up, o + tB * d)
                                           : cb_trilinear(g, o + tB * d, 0);
            if ((vA < 0.0f) != (vB < 0.0f)) {
                /* Regula falsi, Illinois variant, on the interpolant. */
                float a = tA, fa = vA, b = tB, fb = vB;
                int side = 0;
                for (int k = 0; k < 10 && b - a > 1e-5f; ++k) {
                    const float t = (a * fb - b * fa) / (fb - fa);
                    const float ft = cb_trilinear(g, o + t * d, 0);
                    if ((ft < 0.0f) == (fb < 0.0f)) {
                        b = t;
                        fb = ft;
                        if (side == -1)
                            fa *= 0.5f;
                        side = -1;
                    } else if ((ft < 0.0f) == (fa < 0.0f)) {
                        a = t;
                        fa = ft;
                        if (side == 1)
                            fb *= 0.5f;
                        side = 1;
                    } else
                        return t;
                }
                return (a * fb - b * fa) / (fb - fa);
            }
            tA = tB;
            vA = vB;
        }
        if (!pnanovdb_hdda_step(&h))
            return -1.0f;
        const int3 voxel = (int3)(h.voxel.x, h.voxel.y, h.voxel.z);
        if (h.dim == 1 && all((voxel & ~7) == leaf))
            continue; /* still in the same leaf */
        /* The node the ray is in now: looked up at the ray's position, kept
         * inside the node the DDA stepped into. */
        const float before = h.tmin;
        dim = cb_locate(g, &h, o, d, inv, tmax, skip, voxel, h.dim, &lower, &ijk);
        if (h.tmin > tmax)
            return -1.0f;
        leaf = (int3)(ijk.x, ijk.y, ijk.z) & ~7;
        if (dim != h.dim || h.tmin != before) {
            cb_hdda_enter(&h, o, inv, ijk, dim);
            if (dim == 1) {
                tA = h.tmin;
                vA = cb_trilinear(g, o + tA * d, 0);
            }
        }
    }
}

__kernel void march_rays(__global const uint* surface, __global const uint* color, int hasColor,
                         float4 albedo, float skip, __global const float8* rays,
                         __global float8* hits, uint count)
{
    const uint i = get_global_id(0);
    if (i >= count)
        return;
    const float8 ray = rays[i];
    cb_nano_t g = cb_nano_open(surface, PNANOVDB_GRID_TYPE_FLOAT);
    const pnanovdb_grid_handle_t grid = {pnanovdb_address_null()};
    const float3 o = cb_world_to_index(g.buf, ray.s012);
    const pnanovdb_vec3_t dw = cb_pv(ray.s456);
    float3 d = cb_fv(pnanovdb_grid_world_to_index_dirf(g.buf, grid, &dw));
    /* Index-space distance per unit of world distance (the world direction is
     * a unit vector). */
    const float scale = length(d);
    d /= scale;
    const float t = cb_march(&g, o, d, 0.0f, 1e30f, skip);
    if (!(t >= 0.0f)) {
        hits[i] = (float8)(-1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f);
        return;
    }
    const float3 p = o + t * d;
    float3 gi;
    cb_trilinear(&g, p, &gi);
    /* The world gradient: the transposed inverse Jacobian of the map. */
    const pnanovdb_map_handle_t map = pnanovdb_grid_get_map(g.buf, grid);
    float m[9];
    for (uint k = 0; k < 9; ++k)
        m[k] = pnanovdb_map_get_invmatf(g.buf, map, k);
    const float3 gw =
        (float3)(m[0] * gi.x + m[3] * gi.y + m[6] * gi.z, m[1] * gi.x + m[4] * gi.y + m[7] * gi.z,
                 m[2] * gi.x + m[5] * gi.y + m[8] * gi.z);
    const float len = length(gw);
    const float3 n = len > 0.0f ? gw / len : (float3)(0.0f);
    float3 c = albedo.xyz;
    if (hasColor) {
        cb_nano_t cg = cb_nano_open(color, PNANOVDB_GRID_TYPE_VEC3F);
        const float3 world = ray.s012 + (t / scale) * ray.s456;
        c = cb_trilinear3(&cg, cb_world_to_index(cg.buf, world));
    }
    hits[i] = (float8)(t / scale, n.x, n.y, n.z, c.x, c.y, c.z, 0.0f);
}
