// info.cpp: `spectrack info` (info.h). Volumes through inspect_volume (volume/inspect.h), scenes
// through load_scene and the loaders (scene/media_bounds.h); the camera as framing resolves it.
// A scene is then packed as `render` packs it with the scene's own settings (resolve_settings,
// pack_scene: host work, no device), so that every check render makes of the scene's data (grids,
// maps, numbers the kernels' floats cannot hold) is made here too, once, in the render's words.
// The report's density grids stay loaded (volume.h KeptGrids) and the pack takes them: one read of
// each file, which matters for VDB files of gigabytes.
#include "cli/info.h"
#include "cli/render.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>

#include "scene/frames.h"
#include "scene/media_bounds.h"
#include "scene/sequence_camera.h"
#include "scene/framing.h"
#include "scene/scene.h"
#include "scene/scene_pack.h"
#include "integrator/settings.h"
#include "util/error.h"
#include "volume/inspect.h"
#include "volume/volume.h"
#include "util/strings.h"

namespace spectrack {
namespace {

using json = nlohmann::json;

json vec(const Vec3& v) { return json::array({v[0], v[1], v[2]}); }
json vec(const std::array<double, 3>& v, int) { return json::array({v[0], v[1], v[2]}); }
json ivec(const std::array<int, 3>& v) { return json::array({v[0], v[1], v[2]}); }
std::string v3(const std::array<double, 3>& v) { return fmt::format("({:.6g}, {:.6g}, {:.6g})", v[0], v[1], v[2]); }
std::string i3(const std::array<int, 3>& v) { return fmt::format("({}, {}, {})", v[0], v[1], v[2]); }

std::string bytes_str(int64_t b) {
  if (b < 0) return "n/a";
  if (b < (1 << 20)) return fmt::format("{:.1f} KiB", b / 1024.0);
  return fmt::format("{:.2f} MiB", b / 1048576.0);
}

json volume_json(const std::string& file, const std::vector<GridInfo>& grids) {
  json out = {{"file", file}, {"kind", "volume"}, {"grids", json::array()}};
  for (const GridInfo& g : grids) {
    json j = {{"name", g.name}, {"type", g.type}, {"class", g.cls}, {"empty", g.empty},
              {"active_voxels", g.active_voxels}, {"voxel_size", vec(g.voxel_size, 0)},
              {"density_use", g.density_use}};
    if (!g.velocity_use.empty()) j["velocity_use"] = g.velocity_use;
    if (!g.empty) {
      j["index_bbox"] = {ivec(g.index_min), ivec(g.index_max)};
      j["world_bbox"] = {vec(g.world_min, 0), vec(g.world_max, 0)};
    } else {
      j["index_bbox"] = nullptr;
      j["world_bbox"] = nullptr;
    }
    j["value_range"] = g.has_range ? json::array({g.value_min, g.value_max}) : json(nullptr);
    j["nanovdb_bytes"] = g.nanovdb_bytes >= 0 ? json(g.nanovdb_bytes) : json(nullptr);
    out["grids"].push_back(j);
  }
  return out;
}

void print_volume(const std::string& file, const std::vector<GridInfo>& grids) {
  std::cout << fmt::format("{}: {} grid{}\n", file, grids.size(), grids.size() == 1 ? "" : "s");
  for (size_t i = 0; i < grids.size(); ++i) {
    const GridInfo& g = grids[i];
    std::cout << fmt::format("  [{}] {:<20} {} ({})\n", i, g.name.empty() ? "<unnamed>" : "\"" + printable_name(g.name) + "\"",
                             printable_name(g.type), g.cls);
    if (g.empty) {
      std::cout << "      bbox           empty (no active values)\n";
    } else {
      const std::array<int, 3> dims{g.index_max[0] - g.index_min[0] + 1, g.index_max[1] - g.index_min[1] + 1,
                                    g.index_max[2] - g.index_min[2] + 1};
      std::cout << fmt::format("      index bbox     {} .. {}  ({} x {} x {} voxels)\n", i3(g.index_min), i3(g.index_max),
                               dims[0], dims[1], dims[2]);
      std::cout << fmt::format("      world bbox     {} .. {}\n", v3(g.world_min), v3(g.world_max));
    }
    std::cout << fmt::format("      voxel size     {}\n", v3(g.voxel_size));
    std::cout << fmt::format("      active voxels  {}\n", g.active_voxels);
    std::cout << fmt::format("      value range    {}\n", g.has_range ? fmt::format("{:.6g} .. {:.6g}{}", g.value_min, g.value_max,
                                                                                 g.type.rfind("vec", 0) == 0 ? " (length)" : "")
                                                                   : std::string("n/a"));
    std::cout << fmt::format("      as NanoVDB     {}\n", bytes_str(g.nanovdb_bytes));
    std::cout << fmt::format("      as density     {}\n", g.density_use);
    if (!g.velocity_use.empty()) std::cout << fmt::format("      as velocity    {}\n", g.velocity_use);
  }
}

// For --json's "warnings": a vdb medium whose fire preset finds none of its grids in the file (the
// render takes such a scene and it renders without emission; the pack below prints the warning on
// stderr, and a grid the scene names and the file lacks is the pack's error). Empty otherwise.
std::string emission_grid_warning(const SceneDesc& s, const MediumDesc& md) {
  const EmissionDesc& e = md.emission;
  if (md.type != ST_MEDIUM_VDB || !e.present || !e.blackbody || e.temperature > 0 || !e.temperature_grid.empty() ||
      e.temperature_grid_choices.empty())
    return "";
  const std::vector<std::string> grids = list_grids(md.file);
  for (const auto& choice : e.temperature_grid_choices)
    if (grid_listed(grids, choice.first)) return "";
  std::string all;
  for (const std::string& g : grids) all += (all.empty() ? "" : ", ") + g;
  return fmt::format("{}: {}/preset: {} has none of the preset's fire grids (its grids: {}); the medium renders "
                     "without emission", s.path, md.json_path, md.file, all);
}

const char* light_type(int t) {
  return t == ST_LIGHT_DIRECTIONAL ? "directional"
         : t == ST_LIGHT_ENV_MAP   ? "environment (map)"
         : t == ST_LIGHT_POINT     ? "point"
         : t == ST_LIGHT_SPOT      ? "spot"
         : t == ST_LIGHT_SPHERE    ? "sphere"
                                   : "environment (uniform)";
}

// One medium of `info`'s scene report: its world box (in *box), largest extinction and optical
// depths, as JSON and as lines of text appended to t. A VDB medium's grid is loaded into `kept`,
// where the pack that follows finds it.
json medium_json(const SceneDesc& s, const MediumDesc& md, std::string& t, Box3* box, KeptGrids& kept) {
  json m = {{"name", md.name}, {"type", md.type == ST_MEDIUM_VDB ? "vdb" : "homogeneous"}};
  Box3 b;
  double dmax = 1, voxel = 0;
  if (md.type == ST_MEDIUM_VDB) {
    const GridData& g = kept.load(md.file, md.grid, md.grid_index, s.path + ": " + md.json_path);
    b = medium_world_box(md, g);
    dmax = g.value_max;
    // the longest world step of one index unit along an axis
    const Vec3 o = medium_index_to_world(md, g, {0, 0, 0});
    for (int a = 0; a < 3; ++a) {
      Vec3 e{0, 0, 0};
      e[a] = 1;
      const Vec3 w = medium_index_to_world(md, g, e);
      voxel = std::max(voxel, std::sqrt((w[0] - o[0]) * (w[0] - o[0]) + (w[1] - o[1]) * (w[1] - o[1]) + (w[2] - o[2]) * (w[2] - o[2])));
    }
    m["file"] = md.file;
    m["grid"] = g.name;
    m["density_range"] = {g.value_min, g.value_max};
    m["voxel_world_size"] = voxel;
  } else {
    b = Box3{md.bounds[0], md.bounds[1]};
  }
  *box = b;
  const double diag = std::sqrt((b.hi[0] - b.lo[0]) * (b.hi[0] - b.lo[0]) + (b.hi[1] - b.lo[1]) * (b.hi[1] - b.lo[1]) +
                                (b.hi[2] - b.lo[2]) * (b.hi[2] - b.lo[2]));
  Vec3 st, tau_diag, tau_voxel;
  for (int c = 0; c < 3; ++c) {
    st[c] = (md.sigma_s[c] + md.sigma_a[c]) * md.density_scale;
    tau_diag[c] = st[c] * dmax * diag;
    tau_voxel[c] = st[c] * dmax * voxel;
  }
  m["world_bbox"] = {vec(b.lo), vec(b.hi)};
  const Vec3 st_max{st[0] * dmax, st[1] * dmax, st[2] * dmax};
  m["sigma_t_max"] = vec(st_max);
  m["optical_depth_diagonal_max"] = vec(tau_diag);
  if (md.type == ST_MEDIUM_VDB) m["optical_depth_voxel_max"] = vec(tau_voxel);
  const std::string warning = emission_grid_warning(s, md);
  if (!warning.empty()) {
    m["warnings"] = json::array({warning});
  }
  t += fmt::format("  medium \"{}\" ({}{})\n", md.name, md.type == ST_MEDIUM_VDB ? "vdb " : "homogeneous",
                   md.type == ST_MEDIUM_VDB ? md.file : "");
  t += fmt::format("      world bbox     {} .. {}\n", v3(b.lo), v3(b.hi));
  t += fmt::format("      max sigma_t    {}  (coefficients x density_scale x max density {:.6g})\n", v3(st_max),
                   dmax);
  t += fmt::format("      optical depth  up to {} along the box diagonal", v3(tau_diag));
  t += md.type == ST_MEDIUM_VDB ? fmt::format(", up to {} per voxel\n", v3(tau_voxel)) : std::string("\n");
  return m;
}

json scene_json(const SceneDesc& s, std::string* text, KeptGrids& kept) {
  json out = {{"file", s.path}, {"kind", "scene"}, {"media", json::array()}, {"lights", json::array()}};
  std::string& t = *text;
  t += fmt::format("{}: scene, {}x{} film, {} spp, tracker {}\n", s.path, s.film.width, s.film.height, s.film.spp,
                   tracker_name(s.render.tracker));
  std::vector<Box3> boxes;
  for (const MediumDesc& md : s.media) {
    Box3 b;
    out["media"].push_back(medium_json(s, md, t, &b, kept));
    boxes.push_back(b);
  }
  for (const LightDesc& l : s.lights) {
    json j = {{"type", light_type(l.type)}};
    std::string what;
    if (l.type == ST_LIGHT_DIRECTIONAL) {
      j["to_light"] = vec(l.to_light), j["irradiance"] = vec(l.irradiance), j["angle_deg"] = l.angle_deg;
      what = fmt::format("to_light {}, irradiance {}, angle {:.3g} deg", v3(l.to_light), v3(l.irradiance), l.angle_deg);
    } else if (l.type == ST_LIGHT_SPHERE) {
      j["position"] = vec(l.position), j["radius"] = l.radius, j["radiance"] = vec(l.radiance);
      what = fmt::format("position {}, radius {:g}, radiance {}", v3(l.position), l.radius, v3(l.radiance));
    } else if (l.type == ST_LIGHT_POINT || l.type == ST_LIGHT_SPOT) {
      j["position"] = vec(l.position), j["intensity"] = vec(l.intensity);
      what = fmt::format("position {}, intensity {} W/sr", v3(l.position), v3(l.intensity));
      if (l.type == ST_LIGHT_SPOT) {
        j["look_at"] = vec(l.look_at), j["cone_angle_deg"] = l.cone_angle_deg, j["cone_delta_deg"] = l.cone_delta_deg;
        what += fmt::format(", look_at {}, cone {:.3g} deg, falloff {:.3g} deg", v3(l.look_at), l.cone_angle_deg,
                            l.cone_delta_deg);
      }
    } else if (l.type == ST_LIGHT_ENV_MAP && l.sky) {
      const SkyDesc& k = *l.sky;
      j["sky"] = {{"sun_elevation_deg", k.sun_elevation_deg}, {"sun_azimuth_deg", k.sun_azimuth_deg},
                  {"intensity", k.intensity}, {"resolution", k.resolution}};
      what = fmt::format("sky, sun at elevation {:.3g} deg, azimuth {:.3g} deg, intensity {:.6g}, map {}x{}",
                         k.sun_elevation_deg, k.sun_azimuth_deg, k.intensity, k.resolution, k.resolution / 2);
    } else if (l.type == ST_LIGHT_ENV_MAP) {
      j["map"] = l.map, j["scale"] = l.scale, j["rotate_deg"] = l.rotate_deg;
      what = fmt::format("map {}, scale {:.6g}, rotate_deg {:.6g} (about +y)", l.map, l.scale, l.rotate_deg);
    } else {
      j["radiance"] = vec(l.radiance);
      what = fmt::format("radiance {}", v3(l.radiance));
    }
    out["lights"].push_back(j);
    t += fmt::format("  light {}: {}\n", light_type(l.type), what);
  }
  if (s.ground.present) {
    out["ground"] = {{"height", s.ground.height}, {"albedo", vec(s.ground.albedo)}, {"mode", ground_mode_name(s.ground.mode)}};
    t += fmt::format("  ground: height {:g}, albedo {}, {}\n", s.ground.height, v3(s.ground.albedo), ground_mode_name(s.ground.mode));
  }
  const CameraDesc& c0 = s.camera;
  const CameraDesc c = frame_camera(c0, s.film.width, s.film.height, boxes, s.path + ": /camera");
  json cam = {{"type", c.type == ST_CAMERA_ORTHOGRAPHIC ? "orthographic" : "perspective"},
              {"position", vec(c.position)}, {"look_at", vec(c.look_at)}, {"up", vec(c.up)},
              {"framed", camera_needs_framing(c0)}};
  if (c.type == ST_CAMERA_ORTHOGRAPHIC) cam["height"] = c.height; else cam["fov_deg"] = c.fov_deg;
  json in_view = json::array();
  for (const Box3& b : boxes) in_view.push_back(box_in_view(c, s.film.width, s.film.height, b, 1e-6));
  cam["media_in_view"] = in_view;
  t += fmt::format("  camera {}{}: position {}, look_at {}, up {}, {}\n", cam["type"].get<std::string>(),
                   camera_needs_framing(c0) ? " (framed)" : "", v3(c.position), v3(c.look_at), v3(c.up),
                   c.type == ST_CAMERA_ORTHOGRAPHIC ? fmt::format("height {:.6g}", c.height) : fmt::format("fov {:.6g} deg", c.fov_deg));
  if (c.aperture_radius > 0) {
    cam["aperture_radius"] = c.aperture_radius;
    cam["focus_distance"] = c.focus_distance;  // 0: the distance to look_at
    t += fmt::format("      thin lens      aperture radius {:.6g}, focus {}\n", c.aperture_radius,
                     c.focus_distance > 0 ? fmt::format("at {:.6g}", c.focus_distance) : std::string("on look_at"));
  }
  if (c.shutter) {
    cam["shutter"] = {(*c.shutter)[0], (*c.shutter)[1]};
    t += fmt::format("      shutter        {:.6g} .. {:.6g} s\n", (*c.shutter)[0], (*c.shutter)[1]);
  }
  if (c.position_close) cam["position_close"] = vec(*c.position_close);
  if (c.look_at_close) cam["look_at_close"] = vec(*c.look_at_close);
  if (c.position_close || c.look_at_close)
    t += fmt::format("      at close       position {}, look_at {}\n", v3(c.position_close.value_or(c.position)),
                     v3(c.look_at_close.value_or(c.look_at)));
  for (size_t i = 0; i < boxes.size(); ++i)
    if (!in_view[i].get<bool>()) t += fmt::format("      note: medium \"{}\" is not entirely in view (see \"look_at\": \"media\" and \"fit\")\n", s.media[i].name);
  out["camera"] = cam;
  return out;
}

// The files of a volume frame pattern over the frames (a plain name: itself).
std::vector<std::string> volume_frames(const std::string& f, const std::optional<std::array<long long, 2>>& frames) {
  if (!has_frame_pattern(std::filesystem::path(f).filename().string())) return {f};
  if (!frames) throw Error(fmt::format("{}: is a frame pattern: give the frames with --frames A:B", f));
  std::vector<std::string> out;
  for (long long n = (*frames)[0]; n <= (*frames)[1]; ++n) out.push_back(expand_frame(f, n));
  return out;
}

// A scene's frames, each with its media's files expanded and the sequence's camera
// (scene/sequence_camera.h); a scene without frame patterns: itself.
std::vector<SceneDesc> scene_frames(const SceneDesc& s, const std::optional<std::array<long long, 2>>& frames, bool quiet) {
  bool patterned = false;
  for (const MediumDesc& m : s.media) patterned |= has_frame_pattern(std::filesystem::path(m.file).filename().string());
  if (!patterned) return {s};
  if (!frames) throw Error(fmt::format("{}: its media's files are frame patterns: give the frames with --frames A:B", s.path));
  const CameraDesc camera = sequence_camera(s, (*frames)[0], (*frames)[1], quiet).camera;
  std::vector<SceneDesc> out;
  for (long long n = (*frames)[0]; n <= (*frames)[1]; ++n) {
    SceneDesc frame = s;
    frame.camera = camera;
    for (MediumDesc& m : frame.media) m.file = expand_frame(m.file, n);
    frame.path = fmt::format("{} (frame {})", s.path, n);
    out.push_back(frame);
  }
  return out;
}

}  // namespace

int cmd_info(const std::vector<std::string>& files, bool as_json, const std::optional<std::array<long long, 2>>& frames) {
  json all = json::array();
  int failed = 0;
  for (const std::string& f : files) {
    const std::string ext = lower_extension(f);
    const bool volume = ext == ".vdb" || ext == ".nvdb";  // else a scene, whatever its name, as render reads it
    try {
      if (!volume) {
        std::string text;
        for (const SceneDesc& s : scene_frames(load_scene(f), frames, as_json)) {
          text.clear();
          KeptGrids kept;  // the report's grids, read once: the pack takes them
          all.push_back(scene_json(s, &text, kept));
          if (!as_json) std::cout << text;
          // render's own checks of the scene's data, with the scene's settings (no flags)
          try {
            RenderOptions opt;
            opt.aovs = film_layers(RenderArgs(), s, s.film.output);  // the scene's own output
            const RenderSettings set = resolve_settings(s, opt);
            pack_scene(s, set, pack_options(set));
            all.back()["renders"] = true;
          } catch (const std::exception& e) {
            all.back()["renders"] = false;
            all.back()["error"] = e.what();
            std::cerr << "error: " << e.what() << "\n";
            ++failed;
          }
        }
      } else {
        for (const std::string& file : volume_frames(f, frames)) {
          const std::vector<GridInfo> grids = inspect_volume(file);
          all.push_back(volume_json(file, grids));
          if (!as_json) print_volume(file, grids);
        }
      }
    } catch (const std::exception& e) {
      const std::string hint =
          volume || ext == ".json" ? "" : " (info reads volumes, .vdb and .nvdb, and scene files of JSON)";
      std::cerr << "error: " << e.what() << hint << "\n";
      if (as_json) all.push_back({{"file", f}, {"error", e.what() + hint}});
      ++failed;
    }
  }
  if (as_json) std::cout << all.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";  // names from files need not be UTF-8
  return failed ? 1 : 0;
}

}  // namespace spectrack
