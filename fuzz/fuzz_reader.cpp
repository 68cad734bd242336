// libFuzzer target: one shape reader (HGD_FUZZ_EXTENSION picks PLY, PCD, OBJ, XYZ, OFF, STL, PTS or LAS). The
// input is written to a temporary file with that extension and read with hgd::readShape. It must give a
// consistent shape or throw hgd::IoError; a crash, a sanitizer report or any other exception is
// a bug. A shape that reads is also written back and read again.
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>

#include "hgdeform/io/io.h"

#ifndef HGD_FUZZ_EXTENSION
#error \
    "define HGD_FUZZ_EXTENSION (\".ply\", \".pcd\", \".obj\", \".xyz\", \".off\", \".stl\", \".pts\" or \".las\")"
#endif

namespace {

namespace fs = std::filesystem;

/// A directory of this process's own, removed at exit; in memory (/dev/shm) where there is one:
/// rewriting a file on ext4 flushes it at every close, which would halve the executions.
const fs::path& workDir() {
  static const fs::path dir = [] {
    std::error_code ec;
    const fs::path base = fs::is_directory("/dev/shm", ec) ? fs::path("/dev/shm") : fs::temp_directory_path();
    fs::path d = base / ("hgd-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(d);
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(workDir(), ec);
    });
    return d;
  }();
  return dir;
}

/// A broken invariant: said on stderr (the fuzzer's log keeps it beside the stack) and trapped.
[[noreturn]] void broken(const char* what, int line) {
  std::fprintf(stderr, "fuzz_reader.cpp:%d: broken invariant: %s\n", line, what);
  __builtin_trap();
}
#define check(ok) ((ok) ? void(0) : broken(#ok, __LINE__))

/// The harness's own failure (not the reader's): said with the reason, then aborted.
[[noreturn]] void harnessFailed(const char* what, const std::string& path) {
  std::fprintf(stderr, "fuzz harness: %s %s: %s\n", what, path.c_str(), std::strerror(errno));
  std::abort();
}

void checkShape(const hgd::Shape& s) {
  check(s.size() > 0);
  check(s.cloud.data.size() == s.size() * s.cloud.point_step);
  for (const auto& f : s.cloud.fields) check(f.offset < s.cloud.point_step);
  for (const auto& poly : s.polygons) {
    check(poly.vertices.size() >= 3);
    for (const auto i : poly.vertices) check(i >= 0 && static_cast<std::size_t>(i) < s.size());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string in = (workDir() / ("in" HGD_FUZZ_EXTENSION)).string();
  const std::string out = (workDir() / ("out" HGD_FUZZ_EXTENSION)).string();
  ::unlink(in.c_str());  // a new file rather than a truncated one (see workDir)
  std::FILE* f = std::fopen(in.c_str(), "wb");
  if (!f) harnessFailed("cannot create", in);
  if (size > 0 && std::fwrite(data, 1, size, f) != size) harnessFailed("cannot write", in);
  if (std::fclose(f) != 0) harnessFailed("cannot close", in);
  try {
    const hgd::Shape shape = hgd::readShape(in);
    checkShape(shape);
    hgd::writeShape(out, shape);
    const hgd::Shape again = hgd::readShape(out);
    checkShape(again);
    // Every point comes back, but where the format cannot hold some and says so (a file of
    // another format read by its content, written as STL: its loose and coincident vertices).
    const bool said = !hgd::extrasLost(shape, hgd::formatFromPath(out)).empty();
    check(again.size() == shape.size() || (said && again.size() < shape.size()));
  } catch (const hgd::IoError&) {
  }
  return 0;
}
