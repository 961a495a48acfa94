// sequence_camera.h: the camera of a frame sequence (`spectrack render --frames A:B`, docs/cli.md
// "Frame sequences").
//
// Design: a camera that frames the media ("look_at": "media", "position": "auto", "fit";
// scene/framing.h) is framed once for the whole sequence, from the union of every frame's media
// boxes, so it does not move from frame to frame; each frame then renders with that camera, its
// framing resolved. A frame whose VDB media are all empty adds no box and is named in a warning
// (it renders, with the sequence's camera). The boxes come from loading each frame's grids once
// before the first render; a camera that frames nothing needs no such pass.
#pragma once
#include <string>
#include <vector>

#include "scene/scene.h"

namespace spectrack {

struct SequenceCamera {
  CameraDesc camera;                   // framing resolved (or the scene's camera as it is)
  std::vector<long long> empty_frames;  // frames whose VDB media are all empty (framing pass only)
};

// The camera of frames first..last of `scene` (whose media's files hold frame patterns). Writes
// one warning per empty frame to stderr unless `quiet`. Throws Error naming the file for a grid
// that cannot be read, and when every frame is empty but the camera frames the media.
SequenceCamera sequence_camera(const SceneDesc& scene, long long first, long long last, bool quiet);

}  // namespace spectrack
