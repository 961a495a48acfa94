/* hash.h: integer hashes for values that need no random stream of their own, in the common subset
 * of C++17 and OpenCL C (as types.h), so the host and the device compute the same bits.
 *
 * Design: a value that depends only on a few words (a sample's time in the shutter, queues.h
 * path_shutter_u; whether a camera sample of a guide training pass makes records, guiding.h
 * guide_sample_records) is a chained hash of them, at a tenth of a Philox call (rng.h), and the
 * host can recompute it (tests, the guide's training).
 */
#ifndef SPECTRACK_HASH_H
#define SPECTRACK_HASH_H

#include "types.h"

/* A 32-bit integer hash with full avalanche (Chris Wellons' lowbias32: every input bit flips each
 * output bit with probability about 1/2). */
inline st_uint st_hash32(st_uint x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

/* A uniform in [0, 1) (24 bits, as rng.h's rng_uniform) that depends only on the three words. */
inline float hash_uniform(st_uint a, st_uint b, st_uint c) {
  const st_uint h = st_hash32(a ^ st_hash32(b ^ st_hash32(c ^ 0x2545F491u)));
  return (float)(h >> 8) * (1.0f / 16777216.0f);
}

#endif
