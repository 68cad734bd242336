// The deformed file written block by block from a streamed build (hgdeform/deformer/streamed.h):
// Deformer::writeDeformed's rules (write_deformed.cpp) on each block's records.
#include <algorithm>
#include <filesystem>

#include "deformer/xyz_access.h"
#include "hgdeform/deformer/streamed.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "multires/streamed_passes.h"
#include "util/pack.h"
#include "util/parallel.h"

namespace hgd {

namespace {

/// The one output file of a split run: rank 0 writes it atomically (writeRecords: the header,
/// the elements after the records, the rename), every rank writes its share of the records into
/// its temporary file at their place (StreamRanks::writeAt). Three gathers keep the ranks in
/// step: (A) the temporary file named, or rank 0's failure before it; (B) every share written;
/// (C) the file in place, or rank 0's failure to finish it. An error on any rank is thrown on
/// every rank, and nothing is left at `path`.
template <typename Records>
void writeShared(const std::string& path, const RecordLayout& layout, StreamRanks& ranks, Records&& records) {
  const RecordShare mine = shareOf(layout.count, ranks.rank(), ranks.size());
  const auto part = [&](RecordSink& sink) { records(sink, mine); };
  const auto at = [&](std::uint64_t offset) { return offset + mine.first * layout.bytes; };
  if (ranks.rank() != 0) {
    const std::vector<std::string> named = stream::gatherOrThrow(ranks, "", "");  // A
    pack::Reader in(named[0]);
    std::string file;
    in.get(file);
    const auto offset = in.get<std::uint64_t>();
    stream::gatherOrThrow(ranks, ranks.writeAt(file, at(offset), part), "");  // B
    stream::gatherOrThrow(ranks, "", "");                                     // C
    return;
  }
  int stage = 0;  // 0: the others wait at A; 1: past A (B failed: every rank threw); 2: at C
  const auto tell = [&](const std::string& failed) {  // the others' gather of rank 0's failure
    try {
      stream::gatherOrThrow(ranks, failed, "");
    } catch (const IoError&) {
    }
  };
  try {
    writeRecords(path, layout, [&](RecordSink& sink) {
      // (absolute: a rank may run in another working directory)
      const std::string file =
          sink.file().empty() ? std::string() : std::filesystem::absolute(sink.file()).string();
      pack::Writer w;
      w.put(file).put(sink.offset());
      stage = 1;
      stream::gatherOrThrow(ranks,
                            file.empty() ? path +
                                               ": cannot be written by several processes (a descriptor or a "
                                               "device): give a file"
                                         : "",
                            w.bytes());                                                // A
      stream::gatherOrThrow(ranks, ranks.writeAt(file, at(sink.offset()), part), "");  // B
      stage = 2;
      sink.skip(layout.count * layout.bytes);
    });
  } catch (const std::exception& e) {
    if (stage != 1) tell(e.what());
    throw;
  }
  stream::gatherOrThrow(ranks, "", "");  // C
}

}  // namespace

std::vector<std::string> writeStreamedDeformed(const std::string& path, const RecordLayout& layout,
                                               const StreamedLevel& level, const StreamedDeformer& s,
                                               std::size_t block, StreamRanks* ranks) {
  std::vector<std::string> warnings;
  const Shape& shape = layout.shape;
  const XyzFields f = findXyzFields(shape.cloud);
  const std::string name = shape.path.empty() ? std::string("the shape") : shape.path;
  if (!f.hasXyz()) throw IoError(name + ": no x/y/z fields");
  for (const int idx : {f.x, f.y, f.z}) {
    const std::uint8_t t = shape.cloud.fields[static_cast<std::size_t>(idx)].datatype;
    if (t != pcl::PCLPointField::FLOAT32 && t != pcl::PCLPointField::FLOAT64)
      throw IoError(
          name +
          ": x/y/z are stored as integers, which cannot hold the deformed positions: a streamed run "
          "cannot widen them (the records would change size); read the whole file instead");
  }
  const Deformer& d = *s.deformer;
  const std::shared_ptr<const BlockProlongation> prolong = d.blockProlongation();
  if (!prolong)
    throw std::logic_error("writeStreamedDeformed: the deformer was not built on a streamed level");
  const std::vector<Eigen::Affine3d> moved = d.worldTransforms();
  const bool any_move = std::any_of(moved.begin(), moved.end(), [](const Eigen::Affine3d& t) {
    return !t.isApprox(Eigen::Affine3d::Identity(), 0);
  });
  const bool write_normals = f.hasNormals() && level.file_normals;
  if (f.hasNormals() && !write_normals)
    warnings.push_back(name +
                       ": its normals were not usable (some are zero or not finite): they are written back "
                       "as they were, not turned with the shape");
  const auto& coarse_normals = d.surfaceGraph().normals();
  // The records [share.first, share.last), deformed, to `sink` in order.
  const auto records = [&](RecordSink& sink, const RecordShare& share) {
    streamPass("write");
    const RecordReader reader(layout);
    pcl::PCLPointCloud2 c;
    c.fields = shape.cloud.fields;
    c.point_step = layout.bytes;
    c.height = 1;
    pcl::PointCloud<pcl::PointXYZ> pts;
    pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
    std::vector<std::uint32_t> anchor;
    std::vector<char> stray;
    std::vector<int> cls;
    std::vector<std::size_t> row;
    struct Found {  // a record's place in the level (found in parallel, gathered in order)
      Eigen::Vector3f p, n;
      std::uint32_t anchor;
      int cls;
      char kept, stray;
    };
    std::vector<Found> found;
    for (std::uint64_t first = share.first; first < share.last; first += block) {
      const auto count = static_cast<std::size_t>(std::min<std::uint64_t>(block, share.last - first));
      c.width = static_cast<std::uint32_t>(count);
      c.row_step = c.point_step * c.width;
      c.data.resize(count * c.point_step);
      reader.read(first, count, c.data.data());
      XyzAccess xyz(c, f);
      if (any_move) {
        found.resize(count);
        const auto n = static_cast<long long>(count);
#pragma omp parallel for schedule(static) if (n > kParallelMin)
        for (long long kk = 0; kk < n; ++kk) {
          const auto k = static_cast<std::size_t>(kk);
          const std::uint64_t i = first + k;
          Found& r = found[k];
          const Eigen::Vector3d w = xyz.get(k);
          r.kept = w.allFinite() && level.kept(i, w);
          if (!r.kept) continue;
          r.p = level.local(w);
          const auto at = std::lower_bound(level.strays.begin(), level.strays.end(), i);
          r.stray = at != level.strays.end() && *at == i;
          r.cls = level.classOf(i);
          r.anchor = r.stray ? level.stray_anchor[static_cast<std::size_t>(at - level.strays.begin())]
                             : level.cellAnchor(r.p, r.cls);
          if (write_normals) {
            const Eigen::Vector3f nv(
                static_cast<float>(readValue(c, k, c.fields[static_cast<std::size_t>(f.nx)])),
                static_cast<float>(readValue(c, k, c.fields[static_cast<std::size_t>(f.ny)])),
                static_cast<float>(readValue(c, k, c.fields[static_cast<std::size_t>(f.nz)])));
            r.n = nv / nv.norm();
          }
        }
        pts.clear();
        normals->clear();
        anchor.clear();
        stray.clear();
        cls.clear();
        row.clear();
        for (std::size_t k = 0; k < count; ++k) {
          const Found& r = found[k];
          if (!r.kept) continue;
          pts.push_back(pcl::PointXYZ(r.p.x(), r.p.y(), r.p.z()));
          stray.push_back(r.stray);
          cls.push_back(r.cls);
          anchor.push_back(r.anchor);
          row.push_back(k);
          if (write_normals) {
            pcl::Normal nn;
            nn.getNormalVector3fMap() = r.n;
            normals->push_back(nn);
          }
        }
        InterpolationTable table = prolong->table(pts, anchor, stray, cls);
        if (level.file_normals) {  // shared, as the in-memory table shares the file's
          table.normal_cloud = normals;
        } else {  // a point's rest normal: its anchor's
          table.normals.resize(pts.size());
          for (std::size_t k = 0; k < pts.size(); ++k)
            table.normals[k] = coarse_normals[anchor[k]].getNormalVector3fMap();
        }
        table.has_normals = true;
        const ExactInterpolation exact = d.exactInterpolation(table);
        const auto moved_n = static_cast<long long>(pts.size());
#pragma omp parallel for schedule(static) if (moved_n > kParallelMin)
        for (long long kk = 0; kk < moved_n; ++kk) {
          const auto k = static_cast<std::size_t>(kk);
          if (!exact.moves(k)) continue;  // left as the file had it
          const std::size_t r = row[k];
          xyz.set(r, exact.apply(k, xyz.get(r) - level.origin) + level.origin);
          if (write_normals) {
            const Eigen::Vector3d nv = exact.applyNormal(k, table.restNormal(k).cast<double>());
            writeValue(c, r, c.fields[static_cast<std::size_t>(f.nx)], nv.x());
            writeValue(c, r, c.fields[static_cast<std::size_t>(f.ny)], nv.y());
            writeValue(c, r, c.fields[static_cast<std::size_t>(f.nz)], nv.z());
          }
        }
      }
      sink.write(c.data.data(), c.data.size());
    }
  };
  if (StreamRanks* split = stream::splitRanks(ranks))
    writeShared(path, layout, *split, records);
  else
    writeRecords(path, layout, [&](RecordSink& sink) { records(sink, RecordShare{0, layout.count}); });
  return warnings;
}

}  // namespace hgd
