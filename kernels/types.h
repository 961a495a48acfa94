/* types.h: the plain-data types and enums shared by the host (C++17) and the device (OpenCL C).
 *
 * Design: one header, compiled by both sides, is the only place where an enum value or a struct
 * layout is written down. Vectors are st_float4 (16 bytes, 16-aligned on both sides; .w is
 * padding unless a comment says otherwise); there are no float3 fields (their size differs between
 * OpenCL and C++). The end of this file checks every struct size against its ST_SIZEOF_*: the
 * host with static_assert, the device with st_check_* typedefs (ST_CHECK_SIZE; a negative array size fails the
 * kernel build), so a layout drift fails at compile time on both sides.
 *
 * Names follow the physics: sigma_a, sigma_s (per unit density), beta (path throughput weight),
 * dmax / dmin (per-cell density majorant / minorant).
 */
#ifndef SPECTRACK_TYPES_H
#define SPECTRACK_TYPES_H

#ifdef __OPENCL_VERSION__
typedef float4 st_float4;
typedef uint st_uint;
typedef int st_int;
typedef ulong st_ulong;
#define ST_ALIGN16
#else
#include <cstddef>
#include <cstdint>
struct alignas(16) st_float4 {
  float x, y, z, w;
};
typedef uint32_t st_uint;
typedef int32_t st_int;
typedef uint64_t st_ulong;
#endif

#define ST_MAX_MEDIA 8
#define ST_MAX_LIGHTS 8
#define ST_NO_GRID 0xffffffffu
#define ST_MAX_BATCHES_IN_FLIGHT 8 /* ring of batch result buffers (work distribution) */
/* Shadow-ray entries per (path slot, light): a ring of R entries indexed by the bounce modulo R
 * (R = NL / n_lights, chosen by the host: RenderOptions::shadow_ring), so a path scatters again
 * while the shadow rays of its last R - 1 bounces are still running; it waits only when the entry
 * of bounce d - R is still busy (scatter.cl). R = 1 is the plain rule: wait for every shadow ray. */
#define ST_MAX_SHADOW_RING 8
/* st_shadow.state */
enum st_shadow_state { ST_SHADOW_EMPTY = 0, ST_SHADOW_PENDING = 1, ST_SHADOW_DONE = 2 };

/* ---- enums: one definition each; the user-facing names are in the tables below ---- */

/* How a real collision treats absorption (tracking.h): X(ENUM suffix, name).
 *   event:  absorption is an event that ends the path (P_a > 0), emission scored there; the
 *           paper's analog baselines;
 *   weight: real collisions always scatter (P_a = 0, paper 5.1.3), beta takes the albedo,
 *           emission is scored at every real collision, paths end by Russian roulette. */
#define ST_ABSORPTIONS(X) X(EVENT, "event") X(WEIGHT, "weight")
#define ST_X_ABSORPTION_ENUM(E, name) ST_ABSORPTION_##E,
enum st_absorption { ST_ABSORPTIONS(ST_X_ABSORPTION_ENUM) ST_ABSORPTION_COUNT };

/* Which lights next-event estimation samples at a scatter event (scatter.cl): X(ENUM suffix, name).
 *   all:          one shadow ray to every light;
 *   uniform:      one light, each with the same probability (pbrt-v4's BVH light sampler does this
 *                 for lights at infinity), the contribution divided by that probability;
 *   power:        one light, chosen in proportion to its power (pbrt-v4's PowerLightSampler: the
 *                 radiance it would send to a point with no medium around it);
 *   contribution: one light, chosen at each scatter event in proportion to its unoccluded
 *                 contribution there: st_light.nee_strength times the phase function towards a
 *                 directional light (an environment's phase-weighted radiance is taken as its mean;
 *                 light.h light_select_contribution);
 *   auto:         a request, never seen by the kernels: the host resolves it per scene and tracker
 *                 (scene_pack.cpp) to contribution where shadow rays are long (the media's
 *                 residual majorant optical depth along a mean chord of their boxes, the lookups a
 *                 shadow ray crossing them takes, is at least settings.h kAutoContributionLookups) and to
 *                 all otherwise: one shadow ray per event halves the cost of dense media, where
 *                 shadow rays are most of the work, and loses in thin ones, where they are cheap.
 * MIS with phase sampling takes the probability of a uniform or power choice into the light's pdf;
 * contribution's choice depends on the event, so its MIS weights are all's (select_pmf 1), which
 * stay a partition of unity: unbiased for any choice probabilities. */
#define ST_LIGHT_SAMPLINGS(X) \
  X(ALL, "all") X(UNIFORM, "uniform") X(POWER, "power") X(CONTRIBUTION, "contribution") X(AUTO, "auto")
