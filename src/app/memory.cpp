#include "hgdeform/app/memory.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>

namespace hgd {

namespace {
// Measured peaks (GNU time's maximum resident size; the bench's procedural scans, 300k-2M
// points, records of 24 bytes): the multi-resolution build keeps about 115 bytes a point besides
// the records (the float positions, the index maps, the interpolation table, the coarse level's
// anchors and the deformed positions); the full-resolution graph 330-430 (kNN, the Laplacian,
// the field's solver; more a point as the shape grows). The program's own base is about 20 MB.
constexpr std::uint64_t kBase = std::uint64_t{24} << 20;
constexpr std::uint64_t kPerPointCoarse = 120;
constexpr std::uint64_t kPerPointFull = 380;
constexpr std::uint64_t kLasDecoded =
    20;                                 // a LAS record's integer coordinates held as doubles, its flags apart
constexpr std::uint64_t kPerFace = 64;  // a face's vertex list (pcl::Vertices) and its share of the graph
}  // namespace

std::uint64_t availableMemory() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  std::uint64_t kb = 0;
  std::string unit;
  while (in >> key >> kb) {
    std::getline(in, unit);
    if (key == "MemAvailable:") return kb * 1024;
  }
  return 0;
}

std::uint64_t deformMemoryEstimate(const ShapeSize& size, bool full_resolution) {
  const double per_point =
      static_cast<double>(size.record_bytes + (size.format == FileFormat::Las ? kLasDecoded : 0)) +
      static_cast<double>(full_resolution ? kPerPointFull : kPerPointCoarse);
  const double total = static_cast<double>(kBase) + per_point * static_cast<double>(size.points) +
                       static_cast<double>(kPerFace) * static_cast<double>(size.faces);
  return total >= 1.8e19 ? ~std::uint64_t{0} : static_cast<std::uint64_t>(total);
}

bool parseByteCount(const std::string& text, std::uint64_t* bytes) {
  std::size_t at = 0;
  while (at < text.size() && (std::isdigit(static_cast<unsigned char>(text[at])) || text[at] == '.')) ++at;
  if (at == 0) return false;
  double value = 0;
  try {
    std::size_t used = 0;
    value = std::stod(text.substr(0, at), &used);
    if (used != at) return false;
  } catch (...) {
    return false;
  }
  std::string unit = text.substr(at);
  for (char& c : unit) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  double scale = 1;
  if (!unit.empty() && std::string("KMGT").find(unit[0]) != std::string::npos) {
    scale = std::pow(1024.0, static_cast<double>(std::string("KMGT").find(unit[0]) + 1));
    unit.erase(0, 1);
    if (unit == "IB") unit = "B";
  }
  if (!unit.empty() && unit != "B") return false;
  const double total = value * scale;
  if (!(total >= 1) || total > 1.8e19) return false;
  *bytes = static_cast<std::uint64_t>(total);
  return true;
}

std::string byteText(std::uint64_t bytes) {
  const char* units[] = {"bytes", "KB", "MB", "GB", "TB", "PB"};
  double v = static_cast<double>(bytes);
  int u = 0;
  while (v >= 1024 && u < 5) {
    v /= 1024;
    ++u;
  }
  char buf[64];
  if (u == 0)
    std::snprintf(buf, sizeof buf, "%llu bytes", static_cast<unsigned long long>(bytes));
  else
    std::snprintf(buf, sizeof buf, "%.3g %s", v, units[u]);
  return buf;
}

void checkDeformMemory(const std::string& path, std::uint64_t cap, std::size_t multires_above) {
  const bool asked = cap > 0;
  if (!asked) cap = availableMemory();
  if (cap == 0) return;
  const ShapeSize size = probeShapeSize(path);
  if (size.points == 0) return;
  const bool full = multires_above == 0 || size.points <= multires_above;
  const std::uint64_t need = deformMemoryEstimate(size, full);
  if (need <= cap) return;
  char points[64];
  std::snprintf(points, sizeof points, "%s%llu points", size.exact ? "" : "up to about ",
                static_cast<unsigned long long>(size.points));
  throw IoError(path + ": " + points + " would take about " + byteText(need) + " of memory to deform" +
                (full ? " at full resolution" : "") + ", more than the " + byteText(cap) +
                (asked ? " that --memory allows" : " this machine has available") +
                "; only a binary PLY or PCD built on a coarse level is streamed (--stream)" +
                (full && multires_above == 0 ? "; without --full-field the build takes less" : ""));
}

}  // namespace hgd
