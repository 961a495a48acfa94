/* guiding.h: the directional distribution of volume path guiding (docs/guiding.md): a mixture of
 * von Mises-Fisher (vMF) lobes on the sphere, evaluated and sampled exactly, and the pieces of the
 * one-sample mixture of the phase function with it that a guided scatter event draws from.
 *
 * Design: one header in the common subset of C++17 and OpenCL C (as types.h), so the host's
 * fitter and tests and the device's kernels run the same float arithmetic. Directions are st_vec3
 * (float3 on the device, a struct of three floats on the host), read only through .x .y .z; the
 * math is the float overloads both languages share (sqrt, exp, expm1, log1p, sin, cos, fmin, fmax;
 * C++ takes them from <math.h>). A mixture is a fixed record of ST_VMF_LOBES lobes (unused lobes
 * have weight 0), so a region's cache entry has one size and every loop one trip count. The
 * renderer's program includes this file after light.h; its kernels use it only where the feature
 * mask has ST_FEATURE_GUIDING (features.h), so with guiding off images are unchanged. The
 * device-only part at the end needs phase.h before it, and includes guide_paths.h (records,
 * roulette and splitting along a path).
 *
 * A lobe of unit mean direction mu and concentration kappa has the density
 *     f(w) = kappa / (2 pi (1 - exp(-2 kappa))) * exp(-kappa (1 - mu.w)),
 * its normaliser written with -expm1(-2 kappa) (no cancellation as kappa -> 0, where f -> 1/4pi)
 * and 1 - mu.w written as |w - mu|^2 / 2 (no cancellation near the mean, where a lobe of kappa
 * 1e4 lives within 0.01 rad). Sampling inverts the polar CDF in the stable form of W. Jakob's note
 * on vMF sampling: 1 - cos theta = -log1p(u expm1(-2 kappa)) / kappa, for every kappa > 0.
 */
#ifndef SPECTRACK_GUIDING_H
#define SPECTRACK_GUIDING_H

#include "hash.h"
#include "types.h"

#ifdef __OPENCL_VERSION__
#include "phase.h"
#include "sampling.h"
#include "spectrum.h"
typedef float3 st_vec3;
#define ST_GUIDE_GLOBAL __global
inline st_vec3 vec3_make(float x, float y, float z) { return (float3)(x, y, z); }
#else
#include <math.h>

typedef struct {
  float x, y, z;
} st_vec3;
#define ST_GUIDE_GLOBAL
inline st_vec3 vec3_make(float x, float y, float z) {
  st_vec3 v = {x, y, z};
  return v;
}
#endif

/* Whether camera sample `sample` of pixel `pixel` (of the full film) makes records in a training
 * pass that records `fraction` of its samples (guide_cache.h kGuideRecordSamples): all of them
 * where the fraction is 1, else those whose hash of (pixel, sample) falls below it. The set
 * depends on nothing else, so every part of a render (the pass always covers the full film) and
 * the host's tests agree on it; the samples that do not record render the same paths. */
#define ST_GUIDE_RECORD_HASH 0x9E3779B9u
inline int guide_sample_records(float fraction, st_uint pixel, st_uint sample) {
  return fraction >= 1.0f || hash_uniform(pixel, sample, ST_GUIDE_RECORD_HASH) < fraction;
}

#define ST_GUIDE_PI 3.14159265358979323846f
#define ST_GUIDE_INV_4PI 0.07957747154594767f
#define ST_GUIDE_ONE_MINUS_EPS 0.99999994f /* the largest float below 1 */
/* Below this kappa a lobe is the uniform density (the exact forms divide 0 by 0 at kappa = 0;
 * at 1e-12 they differ from uniform by 1e-12, far below float resolution). */
#define ST_VMF_KAPPA_UNIFORM 1e-12f

/* Lobes per mixture: 8 lobes take 160 bytes, 8 exp per pdf evaluation. Incident radiance in a
 * medium is smooth (the phase function blurs it at every bounce); a sun, a sky and a few bright
 * neighbours fit in 8 lobes (docs/guiding.md, "Directional representation"). */
#define ST_VMF_LOBES 8