#define ST_X_LIGHT_SAMPLING_ENUM(E, name) ST_LIGHT_SAMPLING_##E,
enum st_light_sampling { ST_LIGHT_SAMPLINGS(ST_X_LIGHT_SAMPLING_ENUM) ST_LIGHT_SAMPLING_COUNT };

/* The transmittance estimator of shadow rays (and of every other transmittance; transmittance.h):
 * X(ENUM suffix, name).
 *   ratio:        (residual) ratio tracking, one lookup per tentative collision;
 *   ray-marching: the unbiased ray-marching estimator of Kettunen et al. 2021 (docs/transmittance.md):
 *                 a power series of exp(-tau) around a pilot estimate, each power from
 *                 stratified ray-marched estimates of tau, the series truncated by Russian roulette. */
#define ST_TRANSMITTANCES(X) X(RATIO, "ratio") X(RAY_MARCHING, "ray-marching")
#define ST_X_TRANSMITTANCE_ENUM(E, name) ST_TRANSMITTANCE_##E,
enum st_transmittance_mode { ST_TRANSMITTANCES(ST_X_TRANSMITTANCE_ENUM) ST_TRANSMITTANCE_COUNT };

/* How a density lookup reads a VDB grid (kernels/medium.h): X(ENUM suffix, name).
 *   trilinear:  the trilinear blend of the 8 voxels around the point;
 *   stochastic: one of those 8 voxels, chosen with probability equal to its trilinear weight
 *               (one random draw per lookup). Its expectation is the trilinear value, and every
 *               estimator uses a lookup linearly in expectation with the majorant grid bounding
 *               every voxel of the support, so images keep their expectation
 *               (docs/stochastic-lookup.md): cheaper lookups for some added variance. */
#define ST_LOOKUPS(X) X(TRILINEAR, "trilinear") X(STOCHASTIC, "stochastic")
#define ST_X_LOOKUP_ENUM(E, name) ST_LOOKUP_##E,
enum st_lookup_mode { ST_LOOKUPS(ST_X_LOOKUP_ENUM) ST_LOOKUP_COUNT };

/* What the float4 lanes of a path carry (render.color, --spectral; docs/spectral.md): X(ENUM suffix, name).
 *   rgb:      linear sRGB channels (w unused);
 *   spectral: four wavelengths per path (x, y, z, w), a hero drawn from the visible-range
 *             density and three more a quarter of its CDF apart (kernels/spectrum.h); colours are
 *             upsampled to smooth spectra (src/color/spectrum.h) and the film turns the path's
 *             radiance at its wavelengths into linear sRGB (finish.cl). */
#define ST_FILM_COLORS(X) X(RGB, "rgb") X(SPECTRAL, "spectral")
#define ST_X_FILM_COLOR_ENUM(E, name) ST_FILM_COLOR_##E,
enum st_film_color { ST_FILM_COLORS(ST_X_FILM_COLOR_ENUM) ST_FILM_COLOR_COUNT };

/* How a spectral-mode sample draws its wavelengths (render.wavelength_sampling; kernels/queues.h
 * path_wavelengths; docs/spectral.md): X(ENUM suffix, name).
 *   independent: one uniform per sample, drawn on its own (the hero's CDF value u; the three other
 *                lanes at u + k/4);
 *   stratified:  the samples of a pixel in aligned blocks of ST_WAVELENGTH_BLOCK share one
 *                uniform rotation r per block and take u = r + j/16 (mod 1), j in 0, 2, 1, 3 for
 *                the block's samples in order: a block's 16 lanes lie evenly spaced in the CDF, and
 *                each sample's u is still uniform on its own. RGB mode draws no wavelengths. */
#define ST_WAVELENGTH_SAMPLINGS(X) X(INDEPENDENT, "independent") X(STRATIFIED, "stratified")
#define ST_X_WAVELENGTH_SAMPLING_ENUM(E, name) ST_WAVELENGTHS_##E,
enum st_wavelength_sampling { ST_WAVELENGTH_SAMPLINGS(ST_X_WAVELENGTH_SAMPLING_ENUM) ST_WAVELENGTH_SAMPLING_COUNT };
/* Samples per block of stratified wavelengths: every sample range that adaptive sampling decides
 * on its own (a round, src/integrator/adaptive.cpp) starts at a multiple of it, so a round's
 * wavelengths are independent of the samples before it. */
#define ST_WAVELENGTH_BLOCK 4

/* The trackers, as one table that the host (names, settings, feature mask) and the kernels
 * (tracking.h) read: X(ENUM suffix, CLI/scene name, colour channels traced per sample (one path
 * each), needs achromatic media, uses the spectral scheme, decomposes into control + residual,
 * default st_absorption). Enum values follow the table's order. spectral-mis (tracking.h) is
 * the peers' method: one hero channel per path drives free-path sampling, the path weighted by
 * the one-sample MIS (balance heuristic) over the channels' pdfs. */
