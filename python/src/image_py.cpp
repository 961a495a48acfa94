// image_py.cpp: the Image class and the functions that make images from others or from files:
// merge (film.h merge_pieces: the checks of `spectrack merge`), read (read_piece, adaptive renders
// included) and read_exr
// (the raw channels of an EXR, for comparing files with arrays).
#include "image_py.h"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "args_py.h"
#include "cli/checks.h"
#include "integrator/stats_json.h"
#include "warnings_py.h"

namespace py = pybind11;

namespace spectrack {
namespace python {
namespace {

// A height x width x channels float32 array of pixel-major values with `stride` values per pixel,
// starting at column `first` (channels == 0: height x width, one column).
py::array_t<float> pixels(const std::vector<float>& px, int width, int height, size_t stride, size_t first,
                          size_t channels) {
  std::vector<py::ssize_t> shape = {height, width};
  if (channels > 0) shape.push_back(py::ssize_t(channels));
  py::array_t<float> a(shape);
  float* out = a.mutable_data();
  const size_t n = std::max<size_t>(channels, 1), npix = size_t(width) * size_t(height);
  for (size_t p = 0; p < npix; ++p)
    for (size_t c = 0; c < n; ++c) out[p * n + c] = px[p * stride + first + c];
  return a;
}

py::dict channel_dict(const std::vector<std::string>& names, const std::vector<float>& px, int width, int height) {
  py::dict d;
  for (size_t c = 0; c < names.size(); ++c) d[py::str(names[c])] = pixels(px, width, height, names.size(), c, 0);
  return d;
}

py::dict channels(const Image& im) {
  std::vector<float> px;
  const std::vector<std::string> names = piece_exr_channels(im.piece, &px);
  return channel_dict(names, px, im.piece.width, im.piece.height);
}

// Every film layer by its name (docs/aov.md): the channels of aov_exr_channels stacked last.
py::dict layers(const Image& im) {
  std::vector<float> px;
  const std::vector<std::string> names = piece_exr_channels(im.piece, &px);
  py::dict d;
  for (int k = 0; k < ST_AOV_COUNT; ++k) {
    if (!(im.piece.id.aovs & (1u << k))) continue;
    const std::vector<std::string>& chans = aov_exr_channels(k);
    const size_t first = size_t(std::find(names.begin(), names.end(), chans[0]) - names.begin());
    d[py::str(aov_name(k))] = pixels(px, im.piece.width, im.piece.height, names.size(), first, chans.size());
  }
  return d;
}

py::object to_python(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

Image merge(const py::object& items) {
  if (py::isinstance<py::str>(items) || py::isinstance<py::bytes>(items) || py::hasattr(items, "__fspath__"))
    throw py::type_error("merge: a list of images or paths is needed (one path alone: [path])");
  if (!py::isinstance<py::iterable>(items))
    throw py::type_error(fmt::format("merge: a list of images or paths is needed, not {}",
                                     py::repr(items).cast<std::string>()));
  std::vector<FilmPiece> pieces;
  Image out;
  for (const py::handle& h : items) {
    if (py::isinstance<Image>(h)) {
      const Image& im = h.cast<const Image&>();
      pieces.push_back(im.piece);
      pieces.back().source = fmt::format("image {} of the list", pieces.size());  // messages name which
      out.counters.add(im.counters);
    } else if (py::isinstance<py::str>(h) || py::hasattr(h, "__fspath__")) {
      pieces.push_back(read_piece(path_arg(h, "merge")));
    } else {
      throw py::type_error(fmt::format("merge: {} is neither a spectrack.Image nor an EXR file's path",
                                       py::repr(h).cast<std::string>()));
    }
  }
  if (pieces.empty()) throw Error("merge: no image given");
  out.piece = merge_pieces(pieces);
  out.piece.source = "merge";
  out.stats = stats_to_json(out.counters);
  out.stats["spp"] = out.piece.samples();
  out.stats["spp_ranges"] = format_ranges(out.piece.ranges);
  out.stats["interrupted"] = out.piece.interrupted;
  out.stats["merged"] = pieces.size();
  return out;
}

Image read(const py::object& path_object) {
  const std::string path = path_arg(path_object, "read");
  Image im;
  try {
    im.piece = read_piece(path, &im.meta, /*keep_adaptive=*/true);  // merge() still refuses an adaptive Image
  } catch (const Error& e) {  // read's Image can be merged: the merge's refusals (half, lossy, PNG) are read's
    throw Error(fmt::format("read: {} (read_exr reads any of spectrack's EXR outputs as arrays)", e.what()));
  }
  im.stats = {{"spp", im.piece.samples()}, {"spp_ranges", format_ranges(im.piece.ranges)},
              {"interrupted", im.piece.interrupted}, {"file", path}};
  if (!im.piece.pixel_samples.empty()) {
    double total = 0;
    for (float n : im.piece.pixel_samples) total += n;
    im.stats["adaptive_mean_spp"] = total / double(im.piece.pixel_samples.size());
  }
  return im;
}

py::dict read_exr(const py::object& path_object) {
  const std::string path = path_arg(path_object, "read_exr");
  const RgbImage img = read_image(path, ImageUse::kSpectrackExr);
  py::dict d = channel_dict({"R", "G", "B"}, img.rgb, img.width, img.height);
  for (auto item : channel_dict(img.extra_names, img.extra, img.width, img.height)) d[item.first] = item.second;
  return d;
}

py::list ranges(const Image& im) {
  py::list l;
  for (const SampleRange& r : im.piece.ranges) l.append(py::make_tuple(r.begin, r.end));
  return l;
}

// A piece to merge: rendered with spp_range or pixel_bounds, or a window or samples that are not
// the whole film's from sample 0 without a gap (a read or merged piece).
bool is_piece(const Image& im) {
  const FilmPiece& p = im.piece;
  return im.spp_or_pixel_range || p.x0 != 0 || p.y0 != 0 || p.width != p.id.full_width ||
         p.height != p.id.full_height || p.ranges.size() > 1 || (!p.ranges.empty() && p.ranges.front().begin != 0);
}

}  // namespace

void bind_image(py::module_& m) {
  py::class_<Image>(m, "Image", "A render (or a merge of renders): a pixel window of the film with exact sums")
      .def_property_readonly("rgb", [](const Image& im) {
        return pixels(piece_beauty(im.piece), im.piece.width, im.piece.height, 3, 0, 3);
      }, "the whole beauty, linear sRGB, float32 height x width x 3")
      .def_property_readonly("channels", &channels, "every EXR channel the image writes, name -> float32 height x width")
      .def_property_readonly("layers", &layers, "every film layer by name (docs/aov.md) -> float32 height x width x C")
      .def_property_readonly("stats", [](const Image& im) { return to_python(im.stats); })
      .def_property_readonly("spp", [](const Image& im) { return im.piece.samples(); })
      .def_property_readonly("spp_ranges", &ranges)
      .def_property_readonly("interrupted", [](const Image& im) { return im.piece.interrupted; })
      .def_property_readonly("width", [](const Image& im) { return im.piece.width; })
      .def_property_readonly("height", [](const Image& im) { return im.piece.height; })
      .def_property_readonly("pixel_bounds", [](const Image& im) {
        const FilmPiece& p = im.piece;
        return py::make_tuple(p.x0, p.x0 + p.width, p.y0, p.y0 + p.height);
      })
      .def("write", [](const Image& im, const py::object& path_object, const py::object& half_arg,
                       const py::object& compression_arg) {
        const std::string path = path_arg(path_object, "write");
        const bool half = bool_arg(half_arg, "write", "half");
        const std::string compression = str_arg(compression_arg, "write", "compression");
        if (im.piece.samples() == 0)  // as the command line writes nothing when no sample finished
          throw py::value_error(fmt::format("write: {}: the image holds no finished sample (a render stopped before its "
                                            "first batch): nothing to write", path));
        ExrOptions exr;
        exr.half = half;
        const std::vector<std::string>& known = exr_compressions();  // the CLI's --compression names
        if (std::find(known.begin(), known.end(), compression) == known.end())
          throw py::value_error(fmt::format("write: compression=\"{}\": unknown (one of: {})", compression,
                                            fmt::join(known, ", ")));
        exr.compression = compression;
        // the command line's refusal of --half and --compression with a PNG (cli/checks.h)
        if (const std::string e = png_option_error(half, compression == "zip" ? "" : compression, path, "half=True",
                                                   "compression");
            !e.empty())
          throw py::value_error("write: " + e);
        if (is_piece(im))  // the command line's warning before a piece renders (cli/checks.h)
          if (const std::string w = piece_storage_warning(exr, path); !w.empty())
            if (PyErr_WarnEx(PyExc_UserWarning, w.c_str(), 1) != 0) throw py::error_already_set();
        write_piece(path, im.piece, im.meta, exr);
      }, py::call_guard<FlushWarnings>(), py::arg("path"), py::arg("half") = false, py::arg("compression") = "zip",
         "writes an EXR (every layer, mergeable) or a PNG (the beauty)")
      .def("__repr__", [](const Image& im) {
        return fmt::format("<spectrack.Image {}x{}, {} spp{}>", im.piece.width, im.piece.height, im.piece.samples(),
                           im.piece.interrupted ? ", interrupted" : "");
      });
  m.def("merge", &merge, py::call_guard<FlushWarnings>(), py::arg("images"), "merges images or EXR files of one render (disjoint samples or tiles)");
  m.def("read", &read, py::call_guard<FlushWarnings>(), py::arg("path"), "reads an EXR written by a render or a merge");
  m.def("read_exr", &read_exr, py::arg("path"), "the float channels of a spectrack EXR, name -> height x width");
}

}  // namespace python
}  // namespace spectrack
