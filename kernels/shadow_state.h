/* shadow_state.h: the schema of the shadow-ray entries (st_shadow, with its transmittance estimate
 * st_trans), NL entries per path slot. Part of types.h (included after path_state.h); include
 * types.h, not this file.
 *
 * Design: the path state's pattern (state_schema.h). ST_SHADOW_FIELDS is the one list of an
 * entry's fields, X(SHADOW, type, name, group): the rows before the transmittance estimate, the
 * estimate's own (ST_TRANS_FIELDS, from which st_trans comes: the probes and raygen's alpha use it
 * alone) and the rows after it; st_shadow is the first part, an st_trans `tr`, the last part. The
 * shadow buffer of Q * NL entries is AoS or SoA by the same kernel define as the path buffer
 * (ST_STATE_SOA): SoA, field f of entry i at byte Q * NL * st_shadow_field_offset(f) + i * sizeof(f);
 * AoS, entry i is st_shadow i and a field is st_shadow_field_offset(f) bytes into it (the offsets
 * are st_shadow's, the estimate's fields included: checked on the host). The kernels reach an entry
 * by its index (queues.h shadow_entry) through shadow_load / shadow_store of groups:
 *   RAY:     origin and t reached, direction, the ray's end t_max: k_shadow;
 *   WEIGHT:  the contribution if the transmittance were 1, and whether it is the shadow catcher's:
 *            k_shadow (roulette's importance), the folds;
 *   T:       the estimate (ratio tracking's only field; done: the transmittance);
 *   MARCH:   ray marching's other fields, loaded and stored only where the feature mask compiles
 *            ray marching in (queues.h ST_SHADOW_TRANS);
 *   KEY:     the random stream (its id and next draw) and the owning path slot: k_shadow;
 *   LS:      ring-0 entries: the light's accumulator (cold: raygen clears it, the folds add to it,
 *            finish reads it);
 *   SEGMENT: equi-angular entries: the path's segment, which the tracker's MIS weights read;
 *   EA:      equi-angular entries: the leg, the light and the segment's index (k_shadow, the fold);
 *   STATUS:  empty, pending or done (st_shadow_state): the folds, k_shadow, shadow_begin;
 *   PAD:     padding, never read or written (0 from the host's fill). */
#ifndef SPECTRACK_SHADOW_STATE_H
#define SPECTRACK_SHADOW_STATE_H

#include "state_schema.h"

enum st_shadow_group {
  ST_SHADOW_RAY = 1,
  ST_SHADOW_WEIGHT = 2,
  ST_SHADOW_T = 4,
  ST_SHADOW_MARCH = 8,
  ST_SHADOW_KEY = 16,
  ST_SHADOW_LS = 32,
  ST_SHADOW_SEGMENT = 64,
  ST_SHADOW_EA = 128,
  ST_SHADOW_STATUS = 256,
  ST_SHADOW_PAD = 512,
  ST_SHADOW_ALL = 1023
};

/* A transmittance estimate in progress, resumable across launches (transmittance.h). Ratio tracking
 * uses T only; ray marching (docs/transmittance.md) walks the ray once for the pilot and the
 * first estimate together (pass 0) and once more for each further term of the series. */
#define ST_TRANS_FIELDS(X)                                                                                            \
  X(SHADOW, st_float4, T, T)          /* ratio: running estimate; ray marching: P_0 = exp(-(tau_ctrl + tau_c)), then the estimate */ \
  X(SHADOW, st_float4, tau_c, MARCH)  /* the expansion point (residual optical depth from the pilot) */                \
  X(SHADOW, st_float4, P, MARCH)      /* the current term, divided by the probability of reaching it (pass 0: the roulette factor) */ \
  X(SHADOW, st_float4, S, MARCH)      /* the sum of the terms so far (pass 0: the control's optical depth so far) */      \
  X(SHADOW, st_float4, acc, MARCH)    /* pass 0: the pilot's sum of sigma / mu_bar; later: the pass's */                  \
  X(SHADOW, st_float4, acc1, MARCH)   /* pass 0: the first estimate's sum of sigma / mu_bar */                           \
  X(SHADOW, float, s_left, MARCH)     /* majorant optical depth to the next pilot (later: pass) sample; < 0: not started */ \
  X(SHADOW, float, s_left1, MARCH)    /* pass 0: the same for the first estimate's samples */                            \
  X(SHADOW, float, tau_maj, MARCH)    /* the residual majorant's optical depth along the ray (pass 0) */                 \
  X(SHADOW, st_uint, count, MARCH)    /* pass 0: pilot samples */                                                        \
  X(SHADOW, st_uint, count1, MARCH)   /* pass 0: first-estimate samples */                                               \
  X(SHADOW, st_int, pass, MARCH)      /* 0 the pilot and term 1, k >= 2 term k */                                        \
  X(SHADOW, st_int, pilot_met, MARCH) /* pass 0: the first non-empty segment was met (the pilot samples it) */           \
  X(SHADOW, st_int, pad0, PAD)