#define ST_TRACKERS(X)                                                                  \
  X(DELTA_PER_CHANNEL, "delta-per-channel", 3, 0, 0, 0, ST_ABSORPTION_EVENT)            \
  X(DELTA, "delta", 1, 1, 0, 0, ST_ABSORPTION_EVENT)                                    \
  X(SPECTRAL, "spectral", 1, 0, 1, 0, ST_ABSORPTION_WEIGHT)                             \
  X(DECOMPOSITION, "decomposition", 3, 0, 0, 1, ST_ABSORPTION_WEIGHT)                   \
  X(SPECTRAL_DECOMPOSITION, "spectral-decomposition", 1, 0, 1, 1, ST_ABSORPTION_WEIGHT)        \
  X(SPECTRAL_MIS, "spectral-mis", 1, 0, 0, 0, ST_ABSORPTION_WEIGHT)
#define ST_X_TRACKER_ENUM(E, name, ch, achromatic, scheme, decomposes, absorption) ST_TRACKER_##E,
enum st_tracker { ST_TRACKERS(ST_X_TRACKER_ENUM) ST_TRACKER_COUNT };
#define ST_X_TRACKER_CHANNELS(E, name, ch, achromatic, scheme, decomposes, absorption) (t == ST_TRACKER_##E) ? ch :
#define ST_X_TRACKER_ACHROMATIC(E, name, ch, achromatic, scheme, decomposes, absorption) (t == ST_TRACKER_##E) ? achromatic :
#define ST_X_TRACKER_SCHEME(E, name, ch, achromatic, scheme, decomposes, absorption) (t == ST_TRACKER_##E) ? scheme :
#define ST_X_TRACKER_DECOMPOSES(E, name, ch, achromatic, scheme, decomposes, absorption) (t == ST_TRACKER_##E) ? decomposes :
#define ST_X_TRACKER_ABSORPTION(E, name, ch, achromatic, scheme, decomposes, absorption) (t == ST_TRACKER_##E) ? absorption :
inline int st_tracker_channels(int t) { return ST_TRACKERS(ST_X_TRACKER_CHANNELS) 1; }
/* Paths per (pixel, sample): a per-channel tracker traces each lane alone, the three colour
 * channels in rgb mode and the four wavelengths in spectral mode. */
inline int st_paths_per_sample(int t, int color) {
  return st_tracker_channels(t) > 1 && color == ST_FILM_COLOR_SPECTRAL ? 4 : st_tracker_channels(t);
}
inline int st_tracker_achromatic_only(int t) { return ST_TRACKERS(ST_X_TRACKER_ACHROMATIC) 0; }
inline int st_tracker_uses_scheme(int t) { return ST_TRACKERS(ST_X_TRACKER_SCHEME) 0; }
inline int st_tracker_decomposes(int t) { return ST_TRACKERS(ST_X_TRACKER_DECOMPOSES) 0; }
inline int st_tracker_default_absorption(int t) { return ST_TRACKERS(ST_X_TRACKER_ABSORPTION) ST_ABSORPTION_EVENT; }

/* Spectral schemes (docs/estimators.md, 'Spectral tracking'): X(ENUM suffix, name). */
#define ST_SCHEMES(X) X(MAX, "max") X(AVERAGE, "average") X(HISTORY_MAX, "history-max") X(HISTORY_AVERAGE, "history-average")
#define ST_X_SCHEME_ENUM(E, name) ST_SCHEME_##E,
enum st_scheme { ST_SCHEMES(ST_X_SCHEME_ENUM) ST_SCHEME_COUNT };

enum st_camera_type { ST_CAMERA_PERSPECTIVE = 0, ST_CAMERA_ORTHOGRAPHIC = 1 };
/* Lights at infinity first; point and spot lights are local: intensity / r^2, delta in direction; a
 * sphere is local and has an area: radiance on its surface, sampled in its cone (light.h). */
enum st_light_type { ST_LIGHT_ENV_UNIFORM, ST_LIGHT_ENV_MAP, ST_LIGHT_DIRECTIONAL, ST_LIGHT_POINT, ST_LIGHT_SPOT, ST_LIGHT_SPHERE };
enum st_medium_type { ST_MEDIUM_VDB = 0, ST_MEDIUM_HOMOGENEOUS = 1 };
/* st_path.medium of a path at the ground (a surface vertex, ground.h), not a medium */
#define ST_MEDIUM_GROUND (-1)
/* What the ground does (ground.h): X(ENUM suffix, name): reflects diffusely; catches shadows (the
 * shadow layer, transparent otherwise); holds out (occludes, transparent). */
