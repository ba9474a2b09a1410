/* cambium — field sampling kernels.
 *
 * Built with -D CB_LANES=8: each work-item evaluates eight points at once as
 * float8 lanes (PoCL vectorises only what is written as vectors; a GPU runs
 * the same code).  The programs are region-specialised FieldPrograms
 * (kernels/cb_program.h), so a leaf near one twig runs a handful of
 * instructions.  The CPU reference of these kernels is
 * FieldProgram::evaluate (src/field/program.cpp), the same interpreter in
 * double precision, itself tested against the BlobTree's reference evaluator.
 */
#include "cb_program.h"

#define CB_LEAF_VOXELS 512
#define CB_SAMPLE_CHANNELS 7 /* value, gradient xyz, colour rgb */

/* One work-group of 64 work-items per 8^3 leaf; work-item r evaluates row r,
 * the voxels (x0 + 0..7, y0 + (r & 7), z0 + (r >> 3)).  Voxel (i, j, k) sits
 * at (i, j, k) * voxelSize in world space (OpenVDB's linear transform).
 * leaves: 5 ints per leaf: x0 y0 z0, offset and length of its program in code.
 * out: per leaf 7 planes of 512 floats: value, gx, gy, gz, r, g, b, each in
 * x-fastest order. */
__kernel void sample_leaves(__global const int* code, __global const float* prm,
                            __global const int* leaves, const float voxelSize,
                            __global float* out)
{
    int leaf = (int)get_group_id(0);
    int row = (int)get_local_id(0);
    __global const int* L = leaves + 5 * leaf;
    cb_real x = ((float8)((float)L[0]) + (float8)(0.0f, 1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f)) * voxelSize;
    float y = (float)(L[1] + (row & 7)) * voxelSize;
    float z = (float)(L[2] + (row >> 3)) * voxelSize;
    cb_sample s = cb_run_program(code + 4 * L[3], L[4], prm, cb_v3(x, y, z));
    __global float* o = out + (size_t)leaf * (CB_SAMPLE_CHANNELS * CB_LEAF_VOXELS) + 8 * row;
    vstore8(s.v, 0, o);
    vstore8(s.g.x, 0, o + 1 * CB_LEAF_VOXELS);
    vstore8(s.g.y, 0, o + 2 * CB_LEAF_VOXELS);
    vstore8(s.g.z, 0, o + 3 * CB_LEAF_VOXELS);
    vstore8(s.c.x, 0, o + 4 * CB_LEAF_VOXELS);
    vstore8(s.c.y, 0, o + 5 * CB_LEAF_VOXELS);
    vstore8(s.c.z, 0, o + 6 * CB_LEAF_VOXELS);
}

/* Evaluates one program at arbitrary points, eight per work-item: points and
 * out are planes (x, y, z / value, gx, gy, gz, r, g, b) of `stride` floats,
 * stride a multiple of 8. */
__kernel void sample_points(__global const int* code, const int length,
                            __global const float* prm, __global const float* points,
                            const int stride, __global float* out)
{
    int i = 8 * (int)get_global_id(0);
    cb_vec3 p = cb_v3(vload8(0, points + i), vload8(0, points + stride + i),
                      vload8(0, points + 2 * stride + i));
    cb_sample s = cb_run_program(code, length, prm, p);
    vstore8(s.v, 0, out + i);
    vstore8(s.g.x, 0, out + stride + i);
    vstore8(s.g.y, 0, out + 2 * stride + i);
    vstore8(s.g.z, 0, out + 3 * stride + i);
    vstore8(s.c.x, 0, out + 4 * stride + i);
    vstore8(s.c.y, 0, out + 5 * stride + i);
    vstore8(s.c.z, 0, out + 6 * stride + i);
}