typedef struct {
  st_float4 lobe[ST_VMF_LOBES]; /* xyz: the unit mean direction mu; w: the concentration kappa >= 0 */
  float weight[ST_VMF_LOBES];   /* >= 0, unused lobes 0; the mixture is normalised by their sum,
                                 * and with a zero sum it is the uniform density */
} st_vmf_mixture;

#define ST_SIZEOF_VMF_MIXTURE 160
#ifdef __OPENCL_VERSION__
typedef char st_check_vmf_mixture[(sizeof(st_vmf_mixture) == ST_SIZEOF_VMF_MIXTURE) ? 1 : -1];
#else
static_assert(sizeof(st_vmf_mixture) == ST_SIZEOF_VMF_MIXTURE, "st_vmf_mixture layout");
#endif

/* kappa / (2 pi (1 - exp(-2 kappa))): the density of a lobe at its mean. */
inline float vmf_norm(float kappa) {
  return kappa > ST_VMF_KAPPA_UNIFORM ? kappa / (2.0f * ST_GUIDE_PI * -expm1(-2.0f * kappa)) : ST_GUIDE_INV_4PI;
}

/* The density (per steradian) at unit direction w of the lobe (mu, kappa). */
inline float vmf_eval(st_vec3 mu, float kappa, st_vec3 w) {
  float dx = w.x - mu.x, dy = w.y - mu.y, dz = w.z - mu.z;
  float one_minus_cos = 0.5f * (dx * dx + dy * dy + dz * dz);
  return vmf_norm(kappa) * exp(-kappa * one_minus_cos);
}

/* An orthonormal frame (t, b) around the unit vector n (Duff et al. 2017). */
inline void vmf_frame(st_vec3 n, st_vec3* t, st_vec3* b) {
  float s = n.z >= 0.0f ? 1.0f : -1.0f;
  float a = -1.0f / (s + n.z);
  float c = n.x * n.y * a;
  *t = vec3_make(1.0f + s * n.x * n.x * a, s * c, -s * n.x);
  *b = vec3_make(c, s + n.y * n.y * a, -n.y);
}

/* A direction of the lobe (mu, kappa) from two uniforms in [0, 1): the polar angle by inverting
 * the CDF of 1 - cos theta (u = 0 gives the mean), the azimuth 2 pi u2. The log's argument
 * 1 + u expm1(-2 kappa) is written as (1 - u) + u exp(-2 kappa) where it is small (u near 1: the
 * tail), a sum of two positive terms where the first form would cancel. Past the equator 1 + cos
 * theta comes from its own form, log1p((1 - u) expm1(2 kappa)) / kappa, not from 2 - (1 - cos):
 * near the antipode the difference cancels, and sin theta = sqrt((1 - cos)(1 + cos)) would carry
 * the rounding of the log1p into the direction (as phase.h's product forms avoid for HG). Beyond
 * kappa 40 the far hemisphere has probability below 1e-17, and expm1(2 kappa) overflows from 44. */
inline st_vec3 vmf_sample(st_vec3 mu, float kappa, float u1, float u2) {
  float omc = 2.0f * u1, opc = 2.0f * (1.0f - u1); /* 1 - cos theta, 1 + cos theta */
  if (kappa > ST_VMF_KAPPA_UNIFORM) {
    float x = u1 * expm1(-2.0f * kappa); /* the CDF's log argument minus 1, in (-1, 0] */
    omc = -(x > -0.5f ? log1p(x) : log((1.0f - u1) + u1 * exp(-2.0f * kappa))) / kappa;
    opc = omc > 1.0f && kappa < 40.0f ? log1p((1.0f - u1) * expm1(2.0f * kappa)) / kappa : 2.0f - omc;
  }
  omc = fmin(fmax(omc, 0.0f), 2.0f);
  opc = fmin(fmax(opc, 0.0f), 2.0f);
  float sin_theta = sqrt(omc * opc);
  float cos_theta = omc < opc ? 1.0f - omc : opc - 1.0f;
  float phi = 2.0f * ST_GUIDE_PI * u2;
  float sx = sin_theta * cos(phi), sy = sin_theta * sin(phi);
  st_vec3 t, b;
  vmf_frame(mu, &t, &b);
  return vec3_make(sx * t.x + sy * b.x + cos_theta * mu.x, sx * t.y + sy * b.y + cos_theta * mu.y,
                   sx * t.z + sy * b.z + cos_theta * mu.z);
}