#define ST_GROUND_MODES(X) X(DIFFUSE, "diffuse") X(SHADOW_CATCHER, "shadow_catcher") X(HOLDOUT, "holdout")
#define ST_X_GROUND_ENUM(E, name) ST_GROUND_##E,
enum st_ground_mode { ST_GROUND_MODES(ST_X_GROUND_ENUM) ST_GROUND_MODE_COUNT };
/* A medium's per-voxel colour grid (kernels/medium.h medium_unit_coeffs): none; the
 * single-scattering albedo per channel (sigma_t unchanged); a multiplier of sigma_s per channel. */
enum st_color_mode { ST_COLOR_NONE = 0, ST_COLOR_ALBEDO = 1, ST_COLOR_SCATTERING = 2 };
/* Phase functions (kernels/phase.h): isotropic; Henyey-Greenstein (st_medium.g); a blend of two
 * Draine lobes (1 - w) D(g, alpha1) + w D(g2, alpha2) (st_medium.g and st_medium.phase), the one
 * kernel form of the scene's "draine", "rayleigh", "hg2" and "mie" (src/scene/phase_models.h). */
enum st_phase_type { ST_PHASE_ISOTROPIC = 0, ST_PHASE_HG = 1, ST_PHASE_DRAINE_BLEND = 2 };

/* Layers of the film beyond the beauty (docs/aov.md): X(ENUM suffix, --aov / film.aovs name).
 *   alpha:       A = 1 - the camera ray's transmittance through every medium (its channel mean; AR,
 *                AG, AB per channel), from a transmittance estimate along the camera ray (its own
 *                random stream, ST_STREAM_CAMERA_T); the film becomes transparent: the lights at
 *                infinity seen straight from the camera go to the environment layer, not into RGB;
 *   environment: the lights at infinity seen straight from the camera (escape before any scattering);
 *   variance:    the variance of each pixel's mean, from per-sample second moments (k_accumulate);
 *   emission:    emission scored before the first scattering event (the medium's glow seen directly);
 *   direct:      light of the first scattering event: its next-event estimation and the lights its
 *                phase-sampled ray reaches;
 *   indirect:    everything else (the host takes it as the beauty minus environment, emission and
 *                direct, so the passes add up to the beauty sample by sample).
 *   albedo:      the scattering albedo sigma_s / sigma_t per channel at the camera ray's first
 *                collision (a delta-tracking free flight of the channel-mean extinction along the
 *                camera ray, stream ST_STREAM_CAMERA_COLLISION), averaged over the samples whose
 *                ray collided: a denoiser's albedo buffer (docs/aov.md);
 *   depth:       the distance along the camera ray to that collision, averaged the same way;
 *   shadow:      a shadow-catcher ground seen by the camera ray: the ratio of the shadowed to the
 *                unshadowed direct light it receives, as two sums (ground.h; 1 where no sample saw it).
 * The bits are 1 << index (st_scene.aovs). Per path, alpha and environment take two more float4
 * of the batch result buffer (st_result_layer), the passes two more, albedo and depth one more
 * (ST_RESULT_AUX; the collision count rides in ST_RESULT_ALPHA's w); variance takes nothing per path. */
#define ST_AOVS(X)                                                                       \
  X(ALPHA, "alpha") X(ENVIRONMENT, "environment") X(VARIANCE, "variance") X(EMISSION, "emission") \
  X(DIRECT, "direct") X(INDIRECT, "indirect") X(ALBEDO, "albedo") X(DEPTH, "depth") X(SHADOW, "shadow")
#define ST_X_AOV_ENUM(E, name) ST_AOV_INDEX_##E,
enum st_aov_index { ST_AOVS(ST_X_AOV_ENUM) ST_AOV_COUNT };
#define ST_AOV_BIT(E) (1 << ST_AOV_INDEX_##E)
/* The float4 values a path writes to the batch result buffer (result_index * result_layers + layer). */
enum st_result_layer {
  ST_RESULT_BEAUTY = 0,      /* everything but what the environment layer takes */
  ST_RESULT_ALPHA = 1,       /* xyz: 1 - the camera ray's transmittance estimate, per channel (raygen.cl);
                              * w: the albedo/depth free flight's weight when it collided (1 unless
                              * majorant_scale < 1), else 0 */
  ST_RESULT_ENVIRONMENT = 2, /* lights at infinity seen straight from the camera */
  ST_RESULT_LAYERS_AOV = 3,  /* result_layers when alpha or environment is on, not the passes (else 1) */
  ST_RESULT_EMISSION = 3,    /* the emission pass (its part of the beauty) */
  ST_RESULT_DIRECT = 4,      /* the direct pass (its part of the beauty) */
  ST_RESULT_LAYERS_PASSES = 5, /* result_layers with the emission, direct or indirect pass */
  ST_RESULT_AUX = 5,         /* xyz: sigma_s / sigma_t at the camera ray's first collision, w: its distance (or 0) */
  ST_RESULT_LAYERS_AUX = 6,  /* result_layers with the albedo or depth layer */
  ST_RESULT_SHADOW = 6,      /* the shadow catcher's light-sample estimates times their transmittance (ground.h) */
  ST_RESULT_UNSHADOWED = 7,  /* the same estimates without the transmittance */
  ST_RESULT_LAYERS_SHADOW = 8 /* result_layers with the shadow layer */
};

