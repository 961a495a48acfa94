// render_call.h: one render of a loaded scene in this process, as a library call (the Python
// module's Scene.render; the command line adds MPI, outputs and signals around the same steps).
//
// Design: the steps are the ones of `spectrack render`: resolve_settings once, the device list
// parsed as --device takes it, render_multi_device over the settings' sample range, and the scene
// hash (which reads every referenced file) computed on a second thread while the devices render,
// so that the film piece carries the identity that lets it merge with the command line's pieces.
// A stop (options.stop) or the deadline ends the render with the finished samples, marked
// interrupted.
#pragma once
#include <string>

#include "integrator/multi_device.h"
#include "integrator/settings.h"
#include "scene/scene.h"

namespace spectrack {

// Renders `scene` with `options` on the devices of `device_spec` ("" the default device, "all",
// or a comma-separated list), chunk_spp samples per pixel at a time with several devices (<= 0:
// automatic). `json_text`, when not empty, is the JSON the scene was parsed from (parse_scene), which
// the scene hash reads instead of the scene file. Throws Error naming the scene file and field, or
// the option, at fault.
MultiDeviceResult render_call(const SceneDesc& scene, const RenderOptions& options, const std::string& device_spec,
                              int chunk_spp = 0, const std::string& json_text = "");

}  // namespace spectrack
