/* rng.h: counter-based random numbers (Philox4x32-10, Salmon et al. 2011).
 *
 * A stream is keyed by (pixel, sample, channel, stream id) and the seed; draw k of a stream is
 * Philox(counter = (pixel, sample*4 + channel, stream, k), key = (seed, constant)). Nothing
 * depends on thread ids or launch order, so an image is reproducible on any device and any
 * queue schedule. Stream 0 is the path itself; shadow rays use 1 + bounce * ST_MAX_LIGHTS + light.
 */
#ifndef SPECTRACK_RNG_H
#define SPECTRACK_RNG_H

typedef struct {
  uint4 ctr; /* w: draw index */
  uint2 key;
} st_rng;

inline uint st_mulhilo(uint a, uint b, uint* hi) {
  *hi = mul_hi(a, b);
  return a * b;
}

inline uint4 st_philox4x32_10(uint4 c, uint2 k) {
  for (int r = 0; r < 10; ++r) {
    uint hi0, hi1;
    uint lo0 = st_mulhilo(0xD2511F53u, c.x, &hi0);
    uint lo1 = st_mulhilo(0xCD9E8D57u, c.z, &hi1);
    c = (uint4)(hi1 ^ c.y ^ k.x, lo1, hi0 ^ c.w ^ k.y, lo0);
    k += (uint2)(0x9E3779B9u, 0xBB67AE85u);
  }
  return c;
}

inline st_rng rng_make(uint seed, uint pixel, uint sample, uint channel, uint stream, uint draw) {
  st_rng r;
  r.ctr = (uint4)(pixel, sample * 4u + channel, stream, draw);
  r.key = (uint2)(seed, 0x5EC7AC4Bu);
  return r;
}

/* Uniform in [0, 1): 24 random bits, so 1 - u is never 0. */
inline float rng_uniform(st_rng* r) {
  uint4 x = st_philox4x32_10(r->ctr, r->key);
  r->ctr.w += 1u;
  return (float)(x.x >> 8) * (1.0f / 16777216.0f);
}

#endif