/* Scene features, as one mask: the kernels are compiled with ST_FEATURES = the scene's mask
 * (specialised) or ST_FEATURES_ALL (the generic kernel, which renders any scene). A feature the
 * mask lacks is code the compiler removes (kernels/features.h maps each bit to one macro); the
 * runtime checks that remain are those of the generic kernel, so both render the same image.
 * Coarse on purpose: every distinct mask is one more compile (seconds on PoCL), so the spectral
 * scheme, uniform environments, directional lights and homogeneous media stay runtime (uniform)
 * branches; the tracker's decomposition, which brings whole code paths, is a feature. */
enum st_feature {
  ST_FEATURE_EMISSION = 1 << 0,       /* some medium emits */
  ST_FEATURE_CHROMATIC = 1 << 1,      /* some medium has channel-dependent coefficients */
  ST_FEATURE_ENV_MAP = 1 << 2,        /* a lat-long environment map */
  ST_FEATURE_ESCAPE = 1 << 3,         /* escaping rays can see a light (environment or disc): escape stage */
  ST_FEATURE_HG = 1 << 4,             /* some medium has a Henyey-Greenstein phase function */
  ST_FEATURE_VDB = 1 << 5,            /* some medium is a NanoVDB grid (else homogeneous boxes only) */
  ST_FEATURE_MULTI_MEDIUM = 1 << 6,   /* more than one medium (overlaps possible) */
  ST_FEATURE_DECOMPOSITION = 1 << 7,  /* tracker decomposes (control + residual) */
  ST_FEATURE_COARSE_MAJORANT = 1 << 8, /* the adaptive majorant hierarchy (kernels/majorant.h) */
  ST_FEATURE_COLOR = 1 << 9,          /* some medium has a per-voxel colour grid (st_color_mode) */
  ST_FEATURE_SPECTRAL_MIS = 1 << 10,  /* tracker spectral-mis (hero-channel sampling, MIS over channels) */
  ST_FEATURE_STOCHASTIC_LOOKUP = 1 << 11, /* density lookups read one voxel chosen at random (st_lookup_mode) */
  ST_FEATURE_AOV = 1 << 12,           /* film layers with per-path work: alpha, environment, the passes (st_scene.aovs) */
  ST_FEATURE_SPECTRAL = 1 << 13,      /* spectral mode: the lanes are wavelengths (st_film_color) */
  ST_FEATURE_GUIDING = 1 << 14,       /* volume path guiding: guided scatter directions, radiance records (guiding.h) */
  ST_FEATURE_LOCAL_LIGHT = 1 << 15,   /* point or spot lights: shadow rays of finite length (light.h, walker.h) */
  ST_FEATURE_GROUND = 1 << 16,        /* an infinite ground plane (ground.h): walks end at it, a surface vertex */
  ST_FEATURE_SPHERE_LIGHT = 1 << 17,  /* emitting spheres: rays end at them (ground.h), cone sampling (light.h) */
  ST_FEATURE_PHASE_SET = 1 << 18,     /* some medium has a Draine blend phase (draine, rayleigh, hg2, mie) */
  ST_FEATURE_EQUIANGULAR = 1 << 19,   /* equi-angular samples towards local lights, MIS with free flights (equiangular.h) */
  ST_FEATURE_RAY_MARCHING = 1 << 20,  /* ray-marching transmittance (transmittance.h): its fields of the shadow entries */
  ST_FEATURE_THIN_LENS = 1 << 21,     /* depth of field: the camera's lens radius is > 0 (raygen.cl camera_ray) */
  ST_FEATURE_TIME = 1 << 22,          /* each path has a time in the shutter that something reads: camera motion */
  ST_FEATURE_VELOCITY = 1 << 23,      /* some medium moves during the shutter (a velocity grid; medium.h); implies TIME */
  ST_FEATURE_PIXEL_WORK = 1 << 24,    /* adaptive sampling's trace: each window pixel's tracking work (queues.h pixel_work_add) */
  ST_FEATURE_ADAPTIVE = 1 << 27,      /* adaptive sampling: raygen starts paths of a list of pixels (queues.h active_pixels) */
  ST_FEATURES_ALL = ((1 << 16) - 1) | ST_FEATURE_GROUND | ST_FEATURE_SPHERE_LIGHT | ST_FEATURE_PHASE_SET | ST_FEATURE_EQUIANGULAR | ST_FEATURE_RAY_MARCHING | ST_FEATURE_THIN_LENS | ST_FEATURE_TIME | ST_FEATURE_VELOCITY
};

