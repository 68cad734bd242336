// The batch report's thumbnails, drawn by the module libhgdeform_thumbnails (thumbnail_plugin.cpp),
// which hgdeform loads on first use: the renderer's libraries (VTK, OpenGL, X11) are loaded only
// by a batch that writes a report, not by every start of the program.
#pragma once

#include <string>
#include <vector>

#include "hgdeform/io/shape.h"
#include "hgdeform/version.h"

#define HGD_THUMBNAILS_EXPORT __attribute__((visibility("default")))

namespace hgdcli {
namespace batch {

/// What the module and the program must agree on, compared as text when the module is loaded: a
/// module from another build (another version, or other layouts of the types passed across) is
/// refused instead of called. Bump the "1" when ThumbnailRequest or an entry point changes.
inline const char* thumbnailsAbi() {
  static const std::string abi = std::string("hgdeform " HGDEFORM_VERSION ", thumbnails 1, Shape ") +
                                 std::to_string(sizeof(hgd::Shape)) + ", cloud " +
                                 std::to_string(sizeof(pcl::PCLPointCloud2)) + ", vector " +
                                 std::to_string(sizeof(std::vector<int>));
  return abi.c_str();
}

}  // namespace batch
}  // namespace hgdcli

namespace hgdcli {
namespace batch {

/// What one picture needs: the scan before (its own colours) and after (coloured by each point's
/// displacement from `before`), the handles marked (file point indices).
struct ThumbnailRequest {
  const hgd::Shape* before;
  const hgd::Shape* after;
  const std::vector<int>* fixed;
  const std::vector<int>* manipulated;
  const char* png;
};

/// Empty when thumbnails can be drawn here; else why not (the module could not be loaded, or no
/// X display with OpenGL). Loads the module on its first call.
std::string thumbnailProblem();

/// Whether the module itself was found and loaded (thumbnailProblem() may still name a missing
/// display).
bool thumbnailModuleLoaded();

/// Draws one thumbnail (a 640×320 PNG). Throws std::runtime_error with the renderer's message.
/// Call only after thumbnailProblem() returned "".
void drawThumbnail(const ThumbnailRequest& request);

}  // namespace batch
}  // namespace hgdcli
