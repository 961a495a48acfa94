/* types.h: the plain-data types and enums shared by the host (C++17) and the device (OpenCL C).
 *
 * Design: one header, compiled by both sides, is the only place where an enum value or a struct
 * layout is written down. Vectors are st_float4 (16 bytes, 16-aligned on both sides; .w is
 * padding unless a comment says otherwise); there are no float3 fields (their size differs between
 * OpenCL and C++). The host static_asserts every struct size in src/cl/types_check.cpp and the
 * device checks the same sizes through st_check_sizes() in kernels (a negative array size fails
 * the build), so a layout drift fails at compile time on both sides.
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

/* ---- enums: one definition; names for the CLI/scene live in src/scene/names.cpp ---- */
enum st_tracker {
  ST_TRACKER_DELTA_PER_CHANNEL = 0,
  ST_TRACKER_DELTA = 1,
  ST_TRACKER_SPECTRAL = 2,
  ST_TRACKER_DECOMPOSITION = 3,
  ST_TRACKER_SPECTRAL_DECOMPOSITION = 4,
  ST_TRACKER_COUNT = 5
};
enum st_scheme {
  ST_SCHEME_MAX = 0,
  ST_SCHEME_AVERAGE = 1,
  ST_SCHEME_HISTORY_MAX = 2,
  ST_SCHEME_HISTORY_AVERAGE = 3,
  ST_SCHEME_COUNT = 4
};
enum st_camera_type { ST_CAMERA_PERSPECTIVE = 0, ST_CAMERA_ORTHOGRAPHIC = 1 };
enum st_light_type { ST_LIGHT_ENV_UNIFORM = 0, ST_LIGHT_ENV_MAP = 1, ST_LIGHT_DIRECTIONAL = 2 };
enum st_medium_type { ST_MEDIUM_VDB = 0, ST_MEDIUM_HOMOGENEOUS = 1 };
enum st_phase_type { ST_PHASE_ISOTROPIC = 0, ST_PHASE_HG = 1 };

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
  ST_FEATURE_COARSE_MAJORANT = 1 << 8, /* two-level majorant grid (empty blocks skipped) */
  ST_FEATURES_ALL = (1 << 9) - 1
};

/* Queues of the wavefront. Each stage reads the current buffer of its queue and pushes into the
 * next buffers; the host swaps them once per iteration. */
enum st_queue {
  ST_Q_FREE = 0,    /* free path slots (raygen input) */
  ST_Q_TRACK = 1,   /* paths to track (free-flight sampling) */
  ST_Q_ESCAPE = 2,  /* paths that left every medium (shade: environment and sun) */
  ST_Q_SCATTER = 3, /* paths at a real scattering event (NEE + phase sampling) */
  ST_Q_FINISH = 4,  /* finished paths (write the sample once its shadow rays are done) */
  ST_Q_SHADOW = 5,  /* shadow rays (transmittance by ratio tracking); capacity slots * ST_MAX_LIGHTS */
  ST_Q_COUNT = 6
};

/* Statistic counters, accumulated on the device per iteration (32-bit) and summed on the host
 * into 64-bit totals. */
enum st_counter {
  ST_C_QUEUE = 0,                        /* ST_Q_COUNT entries: sizes of the next queues */
  ST_C_BATCH_DONE = ST_C_QUEUE + ST_Q_COUNT, /* ST_MAX_BATCHES_IN_FLIGHT entries: finished paths per ring slot */
  ST_C_LOOKUPS_TRACK = ST_C_BATCH_DONE + ST_MAX_BATCHES_IN_FLIGHT, /* density lookups by tracking */
  ST_C_LOOKUPS_SHADOW,                   /* density lookups by shadow rays */
  ST_C_LOOKUPS_EMISSION,                 /* emission-grid lookups */
  ST_C_REAL_COLLISIONS,                  /* absorption + scattering events */
  ST_C_NULL_COLLISIONS,
  ST_C_CONTROL_COLLISIONS,
  ST_C_RESIDUAL_COLLISIONS,
  ST_C_DDA_STEPS,
  ST_C_REQUEUES,                         /* items that used up their launch budget */
  ST_C_NONFINITE,                        /* samples dropped because they were NaN or Inf */
  ST_C_MAX_THROUGHPUT_BITS,              /* float bits of the largest beta component (atomic_max) */
  ST_C_SCATTER_EVENTS,
  ST_C_DDA_NONEMPTY,                     /* DDA steps that entered a cell with a non-zero majorant */
  ST_C_COUNT
};