inline st_vec3 vmf_lobe_mean(st_float4 lobe) { return vec3_make(lobe.x, lobe.y, lobe.z); }

/* The mixture's density at unit direction w: sum_k weight_k f_k(w) / sum_k weight_k. */
inline float vmf_mixture_pdf(ST_GUIDE_GLOBAL const st_vmf_mixture* m, st_vec3 w) {
  float sum = 0.0f, total = 0.0f;
  for (int k = 0; k < ST_VMF_LOBES; ++k) {
    float wk = m->weight[k];
    total += wk;
    if (wk > 0.0f) sum += wk * vmf_eval(vmf_lobe_mean(m->lobe[k]), m->lobe[k].w, w);
  }
  return total > 0.0f ? sum / total : ST_GUIDE_INV_4PI;
}

/* A direction of the mixture: u_lobe picks lobe k with probability weight_k / sum (the last lobe
 * of positive weight takes what rounding leaves over), u1 and u2 sample it. */
inline st_vec3 vmf_mixture_sample(ST_GUIDE_GLOBAL const st_vmf_mixture* m, float u_lobe, float u1, float u2) {
  float total = 0.0f;
  for (int k = 0; k < ST_VMF_LOBES; ++k) total += m->weight[k];
  if (!(total > 0.0f)) return vmf_sample(vec3_make(0.0f, 0.0f, 1.0f), 0.0f, u1, u2);
  float target = u_lobe * total, cdf = 0.0f;
  int chosen = -1, last = 0;
  for (int k = 0; k < ST_VMF_LOBES; ++k) {
    float wk = m->weight[k];
    if (!(wk > 0.0f)) continue;
    last = k;
    if (chosen < 0 && target < cdf + wk) chosen = k;
    cdf += wk;
  }
  int k = chosen < 0 ? last : chosen;
  return vmf_sample(vmf_lobe_mean(m->lobe[k]), m->lobe[k].w, u1, u2);
}

/* ---- the product with the phase function (Herholz et al. 2019; Open PGL's volume distribution) ----
 * Deeper than the first scatter event the paths that reach a region propagate in every direction,
 * so a region's mixture holds the incident radiance L_i alone and the event samples its product
 * with the phase function around the path's direction wo: the phase function as one lobe of the
 * same mean cosine (mean nu = wo for g >= 0, -wo for g < 0; kappa from |g|), multiplied with each
 * lobe in closed form. The product of lobes (mu1, k1) and (mu2, k2) is the lobe of mean m / |m| and
 * concentration |m|, m = k1 mu1 + k2 mu2, times C(k1) C(k2) exp(|m| - k1 - k2) / C(|m|) (C: vmf_norm),
 * which scales the lobe's weight. The sampler and the density read the same lobes, so the one-sample
 * mixture's weight stays exact (and the estimator unbiased) however poorly one lobe fits the phase
 * function. */

/* The concentration of the lobe of mean cosine |g| (Banerjee's approximation, |g| clamped to 0.99):
 * 0 for isotropic scattering, where the product is the mixture itself. */
inline float vmf_phase_kappa(float g) {
  const float r = fmin(fabs(g), 0.99f);
  return r * (3.0f - r * r) / (1.0f - r * r);
}

/* Lobe `lobe` of weight `weight` times the lobe (nu, kp): writes its mean and concentration, returns
 * its weight. */
inline float vmf_product_lobe(st_float4 lobe, float weight, st_vec3 nu, float kp, st_vec3* mu, float* kappa) {
  const float k1 = lobe.w;
  const float mx = k1 * lobe.x + kp * nu.x, my = k1 * lobe.y + kp * nu.y, mz = k1 * lobe.z + kp * nu.z;
  const float k = sqrt(mx * mx + my * my + mz * mz);
  *kappa = k > ST_VMF_KAPPA_UNIFORM ? k : 0.0f;
  *mu = k > ST_VMF_KAPPA_UNIFORM ? vec3_make(mx / k, my / k, mz / k) : vec3_make(0.0f, 0.0f, 1.0f);
  return weight * (vmf_norm(k1) * vmf_norm(kp) / vmf_norm(*kappa)) * exp(fmin(k - k1 - kp, 0.0f));
}

