// render_outputs.h: what a render writes once its stage loop has ended (rank 0): the image, the
// preview, the statistics and the summary line, and the exit code.
//
// Design: a render that finished no sample (the time limit or a signal came before the first
// batch) writes nothing, since a black image would pass for a frame: the time limit raises
// TimeLimitError (exit kExitTimeLimit), a signal exits 130 with a message. Otherwise every file
// goes through an OutputFile (util/output_file.h), so each is whole or absent, and a failed write
// is an Error naming the file and the reason. The exit code is 130 whenever a signal came, also
// one that came after the last sample (the files are still written in full).
#pragma once
#include <string>

#include "image/image.h"
#include "integrator/multi_device.h"
#include "scene/scene.h"

namespace spectrack {

struct RenderOutputs {
  std::string image, preview, stats_json;  // empty preview / stats_json: none
  ExrOptions exr;
  bool quiet = false;
  bool mpi = false;  // record mpi_ranks in the metadata
  bool denoise = false;     // also write the denoised beauty (image/denoise.h) as an EXR layer
};

// The times the statistics record, in seconds from the command's (or frame's) start.
struct RenderTimes {
  double total = 0, to_renderer = 0;
};

// Rank 0: writes the outputs of `r` (or nothing, as above) and returns the exit code.
int finish_render(const RenderOutputs& o, const SceneDesc& scene, const MultiDeviceResult& r, const RenderTimes& t,
                  int mpi_ranks, double time_limit, bool signalled);

}  // namespace spectrack