/* One participating medium as the kernels see it. Coefficients are per unit density and already
 * multiplied by density_scale. The majorant grid is in the medium's index space: cell (i,j,k)
 * spans [maj_origin + (i,j,k) * cell, maj_origin + (i,j,k,+1) * cell) and stores (dmax, dmin)
 * of the trilinearly interpolated density over that box (interpolation support included). */
typedef struct {
  st_float4 world_to_index[3]; /* rows of the affine map world -> grid index space */
  st_float4 sigma_a;           /* rgb, per unit density */
  st_float4 sigma_s;           /* rgb, per unit density */
  st_float4 Le;                /* emitted radiance rgb (radiance * scale); 0 when not emissive */
  st_float4 maj_origin;        /* xyz: index-space origin of the majorant grid; w: cell size */
  st_int maj_dims[4];          /* xyz: cells per axis; w unused */
  st_uint maj_offset;          /* first cell of this medium in the majorant buffer (float2 cells) */
  st_uint density_grid;        /* word offset of the NanoVDB density grid, or ST_NO_GRID */
  st_uint emission_grid;       /* word offset of the NanoVDB emission grid, or ST_NO_GRID */
  st_int type;                 /* st_medium_type */
  st_int phase_type;           /* st_phase_type */
  float g;                     /* HG asymmetry */
  float majorant_scale;        /* testing: < 1 under-estimates the majorant (weighted tracking stays exact) */
  float minorant_scale;        /* testing: > 1 over-estimates the minorant */
  st_int emissive;             /* 1 if Le != 0 */
  st_int maj_block;            /* fine cells per coarse-block edge of the two-level grid; 0: one level */
  st_uint maj_coarse_offset;   /* first coarse block in the majorant buffer (float2: dmax, dmin over the block) */
  st_int pad;                  /* coarse blocks per axis: ceil(maj_dims / maj_block) */
} st_medium;

typedef struct {
  st_float4 position;
  st_float4 forward; /* unit */
  st_float4 right;   /* perspective: tan(fov/2) * unit right, scaled for the shorter side; ortho: half extent */
  st_float4 up;      /* same for the up axis (image y grows downwards: pixel rows go along -up) */
  st_int type;       /* st_camera_type */
  st_int width, height;
  st_int pad;
} st_camera;

typedef struct {
  st_float4 radiance;  /* env uniform: radiance; env map: scale; directional: radiance of the disc (or irradiance when delta) */
  st_float4 direction; /* directional: unit vector towards the light */
  st_int type;         /* st_light_type */
  st_int is_delta;     /* directional with angle 0 */
  float cos_max;       /* directional: cos of the half apex angle */
  float pdf_cone;      /* directional: 1 / solid angle of the disc */
  /* environment map: texels (rgb float4) and the sampling distribution in the env buffer */
  st_uint map_offset;   /* float4 texels, width*height, row 0 = top (v = 0 at +y) */
  st_uint cdf_offset;   /* float: marginal cdf (height+1) then conditional cdfs (height*(width+1)) */
  st_int map_width, map_height;
  float map_integral;   /* integral of luminance * sin(theta) over the map's (u,v) domain */
  st_int pad[3];
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
  st_int n_channels_per_sample; /* 3 for delta-per-channel (one path per channel), else 1 */
  st_int iteration_budget;      /* tentative collisions + DDA steps per item and launch */
  st_int pixel_x0, pixel_y0;    /* window of the film being rendered */
  st_int window_width, window_height;
  st_int has_env;               /* any environment light */
  st_int chromatic;             /* any medium with channel-dependent coefficients */
  st_int batches_in_flight;     /* ring size: batch b uses ring slot b % batches_in_flight */
  st_int pad;
} st_scene;