/* The density at unit direction w of the product of the mixture with the lobe (nu, kp), normalised. */
inline float vmf_product_pdf(ST_GUIDE_GLOBAL const st_vmf_mixture* m, st_vec3 nu, float kp, st_vec3 w) {
  float sum = 0.0f, total = 0.0f;
  for (int k = 0; k < ST_VMF_LOBES; ++k) {
    if (!(m->weight[k] > 0.0f)) continue;
    st_vec3 mu;
    float kappa;
    const float wk = vmf_product_lobe(m->lobe[k], m->weight[k], nu, kp, &mu, &kappa);
    total += wk;
    if (wk > 0.0f) sum += wk * vmf_eval(mu, kappa, w);
  }
  return total > 0.0f ? sum / total : ST_GUIDE_INV_4PI;
}

/* A direction of the product (vmf_product_pdf): the lobe by u_lobe over the product's weights (the
 * last of positive weight takes what rounding leaves), u1 and u2 sample it; uniform where every
 * product weight is 0, as the density. */
inline st_vec3 vmf_product_sample(ST_GUIDE_GLOBAL const st_vmf_mixture* m, st_vec3 nu, float kp, float u_lobe, float u1,
                                  float u2) {
  float wk[ST_VMF_LOBES], total = 0.0f;
  st_vec3 mu;
  float kappa;
  for (int k = 0; k < ST_VMF_LOBES; ++k) {
    wk[k] = m->weight[k] > 0.0f ? vmf_product_lobe(m->lobe[k], m->weight[k], nu, kp, &mu, &kappa) : 0.0f;
    total += wk[k];
  }
  if (!(total > 0.0f)) return vmf_sample(vec3_make(0.0f, 0.0f, 1.0f), 0.0f, u1, u2);
  float target = u_lobe * total, cdf = 0.0f;
  int chosen = -1, last = 0;
  for (int k = 0; k < ST_VMF_LOBES; ++k) {
    if (!(wk[k] > 0.0f)) continue;
    last = k;
    if (chosen < 0 && target < cdf + wk[k]) chosen = k;
    cdf += wk[k];
  }
  const int k = chosen < 0 ? last : chosen;
  vmf_product_lobe(m->lobe[k], m->weight[k], nu, kp, &mu, &kappa);
  return vmf_sample(mu, kappa, u1, u2);
}

/* The guide's density at w and a direction of it for a path along wo: the region's mixture, or
 * where kp > 0 (the phase product on, anisotropic phase) its product with the phase lobe (nu, kp). */
inline float guide_pdf(ST_GUIDE_GLOBAL const st_vmf_mixture* m, st_vec3 nu, float kp, st_vec3 w) {
  return kp > 0.0f ? vmf_product_pdf(m, nu, kp, w) : vmf_mixture_pdf(m, w);
}
inline st_vec3 guide_sample(ST_GUIDE_GLOBAL const st_vmf_mixture* m, st_vec3 nu, float kp, float u_lobe, float u1,
                            float u2) {
  return kp > 0.0f ? vmf_product_sample(m, nu, kp, u_lobe, u1, u2) : vmf_mixture_sample(m, u_lobe, u1, u2);
}

/* ---- the guide cache: regions refined from a uniform grid over the media, and radiance records ----
 * The cache is one buffer: an st_guide_header, its regions (st_guide_region), the nodes of its
 * kd-trees (st_guide_node), then the pixel estimates (guided roulette below). Every cell of a
 * uniform grid over the media (x fastest) is the root of a kd-tree whose leaves are the regions:
 * the host splits a leaf that holds too many of a training pass's records (guide_cache.h). A
 * scatter position maps to the cell that holds it, clamped to the grid, then down its tree (any
 * region is a valid guide: the estimator is unbiased for every cache). Records are appended by
 * training passes to a second buffer: one uint count (padded to 16 bytes), then st_guide_record
 * entries. */
