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
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

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

// A state's key as (name, value) fields in order; film_state_key writes them as "name=value" words
// (a value may hold spaces: the majorant grid's and the camera's choices do).
std::vector<std::pair<std::string, std::string>> key_fields(const RenderIdentity& id, const FilmWindow& w,
                                                            int64_t sample_begin, int spp) {
  std::vector<std::pair<std::string, std::string>> f = {
      {"scene_hash", id.scene_hash}, {"film", fmt::format("{}x{}", id.full_width, id.full_height)},
      {"seed", fmt::format("{}", id.seed)}};
  for (const RecordedChoice& c : recorded_choices()) f.emplace_back(c.key, fmt::format("{}", id.*c.field));  // as merge compares them
  f.emplace_back("aovs", fmt::format("{}", id.aovs));
  f.emplace_back("version", id.version);
  f.emplace_back("window", fmt::format("{},{},{},{}", w.x0, w.y0, w.width, w.height));
  f.emplace_back("samples", fmt::format("{}:{}", sample_begin, sample_begin + spp));
  f.emplace_back("little_endian", fmt::format("{}", __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__));
  return f;
}

// A key's value of each field name, found as " name=" in the names' order (a value runs to the
// next name found); a name the key lacks is absent.
std::map<std::string, std::string> parse_key(const std::string& key, const std::vector<std::string>& names) {
  std::vector<std::pair<size_t, size_t>> at(names.size(), {std::string::npos, 0});  // value begin, name begin
  size_t from = 0;
  for (size_t i = 0; i < names.size(); ++i) {
    const std::string word = (i == 0 ? "" : " ") + names[i] + "=";
    const size_t p = i == 0 ? (key.rfind(word, 0) == 0 ? 0 : std::string::npos) : key.find(word, from);
    if (p == std::string::npos) continue;
    at[i] = {p + word.size(), p};
    from = p + word.size();
  }
  std::map<std::string, std::string> out;
  for (size_t i = 0; i < names.size(); ++i) {
    if (at[i].first == std::string::npos) continue;
    size_t end = key.size();
    for (size_t j = i + 1; j < names.size(); ++j)
      if (at[j].first != std::string::npos) {
        end = at[j].second;
        break;
      }
    out[names[i]] = key.substr(at[i].first, end - at[i].first);
  }
  return out;
}

// The fields two keys disagree on, in the key's order: "seed (the file's 1, this render's 2), ...".
std::string key_differences(const std::string& file_key, const std::string& key) {
  std::vector<std::string> names;
  for (const auto& f : key_fields(RenderIdentity(), FilmWindow(), 0, 0)) names.push_back(f.first);
  const auto in_file = parse_key(file_key, names), in_render = parse_key(key, names);
  auto shown = [](const std::map<std::string, std::string>& m, const std::string& name) {
    const auto it = m.find(name);
    return it == m.end() ? std::string("none") : it->second.empty() ? std::string("(empty)") : it->second;
  };
  std::string out;
  for (const std::string& name : names) {
    if (shown(in_file, name) == shown(in_render, name)) continue;
    out += fmt::format("{}{} (the file's {}, this render's {})", out.empty() ? "" : ", ", name, shown(in_file, name),
                       shown(in_render, name));
  }
  return out.empty() ? "what this version does not name (see the keys below)" : out;
}

}  // namespace

std::string film_state_key(const RenderIdentity& id, const FilmWindow& w, int64_t sample_begin, int spp) {
  std::string key;
  for (const auto& [name, value] : key_fields(id, w, sample_begin, spp)) key += (key.empty() ? "" : " ") + name + "=" + value;
  return key;
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
    throw Error(fmt::format("{}: the film state belongs to another render: it differs in {} (remove it, or resume with "
                            "the render's own settings)\n  file:   {}\n  render: {}",
                            path, key_differences(file_key, key), file_key, key));
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
