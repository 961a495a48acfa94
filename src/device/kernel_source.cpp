// kernel_source.cpp: the OpenCL C text of a program, assembled from the embedded kernels/ files.
//
// Design: every kernels/ file includes what it uses (`#include "x.h"`, with include guards), and
// the build embeds each file verbatim (cmake/embed_kernels.cmake). The assembler resolves the
// includes itself, from the embedded set: starting at a root file (kernels/renderer.cl for the
// renderer, plus any extra files such as the probes' probe.cl) it copies a file line by line and
// replaces each `#include "x"` by the text of x (recursively) the first time x is named and by an
// empty line after that, so each file appears once, before its first user. An include is inlined
// where it stands, whatever #if surrounds it (kernel files include unconditionally, except
// guiding.h's device-only phase.h, which stands in the device branch). `#line` markers keep the
// compiler's messages on the real file and line. Two names are not files under kernels/:
// "film_table.h" is generated here from the film tables of src/color/spectrum.h, and
// "nanovdb/PNanoVDB.h" is the system's PNanoVDB.h, rewritten for OpenCL 1.2 (rewrite_pnanovdb).
// Since the kernel cache key is taken over the assembled text (opencl.cpp), it changes whenever
// any included file does.
#include "device/opencl.h"

#include "color/spectrum.h"

#include <fmt/format.h>

#include <regex>
#include <set>
#include <sstream>

namespace spectrack {

const std::map<std::string, std::string>& embedded_kernel_sources();

namespace {

const char* const kFilmTable = "film_table.h";
const char* const kPNanoVDB = "nanovdb/PNanoVDB.h";

std::string rewrite_pnanovdb(std::string s) {
  auto replace_all = [&](const std::string& a, const std::string& b) {
    size_t n = 0;
    for (size_t pos = s.find(a); pos != std::string::npos; pos = s.find(a, pos + b.size())) {
      s.replace(pos, a.size(), b);
      ++n;
    }
    return n;
  };
  replace_all("#include <stdint.h>", "/* stdint.h: types come from pnanovdb_cl.h */");
  replace_all("#include <string.h>", "/* string.h: pnanovdb_memcpy comes from pnanovdb_cl.h */");
  // program-scope tables: OpenCL 1.2 needs them in __constant memory
  const std::string c_branch = "#define PNANOVDB_STATIC_CONST static const";
  auto pos = s.find(c_branch);
  if (pos == std::string::npos) throw Error("PNanoVDB.h: unexpected layout (no PNANOVDB_STATIC_CONST definition)");
  s.replace(pos, c_branch.size(), "#define PNANOVDB_STATIC_CONST __constant");
  return s;
}

// The film table of spectral mode (kernels/spectrum.h st_film_table): per nm from 360 to 830, the
// film's weights F (film_rgb_weights) and CIE D65, as a program-scope __constant array, printed
// with enough digits to read back the same floats.
const std::string& film_table_source() {
  static const std::string text = [] {
    const std::vector<Rgb>& F = film_rgb_weights();
    std::ostringstream o;
    o << "__constant float4 st_film_table[" << F.size() << "] = {\n";
    for (size_t i = 0; i < F.size(); ++i) {
      const double lambda = kSpectrumLambdaMin + double(i);
      o << fmt::format("  (float4)({:.8e}f, {:.8e}f, {:.8e}f, {:.8e}f),\n", float(F[i][0]), float(F[i][1]),
                       float(F[i][2]), float(cie_d65(lambda)));
    }
    o << "};\n";
    return o.str();
  }();
  return text;
}

// Inlines files and their includes, each once, into `out`.
class IncludeResolver {
 public:
  IncludeResolver(std::ostringstream& out, const std::map<std::string, std::string>& files)
      : out_(out), files_(files) {}

  void inline_file(const std::string& name, const std::string& includer) {
    if (!seen_.insert(name).second) return;
    if (name == kFilmTable) {
      out_ << "#line 1 \"<film_table.h: src/color/spectrum.cpp>\"\n" << film_table_source();
      return;
    }
    const auto& files = files_;
    const bool pnanovdb = name == kPNanoVDB;
    auto it = files.find(pnanovdb ? "PNanoVDB.h" : name);
    if (it == files.end())
      throw Error(fmt::format("internal: kernel file {}{} is not embedded", name,
                              includer.empty() ? "" : ", included by kernels/" + includer));
    const std::string shown = pnanovdb ? kPNanoVDB : "kernels/" + name;
    out_ << "#line 1 \"" << shown << "\"\n";
    if (pnanovdb) {  // a third-party file: copied as it is, its own includes rewritten away
      out_ << rewrite_pnanovdb(it->second) << "\n";
      return;
    }
    copy_resolving(name, shown, it->second);
  }

 private:
  void copy_resolving(const std::string& name, const std::string& shown, const std::string& text) {
    // A quoted include, optionally followed by a one-line comment of either kind.
    static const std::regex include_line(
        R"re(^\s*#\s*include\s*"([^"]+)"\s*(//.*|/\*([^*]|\*+[^*/])*\*+/\s*)?$)re");
    static const std::regex quoted_include(R"re(^\s*#\s*include\s*")re");
    std::istringstream in(text);
    std::string line;
    int number = 0;
    std::smatch m;
    while (std::getline(in, line)) {
      ++number;
      // Either pattern needs the word: most lines skip the regular expressions (their cost is the
      // assembler's, about 20 ms per program).
      if (line.find("include") == std::string::npos) {
        out_ << line << "\n";
        continue;
      }
      if (!std::regex_match(line, m, include_line)) {
        if (std::regex_search(line, quoted_include))  // never handed to the device compiler
          throw Error(fmt::format("internal: {}:{}: an #include \"...\" the kernel assembler cannot "
                                  "read (one file name, then at most a one-line comment): {}",
                                  shown, number, line));
        out_ << line << "\n";
        continue;
      }
      const std::string dep = m[1];
      if (seen_.count(dep)) {
        out_ << "\n";  // already in the program: an empty line keeps the numbering
        continue;
      }
      inline_file(dep, name);
      out_ << "#line " << number + 1 << " \"" << shown << "\"\n";
    }
  }

  std::ostringstream& out_;
  const std::map<std::string, std::string>& files_;
  std::set<std::string> seen_;
};

}  // namespace

std::string kernel_files_source(const std::vector<std::string>& roots,
                                const std::map<std::string, std::string>& files) {
  std::ostringstream out;
  IncludeResolver resolver(out, files);
  for (const std::string& name : roots) resolver.inline_file(name, "");
  return out.str();
}

std::string kernel_files_source(const std::vector<std::string>& roots) {
  return kernel_files_source(roots, embedded_kernel_sources());
}

std::string assemble_kernel_source(const std::vector<std::pair<std::string, std::string>>& defines,
                                   const std::vector<std::string>& extra_files) {
  std::ostringstream out;
  out << "/* spectrack " << SPECTRACK_VERSION << ": assembled kernel source */\n";
  for (auto& [k, v] : defines) out << "#define " << k << " " << v << "\n";
  // No contraction of a * b + c into one fma: OpenCL C allows it by default, and NVIDIA's compiler
  // contracts differently in each specialisation of a kernel, so specialised and generic kernels
  // would render different images there (bit for bit; the same on PoCL). Explicit fma() calls stay.
  out << "#pragma OPENCL FP_CONTRACT OFF\n";
  std::vector<std::string> roots = {"renderer.cl"};
  roots.insert(roots.end(), extra_files.begin(), extra_files.end());
  out << kernel_files_source(roots);
  return out.str();
}

}  // namespace spectrack