/* the wavefront's queues, counters and stage arguments */
#include "stage_types.h"

/* One block entry of the majorant hierarchy (kernels/majorant.h majorant_block_entry; two float2
 * records of the majorant buffer): the block of maj_block^3 fine cells is walked in groups of
 * group^3 cells; group == maj_block: the block whole, with bounds (dmax, dmin); group < maj_block:
 * its (maj_block / group)^3 group bounds lie at maj_offset + pool (x fastest), (dmax, dmin) theirs. */
typedef struct { float dmax, dmin; st_int group; st_uint pool; } st_maj_block;

/* One participating medium as the kernels see it. Coefficients are per unit density and already
 * multiplied by density_scale. The majorant grid is in the medium's index space: cell (i,j,k)
 * spans [maj_origin + (i,j,k) * cell, maj_origin + (i,j,k,+1) * cell) and stores (dmax, dmin)
 * of the trilinearly interpolated density over that box (interpolation support included). With
 * maj_block > 1 the cells form the adaptive hierarchy: st_maj_block entries at maj_coarse_offset,
 * the refined blocks' group bounds in a pool at maj_offset. */
typedef struct {
  st_float4 world_to_index[3]; /* rows of the affine map world -> grid index space */
  st_float4 sigma_a;           /* rgb, per unit density */
  st_float4 sigma_s;           /* rgb, per unit density */
  st_float4 Le;                /* emitted radiance rgb (radiance * scale); 0 when not emissive */
  st_float4 maj_origin;        /* xyz: index-space origin of the majorant grid; w: cell size */
  st_int maj_dims[4];          /* xyz: cells per axis; w unused */
  st_uint maj_offset;          /* first cell (hierarchy: first pool group) of this medium in the majorant buffer (float2) */
  st_uint density_grid;        /* word offset of the NanoVDB density grid, or ST_NO_GRID */
  st_uint emission_grid;       /* word offset of the NanoVDB emission grid, or ST_NO_GRID */
  st_int type;                 /* st_medium_type */
  st_int phase_type;           /* st_phase_type */
  float g;                     /* HG asymmetry; Draine blend: the first lobe's g */
  float majorant_scale;        /* testing: < 1 under-estimates the majorant (weighted tracking stays exact) */
  float minorant_scale;        /* testing: > 1 over-estimates the minorant */
  st_int emissive;             /* 1 if Le != 0 */
  st_int maj_block;            /* fine cells per block edge of the hierarchy; 0: one level */
  st_uint maj_coarse_offset;   /* first st_maj_block entry in the majorant buffer (float2 records) */
  st_int color_mode;           /* st_color_mode; ST_COLOR_NONE: no colour grid */
  st_float4 sigma_t_maj;       /* colour grid: per unit density, an upper bound of sigma_t over the medium (rgb);
                                * spectral mode: the bound of the colour's spectrum per unit of sigma_s (medium.h) */
  st_uint color_grid[4];       /* colour grid: word offsets of its x, y, z component float grids; w: spectral mode,
                                * the RGB-to-spectrum table's (medium.h medium_color_spectrum), else ST_NO_GRID */
  /* blackbody emission (emission_grid holds the temperature grid; Le = (scale, scale, scale)):
   * T = value * x + y, nothing emits where T <= z; w: the warp's A (below) */
  st_float4 temperature;
  /* its colour table in the grid buffer at blackbody_offset (ST_NO_GRID: none): float4 (linear
   * sRGB, ln N: the normaliser of src/color/blackbody.h blackbody_xyz) entries at warped
   * temperatures A / T - w ln T = x + i / y, i = 0 .. z (z = entries - 1) */
  st_float4 blackbody_table;
  st_uint blackbody_offset;
  /* spectral mode: 1 when sigma_a, sigma_s and Le hold spectra, not rgb: the sigmoid coefficients
   * (c0, c1, c2, scale) of kernels/spectrum.h, Le's times CIE D65 (an illuminant); the majorants
   * take the extinction at the path's wavelengths (walker.h st_walker) */
  st_int spectral;
  /* spectral mode, blackbody emission (0 otherwise, and in rgb mode): Le = scale times the film's
   * emission scale (src/color/spectrum.h film_emission_scale) in lanes xyz, and the spectrum is
   * exp(ln B(lambda, T) - ln N(T)) (kernels/medium.h blackbody_spectral_Le); a constant temperature
   * is temperature.y (temperature.x = 0) and its ln N is blackbody_log_norm */
  st_int blackbody;
  float blackbody_log_norm;
  st_float4 phase;             /* Draine blend: (alpha of lobe 1, g of lobe 2, alpha of lobe 2, w: lobe 2's weight) */
  /* motion blur (medium.h medium_lookup_index): x: word offset of the NanoVDB Vec3f velocity grid
   * (ST_NO_GRID when the medium does not move); y, z: unused; w: 1 for a staggered (MAC) grid,
   * whose component a sits half a voxel below the voxel centre along axis a */
  st_uint velocity_grid[4];
  /* rows of the map from a velocity value times a time (s) to an index-space displacement: the
   * inverse of the file's index-to-world linear part times scale (times fps for per-frame grids) */
  st_float4 velocity_to_index[3];
} st_medium;

