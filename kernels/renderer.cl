/* renderer.cl: the renderer's program, the root the kernel assembler (src/device/kernel_source.cpp)
 * starts from. Every kernel file includes what it uses and the assembler inlines each file once,
 * at its first #include; this list fixes one order for the whole program (the shared headers
 * first, then the stage kernels in the order of the stage loop), so the text the device compiler
 * reads, and with it the kernel cache key, changes only when a kernel file does. */
#include "types.h"
#include "features.h"
#include "rng.h"
#include "sampling.h"
#include "film_table.h"
#include "spectrum.h"
#include "phase.h"
#include "pnanovdb_cl.h"
#include "medium.h"
#include "majorant.h"
#include "walker.h"
#include "tracking.h"
#include "transmittance.h"
#include "light.h"
#include "ground.h"
#include "guiding.h"
#include "queues.h"
#include "raygen.cl"
#include "track.cl"
#include "shade.cl"
#include "scatter.cl"
#include "shadow.cl"
#include "finish.cl"
