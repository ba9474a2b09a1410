/* cambium — NanoVDB's PNanoVDB.h in OpenCL C 1.2.
 *
 * PNanoVDB.h (NanoVDB 10.0.1) has C, HLSL and GLSL modes but no OpenCL one.
 * Its C mode works on OpenCL with what this file supplies before including
 * it: the fixed-width integer types <stdint.h> would give, floorf, a memcpy,
 * and a buffer type that reads __global memory.  The included copy is the
 * installed header with its program-scope tables made __constant and its
 * system includes removed (cmake/PrepareNanoVDBKernel.cmake), generated at
 * build time and embedded in the binary as "PNanoVDB.h".
 */
#ifndef CAMBIUM_CB_PNANOVDB_H
#define CAMBIUM_CB_PNANOVDB_H

#define PNANOVDB_C
#define PNANOVDB_ADDRESS_32 /* grids under 4 GB (checked by the host): cheaper addresses */
#define PNANOVDB_HDDA
#define PNANOVDB_BUF_CUSTOM
#define PNANOVDB_MEMCPY_CUSTOM

typedef uint uint32_t;
typedef int int32_t;
typedef ulong uint64_t;
typedef long int64_t;
#define floorf floor

/* Bit copies between private values (pnanovdb_uint32_as_float and the like). */
static inline void cb_pnanovdb_memcpy(void* dst, const void* src, size_t n)
{
    for (size_t i = 0; i < n; ++i)
        ((uchar*)dst)[i] = ((const uchar*)src)[i];
}
#define pnanovdb_memcpy cb_pnanovdb_memcpy

/* A NanoVDB grid in global memory, read in 32- and 64-bit words. */
typedef struct pnanovdb_buf_t {
    __global const uint* data;
} pnanovdb_buf_t;
static inline __attribute__((always_inline)) uint pnanovdb_buf_read_uint32(pnanovdb_buf_t buf,
                                                                           uint byte_offset)
{
    return buf.data[byte_offset >> 2];
}
static inline __attribute__((always_inline)) ulong pnanovdb_buf_read_uint64(pnanovdb_buf_t buf,
                                                                            uint byte_offset)
{
    return ((__global const ulong*)buf.data)[byte_offset >> 3];
}
typedef uint pnanovdb_grid_type_t;
#define PNANOVDB_GRID_TYPE_GET(grid_typeIn, nameIn) pnanovdb_grid_type_constants[grid_typeIn].nameIn

#include "PNanoVDB.h"

#endif
