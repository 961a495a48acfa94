// output_proxy.h: OpenImageIO's view of an OutputFile (util/output_file.h), shared by the
// whole-image writers (image_write.cpp) and the band writer of merge (image_rows.cpp), so that
// every image spectrack writes goes through the same checked temporary file and rename.
#pragma once
#include <OpenImageIO/filesystem.h>

#include <mutex>

#include "util/output_file.h"

namespace spectrack {

// OpenImageIO's view of an OutputFile: writes at the proxy's position (or at an offset), checked
// and recorded by the OutputFile; nothing is read back.
class OutputProxy : public OIIO::Filesystem::IOProxy {
 public:
  explicit OutputProxy(OutputFile& f) : IOProxy(f.path(), Write), f_(f) {}
  const char* proxytype() const override { return "spectrack-output"; }
  size_t write(const void* buf, size_t size) override {
    std::lock_guard<std::mutex> lock(mu_);
    const size_t n = f_.write_at(buf, size, uint64_t(m_pos));
    m_pos += int64_t(n);
    return n;
  }
  size_t pwrite(const void* buf, size_t size, int64_t offset) override {
    std::lock_guard<std::mutex> lock(mu_);
    return offset < 0 ? 0 : f_.write_at(buf, size, uint64_t(offset));
  }
  bool seek(int64_t offset) override {
    std::lock_guard<std::mutex> lock(mu_);
    if (offset < 0) return false;
    m_pos = offset;
    return true;
  }
  size_t read(void*, size_t) override { return 0; }
  size_t pread(void*, size_t, int64_t) override { return 0; }
  size_t size() const override { return size_t(f_.size()); }

 private:
  OutputFile& f_;
  std::mutex mu_;
};

}  // namespace spectrack