typedef struct {
  st_float4 origin;   /* xyz: the grid's world-space corner; w: 1 when guided sampling is on */
  st_float4 inv_cell; /* xyz: cells per world unit along each axis; w: in a training pass the fraction of its camera
                       * samples that make records (guide_sample_records), 0 outside training */
  st_int dims[4];     /* xyz: cells per axis; w: record capacity of the record buffer */
  st_int guided_depth; /* scatter events of depth below this are guided, and their records fit the mixtures */
  st_int split_max;    /* guided roulette and splitting: the most paths one path splits into (0: off) */
  float rr_below;      /* guided roulette below this ratio of expected contribution to the pixel's estimate */
  float rr_floor;      /* the least survival probability of guided roulette */
  st_int regions;      /* st_guide_region entries after the header (the kd-trees' leaves) */
  st_int nodes;        /* st_guide_node entries after the regions (the first dims.x * dims.y * dims.z: the cells) */
  st_int depth;        /* the deepest leaf's depth below its cell */
  st_int phase_product; /* 1: mixtures hold L_i (records L / p_mix) and events sample their product with the phase
                         * function; 0: mixtures hold f_phase L_i at the first event's directions (records f L / p_mix) */
} st_guide_header;

/* A node of a cell's kd-tree: a leaf (ST_GUIDE_LEAF set in `next`) holds its region's index in the
 * other bits; an inner node splits at `split` along axis next & 3, its children are nodes
 * (next >> 2) (coordinates below the split) and (next >> 2) + 1. */
typedef struct {
  float split;
  st_uint next;
} st_guide_node;
#define ST_GUIDE_LEAF 0x80000000u
#define ST_GUIDE_MAX_DEPTH 32

typedef struct {
  st_vmf_mixture mix; /* the incident radiance's directional distribution */
  float alpha;        /* selection probability of the guide (0: phase sampling only) */
  float records;      /* records of the region in the last training pass */
  float radiance;     /* guided roulette: the mean over its vertices of every depth of the radiance their
                       * scattered directions brought back per unit throughput (records: how many) */
  float weight;       /* the mean weight of the records the mixture was fitted to (f_phase L / p_mix) */
} st_guide_region;

/* One radiance record: a scatter vertex of a training path, the direction it scattered in and
 * what that direction brought back (st_guide_vertex). */
typedef struct {
  st_float4 pos;  /* xyz: the scatter position; w: from the device f_phase at dir (the fit's records), on
                   * the host the region index (its bits; the host bins by xyz) */
  st_float4 dir;  /* xyz: the scattered direction; w: the weight, f_phase L / p_mix (guide_radiance per unit throughput) */
  st_uint key[4]; /* pixel, sample, channel, depth: the record's place in a canonical order */
} st_guide_record;

/* Record kinds besides the fit's (key.w the vertex depth): a vertex's radiance record (key.w its
 * depth with ST_GUIDE_RECORD_RADIANCE set; dir.x its st_guide_vertex.total, dir.y its throughput's
 * lane mean, dir.z the factor that turns a weight f_phase L / p_mix into the fit's: 1 / f_phase with
 * the phase product, else 1) and the path's end (key.w ST_GUIDE_RECORD_END, region -1, dir.x the path's radiance):
 * the host joins them by (pixel, sample, channel) into the radiance that reached the vertex per
 * unit throughput over the whole rest of the path, (end - total) / beta (guide_cache.cpp). */
#define ST_GUIDE_RECORD_RADIANCE 0x80000000u
#define ST_GUIDE_RECORD_END 0xffffffffu

/* Per path slot, what guiding keeps besides st_path (in the record buffer, after the records): in
 * a training pass the radiance already credited to the path's vertices; with splitting the camera
 * sample's family of split paths (one child waits at a time: guided roulette and splitting below). */
typedef struct {
  st_float4 L_seen; /* training: the path's st_path.L when last credited to its vertices */
  st_uint split[4]; /* splitting: the path's split id (its random key; 0: the camera path), the
                     * children still waiting, the children started so far, 1 while a child resumes */
  st_path saved;    /* splitting: the waiting children's state at their parent's scatter event */
} st_guide_slot;

