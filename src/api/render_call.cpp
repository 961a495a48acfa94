// render_call.cpp: see render_call.h.
#include "api/render_call.h"

#include <future>

#include "film/film.h"

namespace spectrack {

MultiDeviceResult render_call(const SceneDesc& scene, const RenderOptions& options, const std::string& device_spec,
                              int chunk_spp, const std::string& json_text) {
  const RenderSettings set = resolve_settings(scene, options);
  const std::vector<std::string> devices = parse_device_list(device_spec);
  std::future<std::string> hash = std::async(std::launch::async, [&] {
    return json_text.empty() ? scene_hash(scene) : scene_hash(scene, json_text);
  });
  MultiDeviceResult r = render_multi_device(scene, options, set, devices, set.sample_begin, set.spp, chunk_spp);
  r.spp_requested = set.spp;
  r.piece.interrupted = r.piece.interrupted || r.piece.samples() < set.spp;
  const std::string h = hash.get();
  if (r.piece.samples() > 0) r.piece.id.scene_hash = h;
  return r;
}

}  // namespace spectrack
