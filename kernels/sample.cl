/* cambium — field sampling kernels.
 *
 * Built with -D CB_LANES=8: each work-item evaluates eight points at once as
 * float8 lanes (PoCL vectorises only what is written as vectors; a GPU runs
 * the same code); the values kernel is built 16 wide (-D CB_LANES=16).  The programs are
 * region-specialised FieldPrograms (kernels/cb_program.h), so a leaf near one twig runs a handful
 * of instructions.  The CPU reference of these kernels is FieldProgram::evaluate
 * (src/field/program.cpp), the same interpreter in double precision, itself tested against the
 * BlobTree's reference evaluator.
 */
#include "cb_program.h"

#define CB_LEAF_VOXELS 512

/* Which kernels a program holds (-D CB_KERNELS=mask; default all): 1 values,
 * 2 surface, 4 points.  A program holds only what it runs, since a driver may
 * compile every kernel of it (PoCL does, for the program's binary). */
#ifndef CB_KERNELS
#define CB_KERNELS 7
#endif

/* Values of every voxel of 8^3 leaves (built with -D CB_GRADIENT=0 -D CB_COLOR=0).
 * 16 wide: one work-group of 32 work-items per leaf, work-item r evaluates
 * rows 2 r and 2 r + 1, the voxels (x0 + 0..7, y0 + 2 (r & 3) + 0..1,
 * z0 + (r >> 2)); 8 wide: 64 work-items, work-item r row r, the voxels
 * (x0 + 0..7, y0 + (r & 7), z0 + (r >> 3)).  Voxel (i, j, k) sits at
 * (i, j, k) * voxelSize in world space (OpenVDB's linear transform).
 * leaves: 5 ints per leaf: x0 y0 z0, offset and length of its program in code.
 * out: 512 halves per leaf, x fastest: F - T, rounded to nearest even (relative
 * precision 2^-11 where it matters, next to the surface; its sign is the side). */
#if CB_KERNELS & 1
__kernel void sample_values(__global const int* code, __global const float* prm,
                            __global const int* leaves, const float voxelSize, __global half* out)
{
    int leaf = (int)get_group_id(0);
    int row = (int)get_local_id(0);
    __global const int* L = leaves + 5 * leaf;
#if CB_LANES == 16
    /* Two rows per work-item (32 per leaf): rows 2 r and 2 r + 1. */
    const float8 i8 = (float8)(0.0f, 1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f);
    cb_real x = ((float16)((float)L[0]) + (float16)(i8, i8)) * voxelSize;
    int y0 = L[1] + 2 * (row & 3);
    cb_real y = (float16)((float8)((float)y0), (float8)((float)(y0 + 1))) * voxelSize;
    float z = (float)(L[2] + (row >> 2)) * voxelSize;
    cb_sample s = cb_run_program(code + 4 * L[3], L[4], prm, cb_v3(x, y, z));
    vstore_half16_rte(s.v - prm[CB_P_T], 0, out + (size_t)leaf * CB_LEAF_VOXELS + 16 * row);
#else
    cb_real x = ((float8)((float)L[0]) + (float8)(0.0f, 1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f)) *
                voxelSize;
    float y = (float)(L[1] + (row & 7)) * voxelSize;
    float z = (float)(L[2] + (row >> 3)) * voxelSize;
    cb_sample s = cb_run_program(code + 4 * L[3], L[4], prm, cb_v3(x, y, z));
    vstore_half8_rte(s.v - prm[CB_P_T], 0, out + (size_t)leaf * CB_LEAF_VOXELS + 8 * row);
#endif
}
#endif

/* The surface samples of chosen voxels of chosen leaves (the voxels next to
 * the surface), CB_LANES (8 or 16) voxels of one leaf per work-item:
 * chunkLeaf[i] is the leaf of chunk i, chunkVoxels[CB_LANES i + lane] its
 * voxel indices (x + 8 y + 64 z).  Each voxel's Newton step toward the
 * surface (cb_surface_step, at most a voxel: the leaves' programs hold that
 * far beyond their voxels) and the sample where it lands.  out: 7 planes of
 * `stride` halves, entry CB_LANES i + lane: the step (voxels) x, y, z, F - T,
 * the gradient x, y, z; colour as 3 planes of `stride` bytes. */
#if CB_LANES == 16
#define CB_VLOAD vload16
#define CB_VSTORE vstore16
#define CB_VSTORE_HALF vstore_half16
#define CB_CONVERT_INT convert_int16
#define CB_CONVERT_FLOAT convert_float16
#define CB_CONVERT_UCHAR convert_uchar16_sat_rte
#define CB_INT int16
#else
#define CB_VLOAD vload8
#define CB_VSTORE vstore8
#define CB_VSTORE_HALF vstore_half8
#define CB_CONVERT_INT convert_int8
#define CB_CONVERT_FLOAT convert_float8
#define CB_CONVERT_UCHAR convert_uchar8_sat_rte
#define CB_INT int8
#endif
#if CB_KERNELS & 2
__kernel void sample_surface(__global const int* code, __global const float* prm,
                             __global const int* leaves, const float voxelSize,
                             __global const int* chunkLeaf, __global const ushort* chunkVoxels,
                             const int stride, __global half* out, __global uchar* color)
{
    int chunk = (int)get_global_id(0);
    __global const int* L = leaves + 5 * chunkLeaf[chunk];
    CB_INT v = CB_CONVERT_INT(CB_VLOAD(chunk, chunkVoxels));
    cb_vec3 p = cb_v3(CB_CONVERT_FLOAT((CB_INT)(L[0]) + (v & 7)) * voxelSize,
                      CB_CONVERT_FLOAT((CB_INT)(L[1]) + ((v >> 3) & 7)) * voxelSize,
                      CB_CONVERT_FLOAT((CB_INT)(L[2]) + (v >> 6)) * voxelSize);
    cb_vec3 d;
    cb_sample s = cb_surface_step(code + 4 * L[3], L[4], prm, p, (cb_real)(voxelSize), &d);
    const float inv = 1.0f / voxelSize;
    CB_VSTORE_HALF(d.x * inv, chunk, out);
    CB_VSTORE_HALF(d.y * inv, chunk, out + stride);
    CB_VSTORE_HALF(d.z * inv, chunk, out + 2 * stride);
    CB_VSTORE_HALF(s.v - prm[CB_P_T], chunk, out + 3 * stride);
    CB_VSTORE_HALF(s.g.x, chunk, out + 4 * stride);
    CB_VSTORE_HALF(s.g.y, chunk, out + 5 * stride);
    CB_VSTORE_HALF(s.g.z, chunk, out + 6 * stride);
    CB_VSTORE(CB_CONVERT_UCHAR(s.c.x * 255.0f), chunk, color);
    CB_VSTORE(CB_CONVERT_UCHAR(s.c.y * 255.0f), chunk, color + stride);
    CB_VSTORE(CB_CONVERT_UCHAR(s.c.z * 255.0f), chunk, color + 2 * stride);
}
#endif

#if CB_LANES == 8 && (CB_KERNELS & 4)
/* Evaluates one program at arbitrary points, eight per work-item: points and
 * out are planes (x, y, z / value, gx, gy, gz, r, g, b) of `stride` floats,
 * stride a multiple of 8. */
__kernel void sample_points(__global const int* code, const int length, __global const float* prm,
                            __global const float* points, const int stride, __global float* out)
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
#endif