/* The last ST_GUIDE_RING scatter vertices of a path in a training pass (vertex k at ring[k mod
 * ST_GUIDE_RING]): every contribution the path adds later (a finished shadow ray of a later
 * bounce, an escape, emission) is divided by the throughput that arrived at the vertex and added
 * to the vertex's sum; when a vertex leaves the ring or the path ends it becomes one record of the
 * radiance its scattered direction brought back. */
#define ST_GUIDE_RING 8
typedef struct {
  st_float4 pos;   /* xyz: the scatter position; w: the sum of (contribution / beta) credited so far */
  st_float4 dir;   /* xyz: the scattered direction; w: f_phase at it (ST_GUIDE_NO_RECORD at the ground) */
  st_float4 beta;  /* the throughput that arrived at the vertex (before its scatter weight) */
  st_float4 total; /* x: the path's radiance (guide_radiance) when the vertex entered, plus the later folds of the
                    * shadow rays of its own and earlier bounces (none of its scattered direction's) */
} st_guide_vertex;

#define ST_SIZEOF_GUIDE_HEADER 80
#define ST_SIZEOF_GUIDE_NODE 8
#define ST_SIZEOF_GUIDE_REGION 176
#define ST_SIZEOF_GUIDE_RECORD 48
#define ST_SIZEOF_GUIDE_SLOT 160
#define ST_SIZEOF_GUIDE_VERTEX 64
#ifdef __OPENCL_VERSION__
typedef char st_check_guide_slot[(sizeof(st_guide_slot) == ST_SIZEOF_GUIDE_SLOT) ? 1 : -1];
typedef char st_check_guide_vertex[(sizeof(st_guide_vertex) == ST_SIZEOF_GUIDE_VERTEX) ? 1 : -1];
#else
static_assert(sizeof(st_guide_slot) == ST_SIZEOF_GUIDE_SLOT, "st_guide_slot layout");
static_assert(sizeof(st_guide_vertex) == ST_SIZEOF_GUIDE_VERTEX, "st_guide_vertex layout");
#endif
#ifdef __OPENCL_VERSION__
typedef char st_check_guide_header[(sizeof(st_guide_header) == ST_SIZEOF_GUIDE_HEADER) ? 1 : -1];
typedef char st_check_guide_region[(sizeof(st_guide_region) == ST_SIZEOF_GUIDE_REGION) ? 1 : -1];
typedef char st_check_guide_record[(sizeof(st_guide_record) == ST_SIZEOF_GUIDE_RECORD) ? 1 : -1];
typedef char st_check_guide_node[(sizeof(st_guide_node) == ST_SIZEOF_GUIDE_NODE) ? 1 : -1];
#else
static_assert(sizeof(st_guide_header) == ST_SIZEOF_GUIDE_HEADER, "st_guide_header layout");
static_assert(sizeof(st_guide_region) == ST_SIZEOF_GUIDE_REGION, "st_guide_region layout");
static_assert(sizeof(st_guide_record) == ST_SIZEOF_GUIDE_RECORD, "st_guide_record layout");
static_assert(sizeof(st_guide_node) == ST_SIZEOF_GUIDE_NODE, "st_guide_node layout");
#endif

/* The grid cell of world position (x, y, z), clamped to the grid: the root node of its kd-tree. */
inline int guide_cell_index(ST_GUIDE_GLOBAL const st_guide_header* h, float x, float y, float z) {
  float c[3] = {(x - h->origin.x) * h->inv_cell.x, (y - h->origin.y) * h->inv_cell.y, (z - h->origin.z) * h->inv_cell.z};
  int i[3];
  for (int a = 0; a < 3; ++a) {
    float f = fmin(fmax(c[a], 0.0f), (float)(h->dims[a] - 1));
    i[a] = (int)f;
  }
  return (i[2] * h->dims[1] + i[1]) * h->dims[0] + i[0];
}

/* The leaf node below node `root` that holds (x, y, z) (trees are at most ST_GUIDE_MAX_DEPTH deep). */
inline st_uint guide_tree_leaf(ST_GUIDE_GLOBAL const st_guide_node* nodes, st_uint root, float x, float y, float z) {
  st_uint i = root;
  for (int d = 0; d < ST_GUIDE_MAX_DEPTH && !(nodes[i].next & ST_GUIDE_LEAF); ++d) {
    const st_uint a = nodes[i].next & 3u;
    const float c = a == 0u ? x : a == 1u ? y : z;
    i = (nodes[i].next >> 2) + (c < nodes[i].split ? 0u : 1u);
  }
  return i;
}