/* Blackbody colours and spectra below this temperature (K) are those of this temperature (the
 * table's floor, src/color/blackbody.h kBlackbodyTableFloor): 0 for the peak and none
 * normalisations to float precision, the red end of the spectrum for luminance. */
#define ST_BLACKBODY_T_FLOOR 100.0f

typedef struct {
  st_float4 position; /* w: lens radius (world units; 0: pinhole; raygen.cl camera_ray) */
  st_float4 forward;  /* unit; w: focus distance (world units along forward) */
  st_float4 right;    /* perspective: tan(fov/2) * unit right, scaled for the shorter side; ortho: half extent */
  st_float4 up;       /* same for the up axis (image y grows downwards: pixel rows go along -up) */
  st_int type;        /* st_camera_type */
  st_int width, height;
  st_int moving;      /* 1: the camera moves during the shutter (raygen.cl camera_frame) */
  st_float4 position1, look_at0, look_at1; /* motion: position at close; look_at at open, close (w: |right|, |up|) */
  st_float4 up_world, shutter; /* motion: the up as given; x, y: shutter open, close (s), z: time strata (queues.h) */
} st_camera;

typedef struct {
  st_float4 radiance;  /* env uniform: radiance; env map: scale; directional: disc radiance (delta: irradiance);
                        * point, spot: W/sr; sphere: its surface's radiance */
  st_float4 direction; /* directional: unit vector towards the light; spot: unit axis of the cone (from the light) */
  st_float4 position;  /* local: xyz the position (sphere: centre); w: spot: cos(cone_angle - cone_delta), full
                        * intensity inside; sphere: the radius */
  st_int type;         /* st_light_type */
  st_int is_delta;     /* directional with angle 0; point and spot (delta in direction) */
  float cos_max;       /* directional: cos of the half apex angle; spot: cos of the cone angle (intensity 0 beyond) */
  float pdf_cone;      /* directional: 1 / solid angle of the disc */
  /* environment map: texels (rgb float4) and the sampling distribution in the env buffer */
  st_uint map_offset;   /* float4 texels, width*height, row 0 = top (v = 0 at +y): rgb, or in spectral mode the
                         * sigmoid coefficients of each texel's colour (scale = 2 max rgb; kernels/light.h) */
  st_uint cdf_offset;   /* float: marginal cdf (height+1) then conditional cdfs (height*(width+1)) */
  st_int map_width, map_height;
  float map_integral;   /* integral of luminance * sin(theta) over the map's (u,v) domain */
  float select_pmf;     /* probability that next-event estimation picks this light (1 with light sampling "all") */
  float select_cdf;     /* power light sampling: sum of select_pmf over lights 0..this one */
  st_int spectral;      /* spectral mode: radiance holds the sigmoid coefficients of a spectrum that, times D65, is the
                         * light's (an environment map's radiance stays its scale; its texels hold the spectra) */
  float nee_strength;   /* light sampling contribution: a directional light's mean irradiance, an environment's mean
                         * radiance over the sphere (rgb, before spectral mode) */
  float map_turn;       /* environment map: rotate_deg / 360 in [-0.5, 0.5], its right-handed turn about +y (0: none) */
  st_int pad[2];
} st_light;

