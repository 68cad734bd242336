// A scenario run on a streamed scan (hgdeform/app/stream.h).
#include <algorithm>
#include <cstring>

#include "hgdeform/app/report.h"
#include "hgdeform/app/stream.h"
#include "hgdeform/deformer/streamed.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "multires/record_blocks.h"
#include "multires/streamed_passes.h"
#include "util/pack.h"
#include "util/timer.h"

namespace hgd {

RecordHandles streamHandles(const Scenario& scenario, const RecordLayout& layout, const StreamedLevel& level,
                            StreamRanks* ranks) {
  ranks = stream::splitRanks(ranks);
  const std::string name = scenario.path.empty() ? "scenario" : scenario.path;
  const Shape& shape = layout.shape;
  const pcl::PCLPointCloud2& fields = shape.cloud;
  // The regions in order: manipulated, fixed..., joints...; each a test of a record.
  std::vector<const Region*> regions{&scenario.manipulated};
  for (const auto& r : scenario.fixed) regions.push_back(&r);
  for (const auto& r : scenario.joints) regions.push_back(&r);
  struct FieldTest {
    int field = -1;
    bool packed = false;
    std::uint32_t mask = 0, want = 0;
    double lo = 0, hi = 0;
  };
  std::vector<FieldTest> field_tests(regions.size());
  for (std::size_t k = 0; k < regions.size(); ++k) {
    const Region& region = *regions[k];
    const std::string where = name + ": " + (region.json_path.empty() ? "region" : region.json_path);
    if (region.kind == Region::Kind::Indices)
      for (const long long idx : region.indices)
        if (idx < 0 || static_cast<std::uint64_t>(idx) >= layout.count)
          throw ScenarioError(where + ": index " + std::to_string(idx) + " is out of range (the shape has " +
                              std::to_string(layout.count) + " points)");
    if (region.kind != Region::Kind::Field) continue;
    FieldTest& t = field_tests[k];
    t.field = findField(fields, region.field_name);
    if (t.field < 0) {
      std::string list;
      for (const auto& f : fields.fields)
        if (!f.name.empty() && f.name[0] != '_') list += (list.empty() ? "" : ", ") + f.name;
      throw ScenarioError(where + "/field/name: the shape has no field '" + region.field_name +
                          "' (its fields: " + list + ")");
    }
    const pcl::PCLPointField& f = fields.fields[static_cast<std::size_t>(t.field)];
    const std::size_t size = datatypeSize(f.datatype);
    if (size == 0 || f.count > 1)
      throw ScenarioError(where + "/field/name: field '" + region.field_name + "' is not a scalar (" +
                          std::to_string(f.count) + " values per point)");
    t.packed = region.field_name == "rgb" || region.field_name == "rgba";
    if (t.packed) {
      if (!region.equals)
        throw ScenarioError(where + "/field: a packed colour (" + region.field_name +
                            ") has no order: select one colour with equals");
      if (size != 4)
        throw ScenarioError(where + "/field/name: field '" + region.field_name +
                            "' is not a packed colour of 4 bytes");
      t.mask = region.field_name == "rgb" ? 0xFFFFFFu : 0xFFFFFFFFu;
      t.want = static_cast<std::uint32_t>(*region.equals);
    } else {
      const bool single = f.datatype == pcl::PCLPointField::FLOAT32;
      const auto as = [single](double x) { return single ? static_cast<double>(static_cast<float>(x)) : x; };
      t.lo = as(region.equals ? *region.equals : region.field_min);
      t.hi = as(region.equals ? *region.equals : region.field_max);
    }
  }
  std::vector<std::vector<long long>> sorted_indices(regions.size());
  for (std::size_t k = 0; k < regions.size(); ++k)
    if (regions[k]->kind == Region::Kind::Indices) {
      sorted_indices[k] = regions[k]->indices;
      std::sort(sorted_indices[k].begin(), sorted_indices[k].end());
    }
  std::vector<std::vector<std::uint64_t>> picked(regions.size());
  stream::Blocks blocks(layout, 1 << 16);
  blocks.share(stream::shareOf(layout.count, ranks));
  const pcl::PCLPointCloud2& c = blocks.cloud();
  stream::runPass(
      ranks,
      [&] {
        blocks.each([&](std::uint64_t i, std::size_t row) {
          const Eigen::Vector3d w = blocks.world(row);
          if (!w.allFinite() || !level.kept(i, w)) return;
          for (std::size_t k = 0; k < regions.size(); ++k) {
            const Region& r = *regions[k];
            bool in = false;
            switch (r.kind) {
              case Region::Kind::Sphere: in = (w - r.centre).squaredNorm() <= r.radius * r.radius; break;
              case Region::Kind::Box:
                in = (w.array() >= r.min.array()).all() && (w.array() <= r.max.array()).all();
                break;
              case Region::Kind::Indices:
                in = std::binary_search(sorted_indices[k].begin(), sorted_indices[k].end(),
                                        static_cast<long long>(i));
                break;
              case Region::Kind::Cylinder: {
                const Eigen::Vector3d d = r.end - r.start, p = w - r.start;
                const double t = p.dot(d) / d.squaredNorm();
                in = t >= 0 && t <= 1 && (p - t * d).squaredNorm() <= r.radius * r.radius;
                break;
              }
              case Region::Kind::Field: {
                const FieldTest& t = field_tests[k];
                const pcl::PCLPointField& f = c.fields[static_cast<std::size_t>(t.field)];
                if (t.packed) {
                  std::uint32_t v;
                  std::memcpy(&v, c.data.data() + row * c.point_step + f.offset, 4);
                  in = (v & t.mask) == t.want;
                } else {
                  const double v = readValue(c, row, f);
                  in = v >= t.lo && v <= t.hi;
                }
                break;
              }
            }
            if (in) picked[k].push_back(i);
          }
        });
      },
      [&](const std::string& failed) {
        stream::share(*ranks, failed, picked);
      });  // each list in record order
  // The checks in resolveHandles' order: each region's emptiness, then its overlap.
  const auto nonEmpty = [&](std::size_t k) {
    if (picked[k].empty())
      throw ScenarioError(name + ": " + (regions[k]->json_path.empty() ? "region" : regions[k]->json_path) +
                          ": selects no point of the shape");
  };
  RecordHandles h;
  nonEmpty(0);
  h.manipulated = std::move(picked[0]);
  for (std::size_t k = 0; k < scenario.fixed.size(); ++k) {
    nonEmpty(1 + k);
    h.fixed.push_back(std::move(picked[1 + k]));
    for (const std::uint64_t i : h.fixed.back())
      if (std::binary_search(h.manipulated.begin(), h.manipulated.end(), i))
        throw ScenarioError(name + ": " + scenario.fixed[k].json_path + ": point " + std::to_string(i) +
                            " is both fixed and manipulated");
  }
  for (std::size_t k = 0; k < scenario.joints.size(); ++k) {
    nonEmpty(1 + scenario.fixed.size() + k);
    h.joints.push_back(std::move(picked[1 + scenario.fixed.size() + k]));
    for (const std::uint64_t i : h.joints.back()) {
      bool handle = std::binary_search(h.manipulated.begin(), h.manipulated.end(), i);
      for (const auto& f : h.fixed) handle = handle || std::binary_search(f.begin(), f.end(), i);
      if (handle)
        throw ScenarioError(name + ": " + scenario.joints[k].json_path + ": joint overlaps a handle (point " +
                            std::to_string(i) + ")");
    }
  }
  return h;
}

bool canStream(const std::string& input, const std::string& output) {
  try {
    const ShapeSize size = probeShapeSize(input);
    if (!size.binary || size.compressed || size.faces > 0 || formatFromPath(output) != size.format)
      return false;
    readRecordLayout(input);
    return true;
  } catch (const IoError&) {
    return false;
  }
}

DeformReport streamDeform(const std::string& input, const Scenario& scenario, const RunOptions& options,
                          const std::string& output, StreamRanks* ranks) {
  ranks = stream::splitRanks(ranks);
  Stopwatch sw;
  DeformReport rep;
  // Runs `local` (on every rank), then checks that every rank found what rank 0 did (`found`
  // packs it): a rank that failed fails every rank, and one that differs is named.
  const auto agree = [&](auto&& local, auto&& found, const std::string& differs) {
    stream::runPass(ranks, local, [&](const std::string& failed) {
      pack::Writer w;
      if (failed.empty()) found(w);
      const std::vector<std::string> all = stream::gatherOrThrow(*ranks, failed, w.bytes());
      for (std::size_t r = 1; r < all.size(); ++r)
        if (all[r] != all[0]) throw IoError(input + ": rank " + std::to_string(r) + differs);
    });
  };
  // (A rank that cannot read the file, not on its node, fails every rank: none waits.)
  RecordLayout layout;
  agree([&] { layout = readRecordLayout(input); },
        [&](pack::Writer& w) { w.put(layout.count).put(layout.offset).put(layout.bytes); },
        " sees another file than rank 0 (other records or header): the ranks must read the same file");
  if (!layout.shape.polygons.empty())
    throw IoError(input + ": cannot stream: a mesh's faces are not streamed; read the whole file instead");
  if (formatFromPath(output) != layout.shape.format)  // before the passes, not after them
    throw IoError(output + ": cannot stream " + input + " into another format: a streamed run writes the " +
                  (layout.shape.format == FileFormat::Ply ? "binary PLY" : "binary PCD") + " it reads");
  DeformOptions opt = mergedOptions(options, scenario);
  if (opt.multires_above == 0 || layout.count <= opt.multires_above)
    throw IoError(input + ": cannot stream: " + std::to_string(layout.count) +
                  " points are built at full resolution (a streamed run builds on a coarse level, above " +
                  std::to_string(opt.multires_above) + " points); read the whole file instead");
  StreamedLevelOptions lo;
  lo.coarse_points = opt.coarse_points;
  lo.points_per_coarse = opt.points_per_coarse;
  lo.find_strays = layout.shape.polygons.empty();
  lo.ranks = ranks;
  // This rank's reads are its share's: progress counts them.
  struct Share {
    explicit Share(const RecordShare& s) { streamShare(s.first, s.last); }
    ~Share() { streamShare(0, 0); }
  } share(stream::shareOf(layout.count, ranks));
  RecordHandles handles;
  const StreamedLevel level = streamCoarseLevel(
      layout,
      [&](const StreamedLevel& frame) -> const RecordHandles& {
        handles = streamHandles(scenario, layout, frame, ranks);
        return handles;
      },
      lo);
  // The build the file read whole would make is on a coarse level: more points kept than the
  // threshold, and a level (not thousands of handles).
  if (level.points <= opt.multires_above || level.coarse.empty())
    throw IoError(input + ": cannot stream: " + std::to_string(level.points) +
                  " points are built at full resolution (a streamed run builds on a coarse level, above " +
                  std::to_string(opt.multires_above) + " points); read the whole file instead");
  if (layout.shape.isOrganized()) {
    opt.field.orient_to_viewpoint = true;
    opt.field.viewpoint = (layout.shape.sensor_origin.head<3>().cast<double>() - level.origin).cast<float>();
  }
  const StreamedDeformer s = streamedDeformer(layout, level, handles, opt, ranks);
  handles = RecordHandles();  // (the level's classes of the records serve the write)
  rep.read_ms = sw.lap();
  rep.build_ms = rep.read_ms;
  const Deformer& d = *s.deformer;
  std::vector<MoveResult> results;
  // Every rank solves on its own: the same level gives the same transforms, bit for bit (the
  // build does not depend on the thread count), and a rank whose differ would write its share
  // from another deformation: checked, not assumed.
  agree(
      [&] {
        for (std::size_t k = 0; k < scenario.moves.size(); ++k)
          results.push_back(applyMove(*s.deformer, scenario.moves[k], static_cast<int>(k) + 1));
      },
      [&](pack::Writer& w) {
        for (const Eigen::Affine3d& t : d.worldTransforms())
          for (int e = 0; e < 16; ++e) w.put(t.matrix().data()[e]);
      },
      " solved other cluster transforms than rank 0 (the ranks must run the same build of hgdeform on "
      "the same kind of machine)");
  const std::vector<std::string> write_warnings =
      writeStreamedDeformed(output, layout, level, s, 1 << 16, ranks);
  rep.write_ms = sw.lap();
  rep.points = level.points;
  describeRun(d, scenario.moves, results, opt.clusters.isovalues, rep);
  rep.notes.push_back(
      "streamed: the coarse level by passes over the file, the points written block by block (" +
      std::to_string(s.geometry->size()) + " coarse points held, and the rest positions of " +
      std::to_string(s.level->manipulated_rest.size()) + " manipulated handle points)");
  if (ranks)
    rep.notes.push_back("split across " + std::to_string(ranks->size()) +
                        " ranks: each read, deformed and wrote its share of the records; the build ran on "
                        "every rank from the gathered level");
  rep.warnings.insert(rep.warnings.begin(), level.warnings.begin(), level.warnings.end());
  rep.warnings.push_back(input +
                         ": a streamed run does not measure the surface's stretch (every point's neighbour "
                         "pairs): the report's surface figures are not computed");
  rep.warnings.insert(rep.warnings.end(), write_warnings.begin(), write_warnings.end());
  rep.total_ms = rep.build_ms + rep.solve_ms + rep.interpolation_ms + rep.write_ms;
  return rep;
}

}  // namespace hgd
