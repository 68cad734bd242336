#include "thumbnails.h"

#include <dlfcn.h>

#include <array>
#include <cstddef>
#include <cstdlib>
#include <mutex>
#include <stdexcept>

namespace hgdcli {
namespace batch {

namespace {

/// The module's file name: found through the program's RUNPATH (beside libhgdeform, in the build
/// tree and in an installed prefix alike). HGDEFORM_THUMBNAILS_MODULE, when set, names another
/// file (a packager's layout; the tests name a missing one).
constexpr const char* kModule = "libhgdeform_thumbnails.so";

std::string modulePath() {
  const char* path = std::getenv("HGDEFORM_THUMBNAILS_MODULE");
  return path && *path ? path : kModule;
}

struct Module {
  bool loaded = false;
  std::string problem;  ///< why it cannot be used ("" when it can)
  int (*display_problem)(char*, std::size_t) = nullptr;
  int (*draw)(const ThumbnailRequest*, char*, std::size_t) = nullptr;
};

template <typename F>
F symbol(void* handle, const char* name, std::string& problem) {
  void* p = dlsym(handle, name);
  if (!p && problem.empty())
    problem = std::string(kModule) + " has no " + name + " (a module from another build?)";
  return reinterpret_cast<F>(p);
}

Module load() {
  Module m;
  // Never unloaded: VTK registers atexit handlers and static objects.
  const std::string path = modulePath();
  void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle) {
    const char* why = dlerror();
    m.problem = "the thumbnail renderer could not be loaded: " + (why ? std::string(why) : path);
    return m;
  }
  const auto abi = symbol<int (*)()>(handle, "hgd_thumbnails_abi", m.problem);
  m.display_problem =
      symbol<int (*)(char*, std::size_t)>(handle, "hgd_thumbnails_display_problem", m.problem);
  m.draw =
      symbol<int (*)(const ThumbnailRequest*, char*, std::size_t)>(handle, "hgd_thumbnails_draw", m.problem);
  if (m.problem.empty() && abi() != HGD_THUMBNAILS_ABI)
    m.problem = std::string(kModule) + " is from another build of hgdeform (interface " +
                std::to_string(abi()) + ", this program's " + std::to_string(HGD_THUMBNAILS_ABI) + ")";
  if (!m.problem.empty()) return m;
  m.loaded = true;
  std::array<char, 1024> text{};
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
