/* state_schema.h: the machinery of a state schema (Cycles' state_template.h pattern), shared by the
 * path state (path_state.h, st_path: one entry per path slot) and the shadow-ray entries
 * (shadow_state.h, st_shadow: NL entries per path slot). Part of types.h; include types.h, not this file.
 *
 * Design. A schema S (PATH, SHADOW) is one X-macro list ST_<S>_FIELDS(X) of rows
 * X(S, type, name, group), in the order of its struct, and an enum of group bits ST_<S>_<group>.
 * From the list come, by the generic rows below: the struct's members, the field enum
 * ST_<S>_F_<name>, the byte offsets st_<s>_field_offset(f) (the sum of the sizes before f: a
 * constant where f is), the fields' total size (checked against the struct's on both sides: no
 * padding) and the kernels' group-wise copies between an entry of a buffer and a private struct
 * (ST_X_STATE_LOAD, ST_X_STATE_STORE, through the schema's ST_<S>_FIELD). A buffer of n entries
 * has two layouts of the same n * sizeof(struct) bytes, chosen by the kernel define ST_STATE_SOA
 * (the host's choice per device type, src/integrator/state_layout.h):
 *   AoS (no define): entry i is struct i, its fields side by side (one or a few cache lines on a CPU);
 *   SoA (ST_STATE_SOA): one array per field, field f of entry i at byte n * offset(f) + i * sizeof(f)
 *        (a GPU's warp reads neighbouring values of a field).
 * Each field's offset is a multiple of its size (checked on the host), so every SoA array is aligned. */
#ifndef SPECTRACK_STATE_SCHEMA_H
#define SPECTRACK_STATE_SCHEMA_H

#ifdef __OPENCL_VERSION__
#define ST_STATE_CONSTEXPR inline
#else
#define ST_STATE_CONSTEXPR constexpr inline
#endif

/* The generic rows (S: the schema of the row). */
#define ST_X_STATE_MEMBER(S, type, name, group) type name;
#define ST_X_STATE_FIELD_ENUM(S, type, name, group) ST_##S##_F_##name,
#define ST_X_STATE_BEFORE(S, type, name, group) off += (int)ST_##S##_F_##name < f ? (st_uint)sizeof(type) : 0u;
#define ST_X_STATE_BYTES(S, type, name, group) +(int)sizeof(type)

/* Schema S (s: its lower-case name): enum st_<s>_field (ST_<S>_F_<name>, ST_<S>_FIELD_COUNT) and
 * st_<s>_field_offset(f), the bytes of the fields before field f: its offset in the struct, and in
 * the SoA layout its array's start per entry (times n). */
#define ST_STATE_SCHEMA(S, s)                                                               \
  enum st_##s##_field { ST_##S##_FIELDS(ST_X_STATE_FIELD_ENUM) ST_##S##_FIELD_COUNT };     \
  ST_STATE_CONSTEXPR st_uint st_##s##_field_offset(int f) {                                 \
    st_uint off = 0u;                                                                       \
    ST_##S##_FIELDS(ST_X_STATE_BEFORE)                                                      \
    return off;                                                                             \
  }
#define ST_STATE_FIELD_BYTES(S) (0 ST_##S##_FIELDS(ST_X_STATE_BYTES))

/* Checked at the end of types.h: the fields of S fill its struct (of `size` bytes) without
 * padding, so that the SoA arrays fill the same buffer. (Each schema checks its fields' offsets
 * on the host too: path_state.h, shadow_state.h.) */
#ifdef __OPENCL_VERSION__
#define ST_STATE_CHECK_BYTES(S, s, size) typedef char st_check_##s##_fields[(ST_STATE_FIELD_BYTES(S) == (size)) ? 1 : -1];
#else
#define ST_STATE_CHECK_BYTES(S, s, size) static_assert(ST_STATE_FIELD_BYTES(S) == (size), "st_" #s " fields without padding");
#endif

#ifdef __OPENCL_VERSION__
/* Where a field of entry i of a buffer of n entries is: SoA, element i of the field's array (the
 * field at byte `offset` of the struct); AoS, `offset` bytes into struct i. */
#define ST_STATE_SOA_AT(state, n, i, type, offset) \
  (((__global type*)((__global uchar*)(state) + (size_t)(n) * (offset)))[i])
#define ST_STATE_AOS_AT(state, i, type, offset) (*(__global type*)((__global uchar*)&(state)[i] + (offset)))
/* A buffer of entries of struct T: words in the SoA layout, structs in the AoS layout. */
#ifdef ST_STATE_SOA
#define ST_STATE_BUFFER(T) __global uint*
#else
#define ST_STATE_BUFFER(T) __global T*
#endif

/* The rows of a group-wise copy, in a function of (state, n, i, groups, p): the fields of `groups`
 * (ST_<S>_<group> bits, a constant) of entry i to *p, or from *p to entry i. */
#define ST_X_STATE_LOAD(S, type, name, group) \
  if (groups & ST_##S##_##group) p->name = ST_##S##_FIELD(state, n, i, type, name);
#define ST_X_STATE_STORE(S, type, name, group) \
  if (groups & ST_##S##_##group) ST_##S##_FIELD(state, n, i, type, name) = p->name;
#endif

#endif /* SPECTRACK_STATE_SCHEMA_H */
