// mpi_render.cpp: see mpi_render.h. Rank 0 checks that the gathered ranges are disjoint (they are
// by construction; a mismatch means ranks ran with different options) before it trusts the sums.
#include "cli/mpi_render.h"

#include <mpi.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>

#include "device/opencl.h"
#include "integrator/stats_json.h"

namespace spectrack {

static void mpi_check(int code, const char* what) {
  if (code == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int len = 0;
  MPI_Error_string(code, text, &len);
  throw Error(fmt::format("MPI error in {}: {}", what, std::string(text, size_t(len))));
}

MpiWorld mpi_start(int* argc, char*** argv) {
  mpi_check(MPI_Init(argc, argv), "MPI_Init");
  MpiWorld w;
  mpi_check(MPI_Comm_rank(MPI_COMM_WORLD, &w.rank), "MPI_Comm_rank");
  mpi_check(MPI_Comm_size(MPI_COMM_WORLD, &w.size), "MPI_Comm_size");
  MPI_Comm node;
  mpi_check(MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, w.rank, MPI_INFO_NULL, &node),
            "MPI_Comm_split_type");
  MPI_Comm_rank(node, &w.local_rank);
  MPI_Comm_size(node, &w.local_size);
  MPI_Comm_free(&node);
  return w;
}

void mpi_finish() { MPI_Finalize(); }

void mpi_abort(int code) {
  MPI_Abort(MPI_COMM_WORLD, code);
  std::exit(code);
}

std::pair<int64_t, int64_t> mpi_sample_share(const MpiWorld& w, const RenderSettings& s) {
  const int64_t a = s.sample_begin + int64_t(s.spp) * w.rank / w.size;
  const int64_t b = s.sample_begin + int64_t(s.spp) * (w.rank + 1) / w.size;
  return {guide_part_boundary(s, a), guide_part_boundary(s, b)};
}

std::string mpi_default_device(const MpiWorld& w) {
  if (std::getenv("SPECTRACK_DEVICE")) return "";
  std::vector<std::string> gpus;
  for (auto& d : enumerate_devices(false))
    if (d.type & CL_DEVICE_TYPE_GPU) gpus.push_back(fmt::format("{}:{}", d.platform_index, d.device_index));
  if (gpus.size() > 1) return gpus[size_t(w.local_rank) % gpus.size()];
  return "";
}

void mpi_reduce_to_root(const MpiWorld& w, MultiDeviceResult& r) {
  FilmPiece& p = r.piece;
  nlohmann::json mine = {{"rank", w.rank},
                         {"ranges", format_ranges(p.ranges)},
                         {"samples", p.samples()},
                         {"window", {p.x0, p.y0, p.width, p.height}},
                         {"interrupted", p.interrupted},
                         {"stats", stats_to_json(r.stats)},
                         {"devices", r.devices},
                         {"samples_per_device", r.samples_per_device},
                         {"seconds_render", r.seconds_render},
                         {"seconds_setup", r.seconds_setup},
                         {"seconds_build", r.seconds_build},
                         {"kernels_from_cache", r.kernels_from_cache}};
  std::string text = mine.dump();
  int len = int(text.size());
  std::vector<int> lens(size_t(w.size), 0), offsets(size_t(w.size), 0);
  mpi_check(MPI_Gather(&len, 1, MPI_INT, lens.data(), 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Gather");
  std::string all;
  if (w.rank == 0) {
    int total = 0;
    for (int i = 0; i < w.size; ++i) offsets[size_t(i)] = total, total += lens[size_t(i)];
    all.resize(size_t(total));
  }
  mpi_check(MPI_Gatherv(text.data(), len, MPI_CHAR, all.data(), lens.data(), offsets.data(), MPI_CHAR, 0,
                        MPI_COMM_WORLD),
            "MPI_Gatherv");
  std::vector<double> total_sum(w.rank == 0 ? p.sum.size() : 0);
  mpi_check(MPI_Reduce(p.sum.data(), w.rank == 0 ? total_sum.data() : nullptr, int(p.sum.size()), MPI_DOUBLE,
                       MPI_SUM, 0, MPI_COMM_WORLD),
            "MPI_Reduce");
  std::vector<double> total_aov(w.rank == 0 ? p.aov_sum.size() : 0);
  if (!p.aov_sum.empty())  // the film layers: every rank has the same (ranks run with the same options)
    mpi_check(MPI_Reduce(p.aov_sum.data(), w.rank == 0 ? total_aov.data() : nullptr, int(p.aov_sum.size()), MPI_DOUBLE,
                         MPI_SUM, 0, MPI_COMM_WORLD),
              "MPI_Reduce");
  if (w.rank != 0) return;

  MultiDeviceResult out = r;
  out.stats = RenderStats{};
  out.devices.clear();
  out.samples_per_device.clear();
  out.kernels_from_cache = true;
  std::vector<SampleRange> ranges;
  int64_t count = 0;
  for (int i = 0; i < w.size; ++i) {
    auto j = nlohmann::json::parse(all.substr(size_t(offsets[size_t(i)]), size_t(lens[size_t(i)])));
    auto win = j.at("window").get<std::vector<int>>();
    if (win != std::vector<int>{p.x0, p.y0, p.width, p.height})
      throw Error(fmt::format("--mpi: rank {} rendered another pixel window than rank 0 (ranks must run with the same "
                              "options)", i));
    if (j.at("samples").get<int64_t>() > 0) {
      auto rs = parse_ranges(j.at("ranges").get<std::string>(), fmt::format("--mpi: rank {}", i));
      ranges.insert(ranges.end(), rs.begin(), rs.end());
      count += j.at("samples").get<int64_t>();
    }
    out.piece.interrupted |= j.at("interrupted").get<bool>();
    out.stats.add(stats_from_json(j.at("stats")));
    for (auto& d : j.at("devices")) out.devices.push_back(fmt::format("rank {}: {}", i, d.get<std::string>()));
    for (auto& n : j.at("samples_per_device")) out.samples_per_device.push_back(n.get<int64_t>());
    out.seconds_render = std::max(out.seconds_render, j.at("seconds_render").get<double>());
    out.seconds_setup = std::max(out.seconds_setup, j.at("seconds_setup").get<double>());
    out.seconds_build = std::max(out.seconds_build, j.at("seconds_build").get<double>());
    out.kernels_from_cache = out.kernels_from_cache && j.at("kernels_from_cache").get<bool>();
  }
  out.piece.ranges = join_ranges(ranges);
  if (count_samples(out.piece.ranges) != count)
    throw Error("--mpi: the ranks' sample ranges overlap (ranks must run with the same options)");
  out.piece.sum = std::move(total_sum);
  out.piece.aov_sum = std::move(total_aov);
  r = std::move(out);
}

}  // namespace spectrack
