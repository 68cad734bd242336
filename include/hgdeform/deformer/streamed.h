// A Deformer on a scan streamed from its file (hgdeform/multires/streamed.h): its geometry holds
// the coarse points and the manipulated handle's points only, and it solves what a Deformer on
// the whole file, read into memory, solves at the same resolution, bit for bit.
#pragma once

#include <memory>

#include "hgdeform/deformer/deformer.h"
#include "hgdeform/multires/streamed.h"

namespace hgd {

struct StreamedDeformer {
  std::shared_ptr<const Geometry> geometry;  ///< the points held, in Geometry's order
  Handles handles;                           ///< the shape's handles among them
  std::shared_ptr<const PrebuiltLevel> level;
  std::unique_ptr<Deformer> deformer;
};

/// Reads the manipulated handle's points in one pass over the file's records and builds the
/// Deformer on `level` (streamCoarseLevel of the same file and handles, which must not be
/// empty). `options`: the deformation's; its multi-resolution sizes are the level's.
StreamedDeformer streamedDeformer(const RecordLayout& layout, const StreamedLevel& level,
                                  const RecordHandles& handles, const DeformOptions& options);

}  // namespace hgd
