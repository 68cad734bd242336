// libhgdeform_thumbnails: `hgdeform batch --report`'s before/after pictures, drawn with the
// shared renderer (PCL visualization, hence VTK and OpenGL). A module that hgdeform loads only
// when a report is asked for (batch/thumbnails.cpp), so that every other command starts without
// VTK's libraries: 44 MB and about 40 ms less at each start. The entry points are C functions
// that never throw; the program refuses a module whose build check (thumbnailsAbi) differs from
// its own, so the hgd types they pass have the same layout on both sides.
#include <algorithm>
#include <cstddef>
#include <cstring>
#include <exception>
#include <mutex>
#include <string>
#include <vector>

#include "hgdeform/io/shape.h"
#include "hgdeform/render/render.h"
#include "thumbnails.h"

namespace {

std::mutex g_render_mutex;  // VTK is not thread-safe: one picture at a time

void copyMessage(const std::string& what, char* out, std::size_t size) {
  if (size == 0) return;
  const std::size_t n = std::min(what.size(), size - 1);
  std::memcpy(out, what.data(), n);
  out[n] = '\0';
}

/// An entry point's body, so that no exception crosses into the program: 0 and the text `body`
/// returns in `out`, or 1 and what went wrong (`fallback` for an exception that says nothing).
template <typename Body>
int guarded(char* out, std::size_t size, const char* fallback, Body&& body) {
  try {
    copyMessage(body(), out, size);
    return 0;
  } catch (const std::exception& e) {
    copyMessage(*e.what() ? e.what() : fallback, out, size);
  } catch (...) {
    copyMessage(fallback, out, size);
  }
  return 1;
}

}  // namespace

extern "C" {

HGD_THUMBNAILS_EXPORT const char* hgd_thumbnails_abi() {
  return hgdcli::batch::thumbnailsAbi();
}

HGD_THUMBNAILS_EXPORT int hgd_thumbnails_display_problem(char* problem, std::size_t size) {
  return guarded(problem, size, "the display check failed", [] { return hgd::displayProblem(); });
}

HGD_THUMBNAILS_EXPORT int hgd_thumbnails_draw(const hgdcli::batch::ThumbnailRequest* request, char* error,
                                              std::size_t size) {
  return guarded(error, size, "the thumbnail renderer failed", [request] {
    hgd::RenderOptions o;
    o.width = 640;
    o.height = 320;
    o.point_size = 3;  // a lit cloud's points fill the thumbnail without gaps
    o.titles = {"before", "after"};
    o.displacement_rest = request->before;
    o.fixed_points = *request->fixed;
    o.manipulated_points = *request->manipulated;
    const std::lock_guard<std::mutex> lock(g_render_mutex);
    hgd::renderPng({request->before, request->after}, request->png, o);
    return std::string();
  });
}

}  // extern "C"