/* ---- the one-sample mixture of the phase function and the guide ----
 * A guided scatter event samples the guide with probability alpha (the region's selection
 * probability) and the phase function otherwise, and weighs the direction w by
 *     f_phase(w) / (alpha p_guide(w) + (1 - alpha) p_phase(w)),
 * whichever strategy drew it. For 0 <= alpha < 1 the denominator is positive wherever f_phase is,
 * so the estimator is unbiased for any guide, however wrong (docs/guiding.md). */

/* The choice of strategy from one uniform u: returns 1 for the guide (u < alpha) and 0 for the
 * phase function, and writes u rescaled to [0, 1) within the chosen part (the guide's lobe choice
 * reuses it). */
inline int guide_choose(float alpha, float u, float* u_reuse) {
  int guide = u < alpha;
  float r = guide ? u / alpha : (u - alpha) / (1.0f - alpha);
  *u_reuse = fmin(fmax(r, 0.0f), ST_GUIDE_ONE_MINUS_EPS);
  return guide;
}

/* The density with which the one-sample mixture draws a direction. */
inline float guide_mixture_pdf(float alpha, float pdf_guide, float pdf_phase) {
  return alpha * pdf_guide + (1.0f - alpha) * pdf_phase;
}

#ifdef __OPENCL_VERSION__
/* The guided scatter direction around the propagation direction wo (needs phase.h): three
 * uniforms (strategy and lobe, then the two of the chosen sampler; a Draine blend's rejection
 * sampling draws more from rng); writes the mixture's pdf and the phase function's value at the
 * direction, so the path's weight is f_phase / pdf_mix. */
inline float3 guided_phase_sample(__global const st_vmf_mixture* m, float alpha, int phase_type, float g, float4 phase,
                                  float3 wo, float u0, float u1, float u2, st_rng* rng, float* pdf_mix,
                                  float* f_phase, float kp) {
  float u_lobe, p_phase;
  float3 wi;
  const float3 nu = g >= 0.0f ? wo : -wo;
  if (guide_choose(alpha, u0, &u_lobe)) {
    wi = guide_sample(m, nu, kp, u_lobe, u1, u2);
    *f_phase = phase_eval_any(phase_type, g, phase, dot(wo, wi));
  } else {
    wi = phase_sample_any(phase_type, g, phase, wo, u1, u2, rng, &p_phase, f_phase);
  }
  *pdf_mix = guide_mixture_pdf(alpha, guide_pdf(m, nu, kp, wi), *f_phase);
  return wi;
}

/* The phase lobe's concentration of the guided events of medium (phase_type, g) under header h:
 * 0 (the mixture alone) unless the phase product is on and the phase function is Henyey-Greenstein. */
inline float guide_phase_kappa(__global const st_guide_header* h, int phase_type, float g) {
  return h->phase_product && phase_type == ST_PHASE_HG ? vmf_phase_kappa(g) : 0.0f;
}

/* The regions follow the header in the cache buffer, the kd-trees' nodes the regions. */
inline __global const st_guide_region* guide_regions(__global const st_guide_header* h) {
  return (__global const st_guide_region*)(h + 1);
}
inline __global const st_guide_node* guide_nodes(__global const st_guide_header* h) {
  return (__global const st_guide_node*)(guide_regions(h) + h->regions);
}

/* The region of world position (x, y, z): its cell, then down the cell's kd-tree to a leaf. */
inline int guide_region_index(__global const st_guide_header* h, float x, float y, float z) {
  __global const st_guide_node* nodes = guide_nodes(h);
  const st_uint leaf = guide_tree_leaf(nodes, (st_uint)guide_cell_index(h, x, y, z), x, y, z);
  return (int)(nodes[leaf].next & ~ST_GUIDE_LEAF);
}

#include "guide_paths.h"
#endif

#endif /* SPECTRACK_GUIDING_H */
