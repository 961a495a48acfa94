// film_watch.cpp: film states on disk (film_watch.h). The header is text (the format, the key, the
// sample range and the film's shape, and the SHA-1 of the shape line and the floats, on four
// lines), the floats follow in the host's byte order; a state is only ever read back on the
// machine kind that wrote it (the key names the version). The digest makes a damaged file (a
// changed sample count, flipped bits) an error naming the file instead of a wrong image.
#include "integrator/film_watch.h"

#include <OpenImageIO/hash.h>
#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "util/files.h"
#include "util/output_file.h"

namespace spectrack {
namespace {

constexpr const char* kFormat = "spectrack-film-state/2";

// The digest of a state: its shape line and its floats.
std::string film_state_digest(const std::string& shape, const std::vector<float>& film) {
  OIIO::SHA1 h;
  h.append(shape.data(), shape.size());
  h.append(film.data(), film.size() * sizeof(float));
  return h.digest();
}

}  // namespace

std::string film_state_key(const RenderIdentity& id, const FilmWindow& w, int64_t sample_begin, int spp) {
  std::string key = fmt::format("scene_hash={} film={}x{} seed={}", id.scene_hash, id.full_width, id.full_height, id.seed);
  for (const RecordedChoice& c : recorded_choices()) key += fmt::format(" {}={}", c.key, id.*c.field);  // as merge compares them
  return key + fmt::format(" aovs={} version={} window={},{},{},{} samples={}:{} little_endian={}", id.aovs, id.version,
                           w.x0, w.y0, w.width, w.height, sample_begin, sample_begin + spp,
                           __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__);
}

void write_film_state(const std::string& path, const FilmState& st, const std::string& key) {
  OutputFile f(path);
  const std::string shape = fmt::format("{} {} {} {}", st.sample_begin, st.samples_done, st.npix, st.layers);
  const std::string head = fmt::format("{}\n{}\n{}\n{}\n", kFormat, key, shape, film_state_digest(shape, st.film));
  f.append(head.data(), head.size());
  f.append(st.film.data(), st.film.size() * sizeof(float));
  f.commit();
}

FilmState read_film_state(const std::string& path, const std::string& key) {
  check_input_file(path, "film state (--resume)");  // a FIFO would block, a folder is no state
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(fmt::format("{}: cannot read the checkpoint's film state: {}", path, std::strerror(errno)));
  std::string format, file_key, shape, digest;
  if (!std::getline(in, format) || format != kFormat)
    throw Error(fmt::format("{}: not a film state of this version (its first line is not '{}')", path, kFormat));
  if (!std::getline(in, file_key) || !std::getline(in, shape) || !std::getline(in, digest))
    throw Error(fmt::format("{}: the film state's header is cut short (it ends before its fourth line)", path));
  if (file_key != key)
    throw Error(fmt::format("{}: the film state belongs to another render (a different scene, film, seed, estimator or "
                            "schedule choice, shutter, camera, layers, version or sample range):\n  file:   {}\n  render: {}",
                            path, file_key, key));
  FilmState st;
  std::istringstream ss(shape);
  std::string rest;
  if (!(ss >> st.sample_begin >> st.samples_done >> st.npix >> st.layers) || (ss >> rest) || st.samples_done < 1 ||
      st.npix == 0 || st.layers == 0 || st.layers > 64 || st.npix > (uint64_t(1) << 40))
    throw Error(fmt::format("{}: malformed film state header '{}'", path, shape));
  const uint64_t bytes = 2 * st.layers * st.npix * 4 * sizeof(float);
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  const auto at = in.tellg();
  if (ec || at < 0 || size != uint64_t(at) + bytes)
    throw Error(fmt::format("{}: the film state is truncated or too long ({} bytes of film expected after its header)",
                            path, bytes));
  st.film.resize(bytes / sizeof(float));
  in.read(reinterpret_cast<char*>(st.film.data()), std::streamsize(st.film.size() * sizeof(float)));
  if (size_t(in.gcount()) != st.film.size() * sizeof(float) || in.peek() != std::char_traits<char>::eof())
    throw Error(fmt::format("{}: the film state is truncated or too long (expected {} bytes of film after its header)",
                            path, st.film.size() * sizeof(float)));
  if (digest != film_state_digest(shape, st.film))
    throw Error(fmt::format("{}: the film state is damaged: its SHA-1 is not the one its header records (remove it to "
                            "render from the first sample)", path));
  for (size_t i = 0; i < st.film.size(); ++i)
    if (!std::isfinite(st.film[i]))
      throw Error(fmt::format("{}: the film state holds a non-finite value at float {} (remove it to render from the "
                              "first sample)", path, i));
  return st;
}

}  // namespace spectrack
