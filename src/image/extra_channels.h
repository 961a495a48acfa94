// extra_channels.h: the EXR channels spectrack writes beside the film layers (docs/aov.md): an
// adaptive film's samples per pixel (integrator/adaptive.h; a merge refuses the file) and the
// denoised beauty (--denoise, image/denoise.h; a merge drops it). film_io.cpp writes them,
// image.cpp lets a merge input hold them.
#pragma once

namespace spectrack {

inline constexpr const char* kSamplesChannel = "samples";
inline constexpr const char* kDenoisedChannels[3] = {"denoised.R", "denoised.G", "denoised.B"};

}  // namespace spectrack