/* Shadow-ray entry slot * NL + ring * n_lights + light, ring = bounce % R (NL = n_lights * R
 * entries per path slot, R the shadow ring). The ring-0 entries' Ls also hold each light's
 * accumulator: the finished entries' weight * T, added in bounce order (scatter.cl, finish.cl). */
#define ST_SHADOW_HEAD_FIELDS(X)                                                                    \
  X(SHADOW, st_float4, o, RAY)        /* xyz origin; w: t reached */                                \
  X(SHADOW, st_float4, d, RAY)        /* xyz unit direction */                                      \
  X(SHADOW, st_float4, weight, WEIGHT) /* contribution if the transmittance were 1 */               \
  X(SHADOW, st_float4, Ls, LS)        /* ring-0 entries: this light's contributions gathered over the path's bounces */
/* equi-angular entries (equiangular.h; the entry after the lights'): the path's segment, its origin
 * and t0 (w), its unit direction and t1 (w), which the tracker's MIS weights read too; the leg (0:
 * not an equi-angular sample, 1: along the segment, 2: to the light), the light, the segment (the
 * depth of the scatter events on it) */
#define ST_SHADOW_TAIL_FIELDS(X)                                                                    \
  X(SHADOW, st_uint, rng_draw, KEY)   /* next draw of the entry's random stream */                 \
  X(SHADOW, st_uint, stream, KEY)     /* random stream id (bounce, light) */                        \
  X(SHADOW, st_uint, slot, KEY)       /* owning path slot */                                        \
  X(SHADOW, st_uint, state, STATUS)   /* st_shadow_state */                                         \
  X(SHADOW, float, t_max, RAY)        /* where the ray ends (a local light's distance; else INFINITY) */ \
  X(SHADOW, st_uint, catcher, WEIGHT) /* 1 when it is the shadow catcher's (ground.h) */            \
  X(SHADOW, st_uint, pad1, PAD)                                                                     \
  X(SHADOW, st_uint, pad2, PAD)                                                                     \
  X(SHADOW, st_float4, seg_o, SEGMENT)                                                              \
  X(SHADOW, st_float4, seg_d, SEGMENT)                                                              \
  X(SHADOW, st_uint, ea_leg, EA)                                                                    \
  X(SHADOW, st_uint, ea_light, EA)                                                                  \
  X(SHADOW, st_uint, ea_segment, EA)                                                                \
  X(SHADOW, st_uint, pad3, PAD)
/* X(SHADOW, type, name, group), in the order of the AoS struct. */
#define ST_SHADOW_FIELDS(X) ST_SHADOW_HEAD_FIELDS(X) ST_TRANS_FIELDS(X) ST_SHADOW_TAIL_FIELDS(X)

typedef struct {
  ST_TRANS_FIELDS(ST_X_STATE_MEMBER)
} st_trans;

typedef struct {
  ST_SHADOW_HEAD_FIELDS(ST_X_STATE_MEMBER)
  st_trans tr; /* the transmittance estimate (done: its T) */
  ST_SHADOW_TAIL_FIELDS(ST_X_STATE_MEMBER)
} st_shadow;

ST_STATE_SCHEMA(SHADOW, shadow) /* enum st_shadow_field, st_shadow_field_offset */

/* Checked at the end of types.h: the fields fill st_shadow without padding, each at its offset in
 * st_shadow (the estimate's at tr's offset plus theirs in st_trans) and aligned to its size. */