/* Path state, one slot per path in flight. */
typedef struct {
  st_float4 o;        /* xyz: ray origin; w: t reached along the ray (resume point) */
  st_float4 d;        /* xyz: unit direction; w: pdf of the phase sample that made d (0: camera ray) */
  st_float4 beta;     /* throughput weight per channel */
  st_float4 L;        /* radiance gathered by this path (emission, escape) */
  st_float4 mask;     /* 1 for the channels this path carries, 0 otherwise */
  st_uint pixel;      /* pixel index in the film window */
  st_uint sample;     /* sample index in the full sequence */
  st_uint channel;    /* 0..2 for delta-per-channel, 0 otherwise */
  st_uint result_index; /* slot in the batch result buffer */
  st_uint rng_draw;   /* next draw of the path's random stream */
  st_int depth;       /* real scattering events so far */
  st_int pending;     /* shadow rays of this path not finished yet */
  st_int medium;      /* medium whose phase function applies at the scatter point */
  st_uint batch;      /* ring slot of this path's batch */
  st_uint pad[3];
} st_path;

/* Shadow ray: slot * ST_MAX_LIGHTS + light. */
typedef struct {
  st_float4 o;        /* xyz origin; w: t reached */
  st_float4 d;        /* xyz unit direction */
  st_float4 weight;   /* contribution if the transmittance were 1 */
  st_float4 T;        /* running transmittance estimate per channel */
  st_float4 Ls;       /* this light's contributions gathered over the path's bounces */
  st_uint rng_draw;
  st_uint stream;     /* random stream id (bounce, light) */
  st_uint slot;       /* owning path slot */
  st_uint pad;
} st_shadow;

#define ST_SIZEOF_MEDIUM 176
#define ST_SIZEOF_CAMERA 80
#define ST_SIZEOF_LIGHT 80
#define ST_SIZEOF_SCENE (ST_SIZEOF_CAMERA + ST_MAX_LIGHTS * ST_SIZEOF_LIGHT + ST_MAX_MEDIA * ST_SIZEOF_MEDIUM + 64)
#define ST_SIZEOF_PATH 128
#define ST_SIZEOF_SHADOW 96

#ifdef __OPENCL_VERSION__
typedef char st_check_medium[(sizeof(st_medium) == ST_SIZEOF_MEDIUM) ? 1 : -1];
typedef char st_check_camera[(sizeof(st_camera) == ST_SIZEOF_CAMERA) ? 1 : -1];
typedef char st_check_light[(sizeof(st_light) == ST_SIZEOF_LIGHT) ? 1 : -1];
typedef char st_check_scene[(sizeof(st_scene) == ST_SIZEOF_SCENE) ? 1 : -1];
typedef char st_check_path[(sizeof(st_path) == ST_SIZEOF_PATH) ? 1 : -1];
typedef char st_check_shadow[(sizeof(st_shadow) == ST_SIZEOF_SHADOW) ? 1 : -1];
#else
static_assert(sizeof(st_medium) == ST_SIZEOF_MEDIUM, "st_medium layout");
static_assert(sizeof(st_camera) == ST_SIZEOF_CAMERA, "st_camera layout");
static_assert(sizeof(st_light) == ST_SIZEOF_LIGHT, "st_light layout");
static_assert(sizeof(st_scene) == ST_SIZEOF_SCENE, "st_scene layout");
static_assert(sizeof(st_path) == ST_SIZEOF_PATH, "st_path layout");
static_assert(sizeof(st_shadow) == ST_SIZEOF_SHADOW, "st_shadow layout");
#endif

#endif /* SPECTRACK_TYPES_H */
