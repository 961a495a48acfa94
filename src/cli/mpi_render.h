// mpi_render.h: `spectrack render --mpi`, one frame over the ranks of an MPI job (built only when
// CMake finds MPI: SPECTRACK_HAVE_MPI). Each rank renders a disjoint sample range of the frame on
// its own device(s); the films (exact per-pixel sums in double) are reduced to rank 0 with
// MPI_Reduce, and the ranks' ranges and statistics are gathered there as JSON text, so rank 0
// writes the one image and statistics a single process would have written (to float rounding).
#pragma once
#include <string>
#include <vector>

#include "film/film.h"
#include "integrator/multi_device.h"

namespace spectrack {

struct MpiWorld {
  int rank = 0, size = 1;
  int local_rank = 0, local_size = 1;  // among the ranks on this node (MPI_COMM_TYPE_SHARED)
};

// MPI_Init and the rank layout; throws Error when MPI fails to start.
MpiWorld mpi_start(int* argc, char*** argv);
void mpi_finish();
// Ends every rank of the job (after one rank failed: the others would wait in the reduction).
[[noreturn]] void mpi_abort(int code);

// This rank's share [begin, end) of the render's samples: contiguous, in rank order, the guide's
// training samples in one share (settings.h guide_part_boundary).
std::pair<int64_t, int64_t> mpi_sample_share(const MpiWorld& w, const RenderSettings& s);
// Without an explicit device: the local_rank-th GPU of this node when it has several, else "".
std::string mpi_default_device(const MpiWorld& w);

// Reduces every rank's result to rank 0, whose `r` becomes the frame's (piece, statistics, device
// list and samples per device of all ranks, slowest rank's seconds); other ranks keep theirs.
// Every rank must call it; a rank without samples passes a piece of its window with zero sums.
void mpi_reduce_to_root(const MpiWorld& w, MultiDeviceResult& r);

}  // namespace spectrack
