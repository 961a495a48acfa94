/* pnanovdb_cl.h: the settings that let Debian's PNanoVDB.h (nanovdb/PNanoVDB.h of libnanovdb-dev,
 * NanoVDB 32.4, C path) compile as OpenCL C and read the NanoVDB grids in the device buffer
 * (docs/architecture.md, "NanoVDB on the device").
 * The kernel assembler (assemble_kernel_source and rewrite_pnanovdb in src/device/kernel_source.cpp)
 * inlines, for the include of nanovdb/PNanoVDB.h at the end of this file, a copy of PNanoVDB.h with its <stdint.h>/<string.h> includes
 * replaced by comments and its program-scope tables moved to __constant memory (OpenCL 1.2
 * drivers reject program-scope `static const`).
 * A buffer is the word array of one grid: grids of all media share one device buffer and each
 * medium's buffer starts at its grid's word offset. */
#ifndef SPECTRACK_PNANOVDB_CL_H
#define SPECTRACK_PNANOVDB_CL_H

#ifdef cl_khr_fp64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#else
#define double float /* only the (unused) double map fields of PNanoVDB mention double */
#endif

typedef uint uint32_t;
typedef int int32_t;
typedef ulong uint64_t;
typedef long int64_t;

#define PNANOVDB_C
#define PNANOVDB_ADDRESS_32
#define PNANOVDB_BUF_CUSTOM
#define PNANOVDB_MEMCPY_CUSTOM

typedef struct {
  __global const uint* data;
} pnanovdb_buf_t;

inline uint pnanovdb_buf_read_uint32(pnanovdb_buf_t buf, uint byte_offset) {
  return buf.data[byte_offset >> 2u];
}
inline ulong pnanovdb_buf_read_uint64(pnanovdb_buf_t buf, uint byte_offset) {
  uint w = byte_offset >> 2u;
  return (ulong)buf.data[w] | ((ulong)buf.data[w + 1u] << 32);
}
typedef uint pnanovdb_grid_type_t;
#define PNANOVDB_GRID_TYPE_GET(grid_typeIn, nameIn) pnanovdb_grid_type_constants[grid_typeIn].nameIn

/* PNanoVDB type-puns through memcpy: it must really copy bytes. */
inline void pnanovdb_memcpy(void* dst, const void* src, size_t n) {
  char* d = (char*)dst;
  const char* s = (const char*)src;
  for (size_t i = 0; i < n; ++i) d[i] = s[i];
}

#include "nanovdb/PNanoVDB.h"

#endif