/* Everything the kernels need about the scene and the render, in one __constant block. */
typedef struct {
  st_camera camera;
  st_light lights[ST_MAX_LIGHTS];
  st_medium media[ST_MAX_MEDIA];
  st_int n_lights;
  st_int n_media;
  st_int tracker;     /* st_tracker */
  st_int scheme;      /* st_scheme */
  st_int max_depth;   /* real scattering events; -1 = unlimited */
  st_uint seed;
  st_int n_channels_per_sample; /* delta-per-channel: one path per lane (3, spectral mode 4), else 1 */
  st_int iteration_budget;      /* tentative collisions + DDA steps per item and launch */
  st_int pixel_x0, pixel_y0;    /* window of the film being rendered */
  st_int window_width, window_height;
  st_int has_env;               /* any environment light */
  st_int chromatic;             /* any medium with channel-dependent coefficients */
  st_int batches_in_flight;     /* ring size: batch b uses ring slot b % batches_in_flight */
  st_int absorption;            /* st_absorption (event: 0, the value of a zero-filled struct) */
  st_int light_sampling;        /* st_light_sampling */
  st_int transmittance;         /* st_transmittance_mode */
  float march_spacing;          /* ray-marching: majorant optical depth between the samples of one estimate */
  float pilot_spacing;          /* ray-marching: the same for the pilot estimate (the expansion point) */
  st_int lookup;                /* st_lookup_mode of density lookups */
  st_int aovs;                  /* st_aov_index bits of the layers asked for */
  st_int result_layers;         /* float4 per path in the batch result buffer: 1, ST_RESULT_LAYERS_AOV or _PASSES */
  st_int color;                 /* st_film_color: what the float4 lanes carry */
  struct {                      /* the ground plane y = height (ground.h; features.h ST_HAS_GROUND) */
    st_float4 albedo;           /* rgb; spectral mode: the sigmoid coefficients of its reflectance */
    st_float4 albedo_rgb;       /* rgb in both modes (the albedo layer) */
    float height;
    st_int mode;                /* st_ground_mode */
    st_int present;             /* 0: no ground */
    st_int spectral;            /* albedo holds the coefficients */
  } ground;
  struct {                      /* equi-angular sampling (equiangular.h; features.h ST_HAS_EQUIANGULAR) */
    st_int n_local;             /* local lights it samples towards (point, spot, sphere), each with 1 / n_local; 0: off */
    float sigma_t;              /* the gray extinction (1/length) of the free-flight density its MIS weights assume */
  } equiangular;
  st_int wavelength_sampling;   /* spectral mode: st_wavelength_sampling of the paths' wavelengths */
  st_int wavelength_sample_offset; /* stratified wavelengths: the sequence index of the render's sample 0 (guiding's
                                    * training samples come first: RenderSettings::guide_training_samples) */
} st_scene;

/* Path state, one slot per path in flight: st_path and its layouts (AoS, SoA) and groups. */
#include "path_state.h"

/* Shadow-ray entries, NL per path slot: st_shadow (with its transmittance estimate st_trans) and
 * its layouts and groups. */
#include "shadow_state.h"

/* What changes from one iteration of the stage loop to the next (one by-value kernel argument). */
typedef struct {
  st_ulong first;              /* raygen: index of the first new path over the whole render */
  st_uint cur;                 /* parity of the queue buffers read this iteration */
  st_uint n_queue[ST_Q_COUNT]; /* items in each queue's current buffer */
  st_uint n_new;               /* raygen: new camera paths, from the top of the free stack (queues.h free_push) */
  st_uint batch_paths;         /* paths per batch of samples */
  st_uint sample_begin;        /* first sample index of the render (shards) */
  st_uint samples_per_batch;
  st_uint pad[3];
} st_iteration;

#define ST_SIZEOF_MEDIUM 336
#define ST_SIZEOF_CAMERA 160
#define ST_SIZEOF_LIGHT 112
#define ST_SIZEOF_SCENE (ST_SIZEOF_CAMERA + ST_MAX_LIGHTS * ST_SIZEOF_LIGHT + ST_MAX_MEDIA * ST_SIZEOF_MEDIUM + 96 + 48 + 16)
#define ST_SIZEOF_PATH 128
#define ST_SIZEOF_TRANS 128
#define ST_SIZEOF_SHADOW 272
#define ST_SIZEOF_ITERATION 64
#define ST_SIZEOF_MAJ_BLOCK 16

#ifdef __OPENCL_VERSION__
#define ST_CHECK_SIZE(T, N) typedef char st_check_##T[(sizeof(T) == (N)) ? 1 : -1];
#else
#define ST_CHECK_SIZE(T, N) static_assert(sizeof(T) == (N), #T " layout");
#endif
ST_CHECK_SIZE(st_medium, ST_SIZEOF_MEDIUM)
ST_CHECK_SIZE(st_camera, ST_SIZEOF_CAMERA)
ST_CHECK_SIZE(st_light, ST_SIZEOF_LIGHT)
ST_CHECK_SIZE(st_scene, ST_SIZEOF_SCENE)
ST_CHECK_SIZE(st_path, ST_SIZEOF_PATH)
ST_CHECK_PATH_LAYOUT
ST_CHECK_SIZE(st_trans, ST_SIZEOF_TRANS)
ST_CHECK_SIZE(st_shadow, ST_SIZEOF_SHADOW)
ST_CHECK_SHADOW_LAYOUT
ST_CHECK_SIZE(st_iteration, ST_SIZEOF_ITERATION)
ST_CHECK_SIZE(st_maj_block, ST_SIZEOF_MAJ_BLOCK)

#endif /* SPECTRACK_TYPES_H */
