// sequence_camera.cpp: see sequence_camera.h.
#include "scene/sequence_camera.h"

#include <fmt/format.h>

#include "scene/media_bounds.h"
#include "scene/frames.h"
#include "scene/framing.h"
#include "util/error.h"
#include "util/warning.h"
#include "volume/volume.h"

namespace spectrack {

SequenceCamera sequence_camera(const SceneDesc& scene, long long first, long long last, bool quiet) {
  SequenceCamera out;
  out.camera = scene.camera;
  if (!camera_needs_framing(scene.camera)) return out;
  std::vector<Box3> boxes;  // every frame's: framing fits each one and aims at their union's centre
  auto add = [&](const Box3& b) { boxes.push_back(b); };
  for (long long f = first; f <= last; ++f) {
    bool has_vdb = false, has_content = false;
    for (const MediumDesc& md : scene.media) {
      if (md.type == ST_MEDIUM_HOMOGENEOUS) {
        add(Box3{md.bounds[0], md.bounds[1]});
        continue;
      }
      MediumDesc m = md;
      m.file = expand_frame(md.file, f);
      has_vdb = true;
      const GridData g = load_float_grid(m.file, m.grid, m.grid_index, scene.path + ": " + m.json_path);
      if (g.empty) continue;
      has_content = true;
      add(medium_world_box(m, g));
    }
    if (has_vdb && !has_content) {
      out.empty_frames.push_back(f);
      if (!quiet)
        warn(fmt::format("frame {}: every medium's grid is empty ({}); it renders with the sequence's camera", f,
                         expand_frame(scene.media[0].file, f)));
    }
  }
  if (boxes.empty())
    throw Error(fmt::format("{}: /camera: the camera frames the media, but every frame {}..{} is empty", scene.path,
                            first, last));
  out.camera = frame_camera(scene.camera, scene.film.width, scene.film.height, boxes, scene.path + ": /camera");
  return out;
}

}  // namespace spectrack
