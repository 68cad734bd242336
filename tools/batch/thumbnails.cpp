#include "thumbnails.h"

#include <dlfcn.h>

#include <array>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <vector>

namespace hgdcli {
namespace batch {

namespace {

constexpr const char* kModule = "libhgdeform_thumbnails.so";

/// The module's absolute path, never one in the current directory: HGDEFORM_THUMBNAILS_MODULE
/// when set (a packager's layout; the tests name a missing file), else the first that exists of
/// beside the installed library (the program's directory, then HGD_BIN_TO_LIB) and the build
/// tree's library directory (HGD_THUMBNAILS_BUILD_DIR: a build's programs, shared or static, run
/// from where they were built). "" when none exists; `tried` lists them.
std::string modulePath(std::string& tried) {
  if (const char* path = std::getenv("HGDEFORM_THUMBNAILS_MODULE"); path && *path) return path;
  std::vector<std::filesystem::path> places;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) places.push_back((exe.parent_path() / HGD_BIN_TO_LIB / kModule).lexically_normal());
  places.push_back(std::filesystem::path(HGD_THUMBNAILS_BUILD_DIR) / kModule);
  for (const auto& p : places) {
    if (std::filesystem::exists(p, ec)) return p.string();
    tried += (tried.empty() ? "" : ", ") + p.string();
  }
  return "";
}

struct Module {
  bool loaded = false;
  std::string problem;  ///< why it cannot be used ("" when it can)
  int (*display_problem)(char*, std::size_t) = nullptr;
  int (*draw)(const ThumbnailRequest*, char*, std::size_t) = nullptr;
};

template <typename F>
F symbol(void* handle, const std::string& path, const char* name, std::string& problem) {
  void* p = dlsym(handle, name);
  if (!p && problem.empty()) problem = path + " has no " + name + " (not hgdeform's thumbnail module?)";
  return reinterpret_cast<F>(p);
}

Module load() {
  Module m;
  std::string tried;
  const std::string path = modulePath(tried);
  if (path.empty()) {
    m.problem = std::string("the thumbnail renderer could not be loaded: no ") + kModule + " (looked for " +
                tried + ")";
    return m;
  }
  // Never unloaded: VTK registers atexit handlers and static objects.
  void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle) {
    const char* why = dlerror();
    m.problem = "the thumbnail renderer could not be loaded: " + (why ? std::string(why) : path);
    return m;
  }
  const auto abi = symbol<const char* (*)()>(handle, path, "hgd_thumbnails_abi", m.problem);
  m.display_problem =
      symbol<int (*)(char*, std::size_t)>(handle, path, "hgd_thumbnails_display_problem", m.problem);
  m.draw = symbol<int (*)(const ThumbnailRequest*, char*, std::size_t)>(handle, path, "hgd_thumbnails_draw",
                                                                        m.problem);
  if (m.problem.empty() && std::strcmp(abi(), thumbnailsAbi()) != 0)
    m.problem =
        path + " is from another build of hgdeform (" + abi() + "; this program: " + thumbnailsAbi() + ")";
  if (!m.problem.empty()) return m;
  m.loaded = true;
  std::array<char, 1024> text{};  // (a failure always says something: the module's `guarded`)
  m.display_problem(text.data(), text.size());
  m.problem = text.data();
  return m;
}

const Module& module() {
  static std::once_flag once;
  static Module m;
  std::call_once(once, [] { m = load(); });
  return m;
}

}  // namespace

std::string thumbnailProblem() {
  return module().problem;
}

bool thumbnailModuleLoaded() {
  return module().loaded;
}

void drawThumbnail(const ThumbnailRequest& request) {
  const Module& m = module();
  if (!m.problem.empty()) throw std::runtime_error(m.problem);
  std::array<char, 2048> error{};
  if (m.draw(&request, error.data(), error.size()) != 0) throw std::runtime_error(error.data());
}

}  // namespace batch
}  // namespace hgdcli
