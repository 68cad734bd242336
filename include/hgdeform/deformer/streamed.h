// A Deformer on a scan streamed from its file (hgdeform/multires/streamed.h): its geometry holds
// the coarse points only, the manipulated handle's points are kept apart as rest positions (16
// bytes a point: what a pick and the handle's centre read), and it solves what a Deformer on the
// whole file, read into memory, solves at the same resolution, bit for bit.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "hgdeform/deformer/deformer.h"
#include "hgdeform/multires/streamed.h"

namespace hgd {

struct StreamedDeformer {
  std::shared_ptr<const Geometry> geometry;  ///< the points held, in Geometry's order
  Handles handles;                           ///< the shape's handles among them
  std::shared_ptr<const PrebuiltLevel> level;
  std::unique_ptr<Deformer> deformer;
};

/// Reads the coarse points and the manipulated handle's in one pass over the file's records and
/// builds the Deformer on `level` (streamCoarseLevel of the same file and handles, which must not
/// be empty). `options`: the deformation's; its multi-resolution sizes are the level's. With
/// `ranks` (a split run), each rank reads its share and the points are gathered (collective).
StreamedDeformer streamedDeformer(const RecordLayout& layout, const StreamedLevel& level,
                                  const RecordHandles& handles, const DeformOptions& options,
                                  StreamRanks* ranks = nullptr);

/// Writes the deformed file at `path`: every record of `layout`, block by block, as
/// Deformer::writeDeformed and writeShape write the file read whole into memory, byte for byte:
/// moved points' x, y, z (and normals, where the file's are all usable) computed in double from
/// the record's own values, every other byte as it was, the same header and trailing elements.
/// Returns what a front end should say (normals left as they were). Throws IoError naming the
/// file for x, y, z stored as integers (the in-memory writer widens them: the records would
/// change size) and for what writeRecords refuses; nothing is left at `path` then.
/// With `ranks` (a split run, every rank with the same level and deformer): each rank deforms its
/// share of the records and writes it at its place in the one file (rank 0 writes the rest and
/// puts the file in place); collective, and what fails on one rank is thrown on every rank.
std::vector<std::string> writeStreamedDeformed(const std::string& path, const RecordLayout& layout,
                                               const StreamedLevel& level, const StreamedDeformer& deformer,
                                               std::size_t block = 1 << 16, StreamRanks* ranks = nullptr);

}  // namespace hgd
