// merge.cpp: `spectrack merge OUT.exr IN.exr... [--preview FILE.png] [--half] [--compression C]`:
// combines sample-range shards and pixel tiles of one render into one EXR.
//
// Design: every input's header is read and checked first (a spectrack EXR, no dropped samples,
// consistent sample counts), the merge is planned on the headers (film/film.h: plan_merge),
// and only then are the pixels streamed through, a band of rows at a time
// (film/merge_files.h), so memory stays bounded whatever the number and size of the inputs.
// The merged image and its preview appear whole or not at all.
#include "cli/merge.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <iostream>

#include "cli/checks.h"
#include "cli/options.h"
#include "film/film.h"
#include "film/merge_files.h"
#include "scene/scene.h"
#include "util/strings.h"

namespace spectrack {

CLI::App* add_merge_command(CLI::App& app, MergeArgs& ma) {
  auto* merge = app.add_subcommand("merge", "combine sample-range shards and tiles (EXR) into one EXR");
  merge->add_option("output", ma.output, "the merged EXR")->required();
  merge->add_option("inputs", ma.inputs, "EXR outputs of `spectrack render` (shards and/or tiles)")->required()->expected(1, -1);
  merge->add_option("--preview", ma.preview, "also write a PNG preview")->check(png_file());
  merge->add_flag("-q,--quiet", ma.quiet, "no summary line");
  merge->add_flag("--half", ma.half, "16-bit half-float EXR channels (the result cannot be merged again)");
  merge->add_option("--compression", ma.compression, "EXR compression (default zip)")
      ->check(one_of("compression", exr_compressions()));
  return merge;
}

namespace {

// The record of the inputs: their render time summed, their devices, the scene.
Metadata merged_metadata(const std::vector<MergeInput>& inputs) {
  double seconds = 0;
  std::vector<std::string> devices;
  std::string scene;
  for (const MergeInput& in : inputs) {
    const Metadata& head = in.meta;
    if (auto f = head.find("render_seconds"); f != head.end() && std::holds_alternative<float>(f->second))
      seconds += std::get<float>(f->second);
    if (auto d = head.find("device"); d != head.end() && std::holds_alternative<std::string>(d->second))
      if (std::find(devices.begin(), devices.end(), std::get<std::string>(d->second)) == devices.end())
        devices.push_back(std::get<std::string>(d->second));
    if (auto s = head.find("scene"); s != head.end() && std::holds_alternative<std::string>(s->second))
      scene = std::get<std::string>(s->second);
  }
  std::string device;
  for (auto& d : devices) device += (device.empty() ? "" : ", ") + d;
  Metadata meta;
  meta["render_seconds"] = float(seconds);
  meta["device"] = device;
  meta["scene"] = scene;
  meta["merged_inputs"] = int(inputs.size());
  return meta;
}

}  // namespace

int cmd_merge(const MergeArgs& a) {
  std::string ext = lower_extension(a.output);
  if (ext != ".exr") throw Error(fmt::format("{}: the merged image must be an EXR (use --preview for a PNG)", a.output));
  check_output_path(a.output);
  if (!a.preview.empty()) check_output_path(a.preview);
  check_distinct_paths({{"the merged image", a.output}, {"--preview", a.preview}}, merge_inputs(a.inputs));
  std::error_code ec;
  std::vector<MergeInput> inputs;
  std::vector<FilmPiece> headers;
  for (auto& in : a.inputs) {
    if (std::filesystem::exists(a.output, ec) && std::filesystem::equivalent(in, a.output, ec))
      throw Error(fmt::format("{}: is both an input and the output of the merge", in));
    inputs.push_back(read_merge_header(in));
    check_merge_input(in, inputs.back().meta);
    headers.push_back(inputs.back().piece);
    if (headers.back().interrupted && !a.quiet)
      std::cerr << fmt::format("warning: {} is an interrupted render: it holds samples {} only\n", in,
                               format_ranges(headers.back().ranges));
  }
  const FilmPiece m = plan_merge(headers);
  ExrOptions exr;
  exr.half = a.half;
  exr.compression = a.compression.empty() ? FilmDesc{}.compression : a.compression;
  write_merged(inputs, m, a.output, a.preview, merged_metadata(inputs), exr);
  if (!a.quiet)
    std::cerr << fmt::format("merged {} inputs: samples {} of pixels {},{},{},{} (x0,x1,y0,y1) of the {}x{} film -> {}\n",
                             inputs.size(), format_ranges(m.ranges), m.x0, m.x0 + m.width, m.y0, m.y0 + m.height,
                             m.id.full_width, m.id.full_height, a.output);
  return 0;
}

}  // namespace spectrack