#ifdef __OPENCL_VERSION__
#define ST_CHECK_SHADOW_LAYOUT ST_STATE_CHECK_BYTES(SHADOW, shadow, ST_SIZEOF_SHADOW)
#else
#define ST_X_SHADOW_CHECK_AT(type, name, aos_offset)                                        \
  static_assert(st_shadow_field_offset(ST_SHADOW_F_##name) == (aos_offset) &&                \
                    st_shadow_field_offset(ST_SHADOW_F_##name) % sizeof(type) == 0,          \
                "st_shadow." #name " offset");
#define ST_X_SHADOW_CHECK(S, type, name, group) ST_X_SHADOW_CHECK_AT(type, name, offsetof(st_shadow, name))
#define ST_X_SHADOW_TRANS_CHECK(S, type, name, group) \
  ST_X_SHADOW_CHECK_AT(type, name, offsetof(st_shadow, tr) + offsetof(st_trans, name))
#define ST_CHECK_SHADOW_LAYOUT                                                    \
  ST_STATE_CHECK_BYTES(SHADOW, shadow, ST_SIZEOF_SHADOW)                          \
  ST_SHADOW_HEAD_FIELDS(ST_X_SHADOW_CHECK) ST_TRANS_FIELDS(ST_X_SHADOW_TRANS_CHECK) \
  ST_SHADOW_TAIL_FIELDS(ST_X_SHADOW_CHECK)
#endif

#ifdef __OPENCL_VERSION__
/* The shadow buffer (SoA: as words); field `name` of entry i of n (Q * NL): SoA in its own array,
 * AoS at its offset in st_shadow i. */
#define ST_SHADOW_STATE ST_STATE_BUFFER(st_shadow)
#ifdef ST_STATE_SOA
#define ST_SHADOW_FIELD(state, n, i, type, name) ST_STATE_SOA_AT(state, n, i, type, st_shadow_field_offset(ST_SHADOW_F_##name))
#else
#define ST_SHADOW_FIELD(state, n, i, type, name) ST_STATE_AOS_AT(state, i, type, st_shadow_field_offset(ST_SHADOW_F_##name))
#endif

/* The estimate's fields of `groups` (st_shadow_group bits, a constant) of entry i to *p. */
inline void shadow_trans_load(ST_SHADOW_STATE state, uint n, uint i, uint groups, st_trans* p) {
  ST_TRANS_FIELDS(ST_X_STATE_LOAD)
}
inline void shadow_trans_store(ST_SHADOW_STATE state, uint n, uint i, uint groups, const st_trans* p) {
  ST_TRANS_FIELDS(ST_X_STATE_STORE)
}

/* Copies the fields of `groups` of entry i (of n) into *p. */
inline void shadow_load(ST_SHADOW_STATE state, uint n, uint i, uint groups, st_shadow* p) {
  ST_SHADOW_HEAD_FIELDS(ST_X_STATE_LOAD)
  shadow_trans_load(state, n, i, groups, &p->tr);
  ST_SHADOW_TAIL_FIELDS(ST_X_STATE_LOAD)
}

/* Writes the fields of `groups` of *p to entry i (of n). */
inline void shadow_store(ST_SHADOW_STATE state, uint n, uint i, uint groups, const st_shadow* p) {
  ST_SHADOW_HEAD_FIELDS(ST_X_STATE_STORE)
  shadow_trans_store(state, n, i, groups, &p->tr);
  ST_SHADOW_TAIL_FIELDS(ST_X_STATE_STORE)
}

/* The state (st_shadow_state) of entry e of the n shadow entries. */
inline uint shadow_status(ST_SHADOW_STATE shadows, uint n, uint e) {
  st_shadow s;
  shadow_load(shadows, n, e, ST_SHADOW_STATUS, &s);
  return s.state;
}

/* L plus a path's lights' accumulators, the Ls of its ring-0 entries slot * NL + l (l < n_lights),
 * added in light order: what the path gathered. */
inline float4 shadow_gathered(ST_SHADOW_STATE shadows, uint n, uint NL, int n_lights, uint slot, float4 L) {
  for (int l = 0; l < n_lights; ++l) {
    st_shadow a;
    shadow_load(shadows, n, slot * NL + (uint)l, ST_SHADOW_LS, &a);
    L += a.Ls;
  }
  return L;
}
#endif

#endif /* SPECTRACK_SHADOW_STATE_H */
