/* rng.h: counter-based random numbers (Philox4x32-10, Salmon et al. 2011), four uniforms per call.
 *
 * A stream is keyed by (pixel, sample, channel, stream id) and the seed. Draw k of a stream is
 * 32-bit word (k mod 4) of
 *     Philox4x32-10(counter = (pixel, sample*4 + channel, stream, k / 4), key = (seed, constant)),
 * so one Philox call gives four successive draws. Nothing depends on thread ids, launch order or
 * on where a path was interrupted: a path saves only its next draw index k (rng_draw in st_path /
 * st_shadow) and a resumed generator (rng_make(..., k)) recomputes the block k / 4 when it first
 * draws, so the stream is the same whatever the launch/queue schedule and device, and an image is
 * reproducible per seed. Stream 0 is the path itself; shadow rays use 1 + bounce * ST_MAX_LIGHTS
 * + light; the camera ray's transmittance estimate of the alpha layer uses ST_STREAM_CAMERA_T and
 * the albedo/depth layers' free flight ST_STREAM_CAMERA_COLLISION (a shadow stream would need
 * 2^29 bounces to reach them).
 *
 * Why this generator, used this way: Philox4x32-10 passes TestU01's BigCrush with a safety margin
 * (Salmon et al. 2011, "Parallel random numbers: as easy as 1, 2, 3", SC11: 7 rounds already
 * pass; 10 is their recommended default), and the four 32-bit words of one counter are its
 * intended output: Random123's philox4x32 returns all four and its Engine adaptor hands them out
 * one after the other, as here. Keeping one word per call costs 4x the Philox
 * work, ~40% of the run time on PoCL (bench/RESULTS.md, 'Random numbers, raygen launches'); a cheaper generator
 * (fewer rounds, a hash) would need its own published quality evidence, so we keep the
 * generator and stop discarding three quarters of it. The device code is checked against
 * Random123's known-answer vectors and by chi-square tests of uniformity and of pairs of
 * successive draws, across block boundaries and neighbouring streams (tests/test_rng.cpp, via
 * kernels/probe.cl). The counter layout is part of every image (not of its expectation): another layout gives
 * other images for the same seed.
 *
 * Draw indices are 32-bit (2^32 draws per stream). The block cached in st_rng lives in
 * registers while a kernel runs; only the draw index is stored between launches.
 */
#ifndef SPECTRACK_RNG_H
#define SPECTRACK_RNG_H

#include "hash.h" /* st_hash32, hash_uniform: hashed values that need no stream */

#define ST_STREAM_CAMERA_T 0xffffffffu /* the alpha layer's camera-ray transmittance (raygen.cl) */
#define ST_STREAM_CAMERA_COLLISION 0xfffffffeu /* the albedo and depth layers' camera-ray free flight */
#define ST_STREAM_WAVELENGTHS 0xfffffffdu /* spectral mode: a sample's wavelengths (queues.h path_wavelengths) */
#define ST_STREAM_LENS 0xfffffffcu /* the thin lens: a camera ray's point on the lens disc (raygen.cl) */
#define ST_STREAM_TIME 0xfffffffbu /* a sample's time in the shutter (queues.h path_shutter_u; hashed, not drawn) */
#define ST_STREAM_EQUIANGULAR 0x80000000u /* + segment: a path segment's equi-angular sample (equiangular.h) */
#define ST_RNG_NO_BLOCK 0xffffffffu /* ctr.w when no block is cached (never a block: k / 4 < 2^30) */

typedef struct {
  uint4 ctr;   /* (pixel, sample*4 + channel, stream, index of the cached block) */
  uint4 block; /* Philox(ctr, key): draws 4 * ctr.w .. 4 * ctr.w + 3 */
  uint2 key;
  uint draw;   /* index k of the next draw */
  /* spectral mode: the path's wavelengths (x, y, z; queues.h path_rng), which every function that
   * draws for the path also needs to evaluate its spectra; 0 in rgb mode. Not part of the stream. */
  float4 lambda;
  /* motion blur: the path's time in seconds (queues.h path_rng; 0 without a moving medium), at
   * which every medium lookup of the path is made (medium.h). Not part of the stream. */
  float time;
} st_rng;

/* The 64-bit product of two 32-bit words, high and low halves. Written as one widening multiply:
 * PoCL 3.1 lowers OpenCL's mul_hi(uint, uint) to four 16-bit partial products (seen in perf
 * annotate of k_shadow), where x86-64 has a single 32x32->64 multiply; GPUs compile either form
 * to their widening multiply. The same bits either way (tests/test_rng.cpp's known answers). */
inline uint st_mulhilo(uint a, uint b, uint* hi) {
  ulong p = (ulong)a * (ulong)b;
  *hi = (uint)(p >> 32);
  return (uint)p;
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

/* The generator of one stream, positioned at draw `draw` (0 for a new stream, or a saved
 * rng_draw_index to resume). No Philox call happens until the first draw. */
inline st_rng rng_make(uint seed, uint pixel, uint sample, uint channel, uint stream, uint draw) {
  st_rng r;
  r.ctr = (uint4)(pixel, sample * 4u + channel, stream, ST_RNG_NO_BLOCK);
  r.block = (uint4)(0u);
  r.key = (uint2)(seed, 0x5EC7AC4Bu);
  r.draw = draw;
  r.lambda = (float4)(0.0f);
  r.time = 0.0f;
  return r;
}

/* The index of the next draw: what a path stores to resume its stream in a later launch. */
inline uint rng_draw_index(const st_rng* r) { return r->draw; }

/* The next raw 32-bit word of the stream: one Philox call every fourth draw (or on the first
 * draw after a resume inside a block). */
inline uint rng_next_word(st_rng* r) {
  uint b = r->draw >> 2;
  if (b != r->ctr.w) {
    r->ctr.w = b;
    r->block = st_philox4x32_10(r->ctr, r->key);
  }
  uint j = r->draw & 3u;
  r->draw += 1u;
  return j == 0u ? r->block.x : j == 1u ? r->block.y : j == 2u ? r->block.z : r->block.w;
}

/* Uniform in [0, 1): 24 random bits (a multiple of 2^-24 below 1), so 1 - u is never 0. */
inline float rng_uniform(st_rng* r) { return (float)(rng_next_word(r) >> 8) * (1.0f / 16777216.0f); }

#endif
