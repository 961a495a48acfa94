/* features.h: the one place where the scene-feature mask (st_feature in types.h) becomes macros.
 *
 * Design (after Cycles' feature mask, with LuxCore's lesson: specialise on a few coarse features
 * only, and always keep a generic kernel). The host compiles the kernels with
 * defines ST_FEATURES (a #define atop the assembled source, so it is part of the kernel-cache key)
 * as the scene's mask, or ST_FEATURES_ALL for the generic kernel (--generic-kernels). Each ST_HAS_* is a compile-time constant; code guards a feature with
 * `ST_HAS_X && <the runtime test the generic kernel makes>`, so when the scene lacks X the
 * compiler drops the code, and when it has X the specialised kernel runs exactly the generic
 * code. A scene therefore renders the same image (bit for bit, one seed) with either kernel.
 * No #if is woven through the core logic: only these macros.
 */
#ifndef SPECTRACK_FEATURES_H
#define SPECTRACK_FEATURES_H

#include "types.h"

#ifndef ST_FEATURES
#define ST_FEATURES ST_FEATURES_ALL
#endif

#define ST_HAS(f) ((ST_FEATURES & (f)) != 0)
#define ST_HAS_EMISSION ST_HAS(ST_FEATURE_EMISSION)
#define ST_HAS_CHROMATIC ST_HAS(ST_FEATURE_CHROMATIC)
#define ST_HAS_ENV_MAP ST_HAS(ST_FEATURE_ENV_MAP)
#define ST_HAS_ESCAPE ST_HAS(ST_FEATURE_ESCAPE)
#define ST_HAS_HG ST_HAS(ST_FEATURE_HG)
#define ST_HAS_VDB ST_HAS(ST_FEATURE_VDB)
#define ST_HAS_MULTI_MEDIUM ST_HAS(ST_FEATURE_MULTI_MEDIUM)
#define ST_HAS_DECOMPOSITION ST_HAS(ST_FEATURE_DECOMPOSITION)
#define ST_HAS_COARSE_MAJORANT ST_HAS(ST_FEATURE_COARSE_MAJORANT)
#define ST_HAS_COLOR ST_HAS(ST_FEATURE_COLOR)
#define ST_HAS_SPECTRAL_MIS ST_HAS(ST_FEATURE_SPECTRAL_MIS)
#define ST_HAS_STOCHASTIC_LOOKUP ST_HAS(ST_FEATURE_STOCHASTIC_LOOKUP)
#define ST_HAS_AOV ST_HAS(ST_FEATURE_AOV)
#define ST_HAS_SPECTRAL ST_HAS(ST_FEATURE_SPECTRAL)
#define ST_HAS_GUIDING ST_HAS(ST_FEATURE_GUIDING)
#define ST_HAS_THIN_LENS ST_HAS(ST_FEATURE_THIN_LENS)
#define ST_HAS_TIME ST_HAS(ST_FEATURE_TIME)
#define ST_HAS_VELOCITY ST_HAS(ST_FEATURE_VELOCITY)
#define ST_HAS_LOCAL_LIGHT ST_HAS(ST_FEATURE_LOCAL_LIGHT)
#define ST_HAS_GROUND ST_HAS(ST_FEATURE_GROUND)
#define ST_HAS_SPHERE_LIGHT ST_HAS(ST_FEATURE_SPHERE_LIGHT)
#define ST_HAS_PHASE_SET ST_HAS(ST_FEATURE_PHASE_SET)
#define ST_HAS_EQUIANGULAR ST_HAS(ST_FEATURE_EQUIANGULAR)
#define ST_HAS_RAY_MARCHING ST_HAS(ST_FEATURE_RAY_MARCHING)
#define ST_HAS_ADAPTIVE ST_HAS(ST_FEATURE_ADAPTIVE)
#define ST_HAS_PIXEL_WORK ST_HAS(ST_FEATURE_PIXEL_WORK)

#endif
