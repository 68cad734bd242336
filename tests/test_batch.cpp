// End-to-end tests of `hgdeform batch`: folders of generated scans in fresh temporary
// directories, the real executable (HGD_TOOL) run on them, outputs read back with the library
// and compared with what `hgdeform deform` writes for each scan.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "support/shapes.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;
using hgdtest::contains;
using hgdtest::quote;
using hgdtest::shell;
using hgdtest::slurp;
using hgdtest::TempDir;
using hgdtest::writeText;
using Result = hgdtest::CommandResult;

// --- helpers ---------------------------------------------------------------------------------

std::string q(const fs::path& p) {
  return quote(p.string());
}

/// `hgdeform ARGS`.
Result cli(const std::string& args) {
  return shell(quote(HGD_TOOL) + " " + args);
}

std::size_t countOf(const std::string& text, const std::string& part) {
  std::size_t n = 0;
  for (auto p = text.find(part); p != std::string::npos; p = text.find(part, p + part.size())) ++n;
  return n;
}

/// FNV-1a (64 bit) of a file's bytes.
std::uint64_t fnv(const fs::path& path) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : slurp(path)) h = (h ^ c) * 1099511628211ull;
  return h;
}

/// The batch's own files in OUTPUT_DIR (provenance records, lock files), not outputs.
bool bookkeeping(const std::string& rel) {
  return rel.rfind(".hgdeform/", 0) == 0;
}

/// Relative path -> FNV hash of every file under `dir` (but the batch's bookkeeping).
std::map<std::string, std::uint64_t> treeHashes(const fs::path& dir) {
  std::map<std::string, std::uint64_t> m;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string rel = e.path().lexically_relative(dir).generic_string();
    if (e.is_regular_file() && !bookkeeping(rel)) m[rel] = fnv(e.path());
  }
  return m;
}

/// Relative path -> modification time of every file under `dir` (but the batch's bookkeeping).
std::map<std::string, fs::file_time_type> treeTimes(const fs::path& dir) {
  std::map<std::string, fs::file_time_type> m;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string rel = e.path().lexically_relative(dir).generic_string();
    if (e.is_regular_file() && !bookkeeping(rel)) m[rel] = e.last_write_time();
  }
  return m;
}

/// Files under `dir`; the batch's bookkeeping too with `all`.
std::vector<std::string> filesUnder(const fs::path& dir, bool all = false) {
  std::vector<std::string> v;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string rel = e.path().lexically_relative(dir).generic_string();
    if (e.is_regular_file() && (all || !bookkeeping(rel))) v.push_back(rel);
  }
  return v;
}

/// RFC 4180 parsing, for checking summary.csv.
std::vector<std::vector<std::string>> parseCsv(const std::string& text) {
  std::vector<std::vector<std::string>> rows(1);
  std::string field;
  bool quoted = false, any = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        field += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      rows.back().push_back(field);
      field.clear();
    } else if (c == '\r') {
    } else if (c == '\n') {
      rows.back().push_back(field);
      field.clear();
      rows.emplace_back();
    } else {
      field += c;
    }
    any = true;
  }
  if (!any) return {};
  if (!field.empty() || !rows.back().empty()) rows.back().push_back(field);
  if (rows.back().empty()) rows.pop_back();
  return rows;
}

Eigen::Vector3d position(const hgd::Shape& s, std::size_t i) {
  Eigen::Vector3d p;
  const char* names[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    const int f = hgd::findField(s.cloud, names[a]);
    p[a] = hgd::readValue(s.cloud, i, s.cloud.fields[static_cast<std::size_t>(f)]);
  }
  return p;
}

/// The two files hold the same points up to 1e-6 of the bounding-box diagonal.
void expectSamePoints(const fs::path& expected, const fs::path& actual) {
  SCOPED_TRACE(actual.string());
  ASSERT_TRUE(fs::exists(actual));
  const hgd::Shape a = hgd::readShape(expected.string()), b = hgd::readShape(actual.string());
  ASSERT_EQ(a.size(), b.size());
  if (b.format != hgd::FileFormat::Pcd) {  // PCD has no faces
    EXPECT_EQ(a.polygons.size(), b.polygons.size());
  }
  const double tol = 1e-6 * hgd::boundingBoxDiagonal(hgd::extractGeometry(a));
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    worst = std::max(worst, (position(a, i) - position(b, i)).norm());
  EXPECT_LE(worst, tol);
}

// --- the scans -------------------------------------------------------------------------------

// Every generated shape spans x in [0, 1]: fixed at x = 0, the end at x = 1 lifted and turned.
const char* kScenario = R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.05, 2, 1] } } ],
  "manipulated": { "box": { "min": [0.95, -1, -1], "max": [2, 2, 1] } },
  "move": { "frame": { "translate": [0, 0, 0.15], "rotate": { "axis": [0, 1, 0], "degrees": -10 } } }
})";

const char* kOwnScenario = R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.05, 2, 1] } } ],
  "manipulated": { "box": { "min": [0.95, -1, -1], "max": [2, 2, 1] } },
  "move": { "frame": { "translate": [0, 0.1, -0.2] } }
})";

const char* kNowhereScenario = R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.05, 2, 1] } } ],
  "manipulated": { "box": { "min": [10, 10, 10], "max": [11, 11, 11] } },
  "move": { "frame": { "translate": [0, 0, 0.1] } }
})";

struct Folder {
  std::vector<std::string> good;                // scans that deform (relative paths)
  std::vector<std::string> bad;                 // scans that fail
  std::map<std::string, std::string> scenario;  // scan -> its scenario (own or the default)
};

/// A folder of small scans (1–3k points): PLY, PCD, an OBJ mesh, one in a subfolder, one with
/// its own scenario, one named like the default scenario; with `bad`, a corrupt file and a scan
/// whose own scenario's handle selects nothing.
Folder makeScans(const fs::path& in, bool bad) {
  Folder f;
  fs::create_directories(in / "sub");
  const std::string dflt = (in / "scenario.json").string();
  writeText(dflt, kScenario);
  auto add = [&](const std::string& rel, const hgd::Shape& s, const char* own = nullptr) {
    hgd::writeShape((in / rel).string(), s);
    f.good.push_back(rel);
    f.scenario[rel] = dflt;
    if (own) {
      const fs::path js = (in / rel).replace_extension(".json");
      writeText(js.string(), own);
      f.scenario[rel] = js.string();
    }
  };
  add("bar_a.ply", hgd::shapes::bar(1.0f, 0.1f, 0.0125f));
  add("plane_b.pcd", hgd::shapes::bumpyPlane(3, 0.06f, 0.025f));
  add("plane_c.ply", hgd::shapes::bumpyPlane(4, 0.05f, 0.03f));
  add("mesh_d.obj", hgd::shapes::barMesh(1.0f, 0.1f, 0.0125f));
  add("sub/plane_e.pcd", hgd::shapes::bumpyPlane(2, 0.08f, 0.025f));
  add("own_f.pcd", hgd::shapes::bar(1.0f, 0.1f, 0.0125f), kOwnScenario);
  add("scenario.ply", hgd::shapes::bumpyPlane(3, 0.04f, 0.03f));  // beside the default scenario itself
  if (bad) {
    writeText((in / "corrupt.ply").string(), std::string("\x7f\x01garbage\xff\xfe not a ply file", 27));
    hgd::writeShape((in / "nowhere.ply").string(), hgd::shapes::bumpyPlane(3, 0.05f, 0.03f));
    writeText((in / "nowhere.json").string(), kNowhereScenario);
    f.bad = {"corrupt.ply", "nowhere.ply"};
  }
  return f;
}

/// What `hgdeform deform` writes for each good scan of makeScans(), computed once.
struct Reference {
  TempDir dir;
  Folder folder;
  fs::path in, out;
  Reference() {
    in = dir.path() / "in";
    out = dir.path() / "ref";
    folder = makeScans(in, true);
    for (const auto& rel : folder.good) {
      fs::create_directories((out / rel).parent_path());
      const Result r =
          cli("deform " + q(in / rel) + " -s " + quote(folder.scenario[rel]) + " -o " + q(out / rel));
      EXPECT_EQ(r.code, 0) << rel << ": " << r.err;
    }
  }
};

const Reference& reference() {
  static Reference ref;
  return ref;
}

std::string batch(const fs::path& in, const fs::path& out, const std::string& more = "") {
  return "batch -s " + q(in / "scenario.json") + " " + q(in) + " -o " + q(out) +
         (more.empty() ? "" : " " + more);
}

bool haveDisplay() {
  const char* d = std::getenv("DISPLAY");
  return d && *d;
}

// --- usage -----------------------------------------------------------------------------------

TEST(BatchUsage, HelpListsEveryOption) {
  const Result r = cli("batch --help");
  EXPECT_EQ(r.code, 0) << r.err;
  for (const char* opt : {"--scenario", "--output", "--jobs", "--recursive", "--format", "--force",
                          "--report", "--shard", "--quiet", "--help"})
    EXPECT_TRUE(contains(r.out, opt)) << opt << " missing from:\n" << r.out;
  EXPECT_TRUE(contains(cli("--help").out, "batch"));
}

TEST(BatchUsage, OutputInsideInputIsRefused) {
  TempDir dir;
  makeScans(dir.path() / "in", false);
  for (const fs::path& out :
       {dir.path() / "in" / "out", dir.path() / "in", dir.path() / "in" / "sub" / "x"}) {
    const Result r = cli(batch(dir.path() / "in", out));
    EXPECT_EQ(r.code, 2) << out;
    EXPECT_TRUE(contains(r.err, "input directory")) << r.err;
  }
  // The same through a symbolic link and a relative spelling: canonical paths are compared.
  fs::create_directory_symlink(dir.path() / "in", dir.path() / "link");
  const Result r = cli(batch(dir.path() / "in", dir.path() / "link" / "out2"));
  EXPECT_EQ(r.code, 2) << r.out;
  const Result r2 = cli(batch(dir.path() / "in", dir.path() / "in" / "sub" / ".." / "o"));
  EXPECT_EQ(r2.code, 2) << r2.out;
  const Result r3 =
      cli(batch(dir.path() / "in", dir.path() / "out3", "--report " + q(dir.path() / "in" / "rep")));
  EXPECT_EQ(r3.code, 2) << r3.out;
  EXPECT_TRUE(contains(r3.err, "report directory")) << r3.err;
  EXPECT_FALSE(fs::exists(dir.path() / "in" / "out"));
  EXPECT_FALSE(fs::exists(dir.path() / "in" / "o"));
  EXPECT_FALSE(fs::exists(dir.path() / "in" / "rep"));
}

TEST(BatchUsage, MissingInputDirectory) {
  TempDir dir;
  writeText(dir.file("s.json"), kScenario);
  const Result r = cli("batch -s " + quote(dir.file("s.json")) + " " + quote(dir.file("nope")) + " -o " +
                       quote(dir.file("out")));
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(contains(r.err, "nope")) << r.err;
  EXPECT_TRUE(contains(r.err, "does not exist")) << r.err;
  EXPECT_FALSE(fs::exists(dir.file("out")));
}

TEST(BatchUsage, BadOptions) {
  TempDir dir;
  makeScans(dir.path() / "in", false);
  const fs::path in = dir.path() / "in", out = dir.path() / "out";
  for (const char* extra : {"--shard 3/3", "--shard 1", "--shard -1/2", "--jobs 0", "--jobs x",
                            "--format obj", "--bogus", "extra_positional"}) {
    const Result r = cli(batch(in, out, extra));
    EXPECT_EQ(r.code, 2) << extra << ": " << r.err;
    EXPECT_FALSE(r.err.empty()) << extra;
  }
  const Result r = cli("batch " + q(in) + " -o " + q(out));
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(contains(r.err, "--scenario")) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

// --- a whole folder --------------------------------------------------------------------------

// A scan whose handles touch (fixed x <= 0.5, manipulated beyond, lifted by 0.3) comes apart
// along x = 0.5, and an object beside it stays: the batch says both on stderr and in the
// scan's warning in summary.json, and the other scan of the folder is not warned about.
TEST(Batch, SurfacePulledApartAndObjectLeftAreSaid) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", rep = dir.path() / "rep";
  fs::create_directories(in);
  writeText((in / "scenario.json").string(), R"({
    "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.5, 0.3, 1] } } ],
    "manipulated": { "box": { "min": [0.5001, -1, -1], "max": [2, 0.3, 1] } },
    "move": { "frame": { "translate": [0, 0.3, 0] } }
  })");
  hgd::writeShape((in / "torn.ply").string(), hgd::shapes::barBesideABox(0.0125f));
  writeText((in / "whole.json").string(), kScenario);
  hgd::writeShape((in / "whole.ply").string(), hgd::shapes::bar(1.0f, 0.1f, 0.0125f));
  const Result r = cli(batch(in, out, "--report " + q(rep)));
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_TRUE(contains(r.err, "torn.ply")) << r.err;
  EXPECT_EQ(countOf(r.err, "the surface is pulled apart at"), 1u) << r.err;
  const auto j = nlohmann::json::parse(slurp(rep / "summary.json"));
  std::map<std::string, std::string> warning;
  for (const auto& s : j.at("scans")) warning[s.at("file").get<std::string>()] = s.value("warning", "");
  EXPECT_TRUE(contains(warning["torn.ply"], "the surface is pulled apart at")) << j.dump();
  EXPECT_TRUE(contains(warning["torn.ply"], "that touch no handle lie apart")) << j.dump();
  EXPECT_EQ(countOf(r.err, "that touch no handle lie apart"), 1u) << r.err;
  EXPECT_FALSE(contains(warning["whole.ply"], "pulled apart")) << j.dump();
}

// DISPLAY names an X server that is not there (VTK would abort the process): every scan is
// still deformed and summarised; the thumbnails are skipped with one warning that says why, on
// stderr, in summary.json's warnings and at the top of index.html (the issue: only the page
// said it, the run itself said nothing).
TEST(Batch, AbsentXServerSkipsThumbnailsOnly) {
  const Reference& ref = reference();
  TempDir dir;
  const fs::path out = dir.path() / "out", rep = dir.path() / "report";
  const Result r =
      shell("DISPLAY=:4711 " + quote(HGD_TOOL) + " " + batch(ref.in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(r.code, 1) << r.out << r.err;  // the folder's two bad scans
  for (const auto& rel : ref.folder.good) EXPECT_TRUE(fs::exists(out / rel)) << rel;
  EXPECT_EQ(countOf(r.err, "hgdeform batch: warning: no thumbnails"), 1u) << r.err;
  EXPECT_TRUE(contains(r.err, "cannot open the X display ':4711'")) << r.err;
  const auto j = nlohmann::json::parse(slurp(rep / "summary.json"));
  EXPECT_EQ(j.at("scans").size(), ref.folder.good.size() + ref.folder.bad.size());
  ASSERT_TRUE(j.contains("warnings")) << j.dump(2);
  ASSERT_EQ(j.at("warnings").size(), 1u) << j.at("warnings").dump();
  EXPECT_TRUE(contains(j.at("warnings")[0].get<std::string>(), "no thumbnails")) << j.at("warnings").dump();
  EXPECT_TRUE(contains(j.at("warnings")[0].get<std::string>(), "cannot open the X display ':4711'"));
  EXPECT_TRUE(fs::exists(rep / "summary.csv"));
  const std::string html = slurp(rep / "index.html");
  EXPECT_TRUE(contains(html, "cannot open the X display")) << html;
  EXPECT_FALSE(contains(html, "<img")) << html;
}

#ifdef HGD_HAVE_RENDER
// The renderer (VTK, OpenGL, X11) is a module that only a batch writing a report loads: without
// one, the program starts with none of its libraries (the loader's own log says which it opens).
TEST(Batch, OnlyAReportLoadsTheRenderer) {
  const Reference& ref = reference();
  TempDir dir;
  // The loader's log (LD_DEBUG=files): "file=LIB [0];  needed by WHO" for a dependency,
  // "file=PATH [0];  dynamically loaded by WHO" for a dlopen. A library the program itself
  // needs, or the module's, is the renderer's way in. (A sanitizer build's libhgdeform may need
  // VTK for PCL's sake, without --as-needed: that is the library's, not the program's.)
  const auto loaded = [](const std::string& log, const std::string& library, const std::string& by) {
    std::istringstream lines(log);
    for (std::string line; std::getline(lines, line);)
      if (contains(line, "file=") && contains(line, library) && contains(line, by)) return true;
    return false;
  };
  const std::string program = fs::canonical(HGD_TOOL).string();
  const Result plain = shell("LD_DEBUG=files " + quote(HGD_TOOL) + " " + batch(ref.in, dir.path() / "a", ""));
  EXPECT_TRUE(loaded(plain.err, "lib", "needed by " + program)) << "LD_DEBUG gave no log:\n" << plain.err;
  for (const char* lib : {"libvtk", "libpcl_visualization", "libGL", "libX11"})
    EXPECT_FALSE(loaded(plain.err, lib, "needed by " + program)) << lib << " is needed by the program itself";
  EXPECT_FALSE(loaded(plain.err, "libhgdeform_thumbnails", ""))
      << "a batch without a report loaded the renderer";
  const Result report = shell("DISPLAY=:4711 LD_DEBUG=files " + quote(HGD_TOOL) + " " +
                              batch(ref.in, dir.path() / "b", "--report " + q(dir.path() / "r")));
  EXPECT_TRUE(loaded(report.err, "libhgdeform_thumbnails", "dynamically loaded by"))
      << "the report did not load it";
}

// Without the module, a report is written without pictures and says why; the scans are done.
TEST(Batch, MissingRendererModuleSkipsThumbnailsOnly) {
  const Reference& ref = reference();
  TempDir dir;
  const fs::path out = dir.path() / "out", rep = dir.path() / "report", gone = dir.path() / "libgone.so";
  const Result r = shell("HGDEFORM_THUMBNAILS_MODULE=" + q(gone) + " " + quote(HGD_TOOL) + " " +
                         batch(ref.in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(r.code, 1) << r.out << r.err;  // the folder's two bad scans
  for (const auto& rel : ref.folder.good) EXPECT_TRUE(fs::exists(out / rel)) << rel;
  EXPECT_EQ(
      countOf(r.err, "hgdeform batch: warning: no thumbnails: the thumbnail renderer could not be loaded"),
      1u)
      << r.err;
  EXPECT_TRUE(contains(r.err, gone.string())) << r.err;
  EXPECT_FALSE(contains(r.err, "X display")) << r.err;  // not a display problem
  const auto j = nlohmann::json::parse(slurp(rep / "summary.json"));
  ASSERT_EQ(j.at("warnings").size(), 1u) << j.dump(2);
  EXPECT_TRUE(contains(j.at("warnings")[0].get<std::string>(), "could not be loaded"));
  EXPECT_FALSE(contains(slurp(rep / "index.html"), "<img"));
}

// A library that is not the thumbnail module (here hgdeform's own) is refused by name, before any
// call into it; the report is written without pictures.
TEST(Batch, ALibraryThatIsNotTheModuleIsRefused) {
  const fs::path other = fs::path(HGD_TOOL).parent_path().parent_path() / "libhgdeform.so";
  if (!fs::exists(other)) GTEST_SKIP() << "no " << other << " (a static build)";
  const Reference& ref = reference();
  TempDir dir;
  const fs::path rep = dir.path() / "report";
  const Result r = shell("HGDEFORM_THUMBNAILS_MODULE=" + q(other) + " " + quote(HGD_TOOL) + " " +
                         batch(ref.in, dir.path() / "out", "--recursive --report " + q(rep)));
  EXPECT_EQ(r.code, 1) << r.out << r.err;  // the folder's two bad scans, as without the module
  EXPECT_EQ(countOf(r.err, "hgdeform batch: warning: no thumbnails: " + other.string() +
                               " has no hgd_thumbnails_abi (not hgdeform's thumbnail module?)"),
            1u)
      << r.err;
  EXPECT_FALSE(contains(slurp(rep / "index.html"), "<img"));
}
#endif

TEST(Batch, DeformsLikeDeformAndReportsFailures) {
  const Reference& ref = reference();
  TempDir dir;
  const fs::path out = dir.path() / "out", rep = dir.path() / "report";
  const auto before = treeHashes(ref.in);
  const Result r = cli(batch(ref.in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_EQ(treeHashes(ref.in), before) << "inputs modified";

  // Good scans: the same as `hgdeform deform`, same relative paths and formats.
  for (const auto& rel : ref.folder.good) expectSamePoints(ref.out / rel, out / rel);
  for (const auto& rel : ref.folder.bad) EXPECT_FALSE(fs::exists(out / rel)) << rel;
  EXPECT_EQ(filesUnder(out).size(), ref.folder.good.size());

  // Log: one line per scan; failures also on stderr, naming the file and the problem.
  const std::size_t total = ref.folder.good.size() + ref.folder.bad.size();
  EXPECT_EQ(countOf(r.out, ": ok "), ref.folder.good.size()) << r.out;
  EXPECT_EQ(countOf(r.out, ": FAILED: "), 2u) << r.out;
  EXPECT_TRUE(contains(r.out, "/" + std::to_string(total) + "] sub/plane_e.pcd: ok ")) << r.out;
  EXPECT_TRUE(contains(r.err, "corrupt.ply")) << r.err;
  EXPECT_TRUE(contains(r.err, "selects no point")) << r.err;

  // summary.json
  const auto j = nlohmann::json::parse(slurp(rep / "summary.json"));
  ASSERT_EQ(j.at("scans").size(), total);
  EXPECT_EQ(j.at("totals").at("scans"), total);
  EXPECT_EQ(j.at("totals").at("ok"), ref.folder.good.size());
  EXPECT_EQ(j.at("totals").at("failed"), 2);
  std::map<std::string, nlohmann::json> by_file;
  for (const auto& s : j.at("scans")) by_file[s.at("file").get<std::string>()] = s;
  for (const auto& rel : ref.folder.good) {
    ASSERT_TRUE(by_file.count(rel)) << rel;
    EXPECT_EQ(by_file[rel].at("status"), "ok") << rel;
    EXPECT_GT(by_file[rel].at("points").get<int>(), 500) << rel;
    EXPECT_GT(by_file[rel].at("ms").at("total").get<double>(), 0) << rel;
  }
  EXPECT_EQ(by_file["own_f.pcd"].at("own_scenario"), true);
  EXPECT_EQ(by_file["scenario.ply"].at("own_scenario"), false);  // the default is not an override
  EXPECT_EQ(by_file["bar_a.ply"].at("own_scenario"), false);
  EXPECT_EQ(by_file["corrupt.ply"].at("status"), "failed");
  EXPECT_TRUE(contains(by_file["corrupt.ply"].at("error").get<std::string>(), "corrupt.ply"));
  EXPECT_EQ(by_file["nowhere.ply"].at("status"), "failed");
  EXPECT_TRUE(contains(by_file["nowhere.ply"].at("error").get<std::string>(), "selects no point"));

  // summary.csv, quoted as CSV
  const auto rows = parseCsv(slurp(rep / "summary.csv"));
  ASSERT_EQ(rows.size(), total + 1);
  const std::vector<std::string> header = {
      "file",     "status",   "error",       "points",      "clusters", "iterations",       "handle_error",
      "ms_build", "ms_field", "ms_sampling", "ms_clusters", "ms_solve", "ms_interpolation", "ms_total",
      "reason"};
  EXPECT_EQ(rows[0], header);
  std::map<std::string, std::vector<std::string>> csv;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), header.size()) << i;
    csv[rows[i][0]] = rows[i];
  }
  EXPECT_EQ(csv["nowhere.ply"][1], "failed");
  EXPECT_EQ(csv["nowhere.ply"][2], by_file["nowhere.ply"].at("error").get<std::string>());
  EXPECT_EQ(csv["corrupt.ply"][2], by_file["corrupt.ply"].at("error").get<std::string>());
  EXPECT_EQ(csv["plane_b.pcd"][1], "ok");
  EXPECT_EQ(csv["plane_b.pcd"][3], std::to_string(by_file["plane_b.pcd"].at("points").get<int>()));
  EXPECT_EQ(csv["plane_b.pcd"].back(), "new");
  EXPECT_EQ(by_file["plane_b.pcd"].at("reason"), "new");

  // index.html: every scan, and thumbnails exactly when there is a display.
  const std::string html = slurp(rep / "index.html");
  for (const auto& rel : ref.folder.good) EXPECT_TRUE(contains(html, rel)) << rel;
  for (const auto& rel : ref.folder.bad) EXPECT_TRUE(contains(html, rel)) << rel;
#ifdef HGD_HAVE_RENDER
  if (haveDisplay()) {
    for (const auto& rel : ref.folder.good) {
      const fs::path png = rep / "thumbs" / (rel + ".png");
      EXPECT_TRUE(fs::exists(png) && fs::file_size(png) > 0) << png;
      EXPECT_TRUE(contains(html, "thumbs/" + rel + ".png")) << rel;
    }
    return;
  }
#endif
  EXPECT_TRUE(contains(html, "need")) << html;
  EXPECT_FALSE(contains(html, "<img")) << html;
  EXPECT_FALSE(fs::exists(rep / "thumbs"));
}

TEST(Batch, TopLevelOnlyAndFormatConversion) {
  const Reference& ref = reference();
  TempDir dir;
  const Result r = cli(batch(ref.in, dir.path() / "ply", "--format ply -q"));
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(r.out.empty()) << r.out;  // --quiet: errors only
  EXPECT_TRUE(contains(r.err, "corrupt.ply")) << r.err;
  EXPECT_FALSE(fs::exists(dir.path() / "ply" / "sub"));  // not --recursive
  for (const auto& rel : ref.folder.good) {
    if (rel.rfind("sub/", 0) == 0) continue;
    expectSamePoints(ref.out / rel, (dir.path() / "ply" / rel).replace_extension(".ply"));
  }
  EXPECT_FALSE(fs::exists(dir.path() / "ply" / "plane_b.pcd"));
  const Result r2 = cli(batch(ref.in, dir.path() / "pcd", "--format pcd --recursive -q"));
  EXPECT_EQ(r2.code, 1);
  for (const auto& rel : ref.folder.good)
    expectSamePoints(ref.out / rel, (dir.path() / "pcd" / rel).replace_extension(".pcd"));
}

TEST(Batch, TwoScansOntoOneOutputFail) {
  TempDir dir;
  const fs::path in = dir.path() / "in";
  makeScans(in, false);
  hgd::writeShape((in / "plane_b.ply").string(), hgd::shapes::bumpyPlane(3, 0.06f, 0.025f));
  const Result r = cli(batch(in, dir.path() / "out", "--format ply"));
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.err, "plane_b.pcd")) << r.err;
  EXPECT_TRUE(fs::exists(dir.path() / "out" / "plane_b.ply"));
}

TEST(Batch, JobsGiveTheSameOutputs) {
  TempDir dir;
  const fs::path in = dir.path() / "in";
  makeScans(in, false);
  const Result r1 = cli(batch(in, dir.path() / "one", "--recursive --jobs 1"));
  const Result r2 = cli(batch(in, dir.path() / "two", "--recursive --jobs 2"));
  EXPECT_EQ(r1.code, 0) << r1.err;
  EXPECT_EQ(r2.code, 0) << r2.err;
  EXPECT_EQ(countOf(r2.out, ": ok "), 7u) << r2.out;
  EXPECT_EQ(treeHashes(dir.path() / "one"), treeHashes(dir.path() / "two"));
}

// --- resuming --------------------------------------------------------------------------------

TEST(Batch, ResumesAndForceRedoes) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out";
  const Folder f = makeScans(in, false);
  const std::size_t n = f.good.size();
  const Result r1 = cli(batch(in, out, "--recursive"));
  ASSERT_EQ(r1.code, 0) << r1.err;
  EXPECT_EQ(countOf(r1.out, ": ok "), n) << r1.out;
  const auto t1 = treeTimes(out);
  ASSERT_EQ(t1.size(), n);

  // Nothing to do.
  const Result r2 = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(r2.code, 0) << r2.err;
  EXPECT_EQ(countOf(r2.out, ": skipped (up to date)"), n) << r2.out;
  EXPECT_EQ(treeTimes(out), t1);

  // A newer input or own scenario with the same content: still up to date (provenance, not
  // times; BatchProvenance tests the details).
  fs::last_write_time(in / "plane_c.ply", fs::file_time_type::clock::now());
  fs::last_write_time(in / "own_f.json", fs::file_time_type::clock::now());
  const Result r3 = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(r3.code, 0) << r3.err;
  EXPECT_EQ(countOf(r3.out, ": skipped (up to date)"), n) << r3.out;
  EXPECT_EQ(treeTimes(out), t1);

  // A changed own scenario: that scan again.
  writeText((in / "own_f.json").string(), kScenario);
  const Result r4 = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(countOf(r4.out, ": ok "), 1u) << r4.out;
  EXPECT_TRUE(contains(r4.out, "own_f.pcd: ok ")) << r4.out;
  EXPECT_TRUE(contains(r4.out, "(scenario changed)")) << r4.out;

  // --force: everything.
  const auto t4 = treeTimes(out);
  const Result r5 = cli(batch(in, out, "--recursive --force"));
  EXPECT_EQ(r5.code, 0) << r5.err;
  EXPECT_EQ(countOf(r5.out, ": ok "), n) << r5.out;
  EXPECT_EQ(countOf(r5.out, " ms (forced)"), n) << r5.out;
  const auto t5 = treeTimes(out);
  for (const auto& [rel, t] : t4) EXPECT_GT(t5.at(rel), t) << rel;
}

// --- provenance ------------------------------------------------------------------------------

/// summary.json's scans: file -> reason.
std::map<std::string, std::string> reasons(const fs::path& report) {
  std::map<std::string, std::string> m;
  const auto j = nlohmann::json::parse(slurp(report / "summary.json"));
  for (const auto& s : j.at("scans")) m[s.at("file").get<std::string>()] = s.at("reason").get<std::string>();
  return m;
}

nlohmann::json record(const fs::path& out, const std::string& rel) {
  return nlohmann::json::parse(slurp(out / ".hgdeform" / "records" / (rel + ".json")));
}

/// `hgdeform ARGS` in the background, paused by HGDEFORM_BATCH_TEST_HOOK once the output of
/// `rel` is written; returns when it is paused (the caller removes `flag` to let it go on).
std::future<Result> startPaused(const std::string& args, const std::string& rel, const fs::path& flag,
                                const fs::path& err) {
  auto run = std::async(std::launch::async, [=] {
    Result r = shell("(HGDEFORM_BATCH_TEST_HOOK=" + quote(rel + ":" + flag.string()) + " " + quote(HGD_TOOL) +
                     " " + args + " 2>" + q(err) + ")");
    r.err = slurp(err);
    return r;
  });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!fs::exists(flag) && std::chrono::steady_clock::now() < deadline &&
         run.wait_for(std::chrono::milliseconds(10)) != std::future_status::ready) {
  }
  return run;
}

// The issue: a changed scenario whose file is not newer than the outputs (restored from a
// backup, checked out, another file named by -s) was "up to date".
TEST(BatchProvenance, EditedScenarioRedoesEveryScanThatUsesIt) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", rep = dir.path() / "report";
  const Folder f = makeScans(in, false);
  const std::size_t n = f.good.size();
  const auto old = fs::last_write_time(in / "scenario.json");
  ASSERT_EQ(cli(batch(in, out, "--recursive")).code, 0);
  const auto t1 = treeTimes(out);

  // The same scenario written differently (spacing, key order): its canonical form is the same.
  writeText(
      (in / "scenario.json").string(),
      R"({"move": { "frame": { "rotate": { "degrees": -10, "axis": [0, 1, 0] }, "translate": [0, 0, 0.15] } },
                "manipulated": { "box": { "max": [2, 2, 1], "min": [0.95, -1, -1] } },
                "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.05, 2, 1] } } ],
                "format": "hgdeform-scenario/1"})");
  const Result same = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(same.code, 0) << same.err;
  EXPECT_EQ(countOf(same.out, ": skipped (up to date)"), n) << same.out;
  EXPECT_EQ(treeTimes(out), t1);

  // Another move, with the old time.
  writeText((in / "scenario.json").string(), kOwnScenario);
  fs::last_write_time(in / "scenario.json", old);
  const Result r = cli(batch(in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(countOf(r.out, " ms (scenario changed)"), n - 1) << r.out;
  EXPECT_TRUE(contains(r.out, "own_f.pcd: skipped (up to date)")) << r.out;  // its own scenario
  for (const auto& [file, why] : reasons(rep))
    EXPECT_EQ(why, file == "own_f.pcd" ? "up to date" : "scenario changed") << file;
  const auto rows = parseCsv(slurp(rep / "summary.csv"));
  ASSERT_EQ(rows.size(), n + 1);
  EXPECT_EQ(rows[0].back(), "reason");
  for (std::size_t i = 1; i < rows.size(); ++i)
    EXPECT_EQ(rows[i].back(), rows[i][0] == "own_f.pcd" ? "up to date" : "scenario changed") << rows[i][0];
  // What each output was made from.
  const auto rec = record(out, "bar_a.ply");
  EXPECT_EQ(rec.at("input").at("file"), "bar_a.ply");
  EXPECT_EQ(rec.at("input").at("size"), fs::file_size(in / "bar_a.ply"));
  EXPECT_EQ(rec.at("input").at("xxh3").get<std::string>().size(), 16u);
  EXPECT_EQ(rec.at("options").at("output_format"), "ply");
  EXPECT_TRUE(contains(rec.at("tool").get<std::string>(), "hgdeform "));
  EXPECT_EQ(rec.at("output").at("size"), fs::file_size(out / "bar_a.ply"));

  // Options: --format pcd writes other files; --format ply on PLY inputs changes nothing.
  const Result ply = cli(batch(in, out, "--recursive --format ply"));
  EXPECT_EQ(countOf(ply.out, ": skipped (up to date)"), 3u) << ply.out;  // bar_a, plane_c, scenario.ply
  // A deleted output, an output edited by hand, one whose 12 last bytes were zeroed in place
  // with its time restored (same size: the issue, "up to date"), one replaced by a copy of
  // itself (same bytes and time, another inode).
  fs::remove(out / "plane_c.ply");
  writeText((out / "bar_a.ply").string(), "spoilt");
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // past the ctime of the last write
  const fs::path zeroed = out / "sub" / "plane_e.pcd", copied = out / "mesh_d.obj";
  const auto zeroed_time = fs::last_write_time(zeroed), copied_time = fs::last_write_time(copied);
  const std::string zeroed_bytes = slurp(zeroed);
  {
    std::fstream file(zeroed, std::ios::in | std::ios::out | std::ios::binary);
    file.seekp(-12, std::ios::end);
    file.write("\0\0\0\0\0\0\0\0\0\0\0\0", 12);
  }
  fs::last_write_time(zeroed, zeroed_time);
  fs::copy_file(copied, out / "copy.tmp");
  fs::rename(out / "copy.tmp", copied);
  fs::last_write_time(copied, copied_time);
  const Result again = cli(batch(in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(again.code, 0) << again.err;
  EXPECT_EQ(reasons(rep)["plane_c.ply"], "output missing");
  EXPECT_EQ(reasons(rep)["bar_a.ply"], "output changed");
  EXPECT_EQ(reasons(rep)["sub/plane_e.pcd"], "output changed");
  EXPECT_EQ(reasons(rep)["mesh_d.obj"], "output changed");
  EXPECT_EQ(reasons(rep)["plane_b.pcd"], "up to date");
  EXPECT_EQ(countOf(again.out, ": ok "), 4u) << again.out;
  EXPECT_TRUE(slurp(zeroed) == zeroed_bytes) << "not redone";
  const Result settled = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(countOf(settled.out, ": skipped (up to date)"), n) << settled.out;
}

// The issue: a touched input was redone; a changed one older than its output was not.
TEST(BatchProvenance, InputsAreComparedByContent) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", rep = dir.path() / "report";
  const Folder f = makeScans(in, false);
  const std::size_t n = f.good.size();
  ASSERT_EQ(cli(batch(in, out, "--recursive")).code, 0);
  const auto t1 = treeTimes(out);
  const auto old = fs::last_write_time(in / "plane_c.ply");

  // Touched, same bytes: not redone; the record learns the new time.
  fs::last_write_time(in / "plane_c.ply", fs::file_time_type::clock::now() + std::chrono::seconds(5));
  const Result touched = cli(batch(in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(touched.code, 0) << touched.err;
  EXPECT_EQ(countOf(touched.out, ": skipped (up to date)"), n) << touched.out;
  EXPECT_EQ(treeTimes(out), t1);
  EXPECT_EQ(reasons(rep)["plane_c.ply"], "up to date");
  struct stat st {};
  ASSERT_EQ(::stat((in / "plane_c.ply").c_str(), &st), 0);
  const long long ns = static_cast<long long>(st.st_mtim.tv_sec) * 1000000000LL + st.st_mtim.tv_nsec;
  EXPECT_EQ(record(out, "plane_c.ply").at("input").at("mtime_ns").get<long long>(), ns);

  // Its mode changed (its ctime moves, not its mtime): hashed again, same bytes, up to date;
  // the record learns the new ctime.
  fs::permissions(in / "plane_c.ply", fs::perms::owner_exec, fs::perm_options::add);
  const Result chmodded = cli(batch(in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(countOf(chmodded.out, ": skipped (up to date)"), n) << chmodded.out;
  EXPECT_EQ(treeTimes(out), t1);
  ASSERT_EQ(::stat((in / "plane_c.ply").c_str(), &st), 0);
  EXPECT_EQ(record(out, "plane_c.ply").at("input").at("ctime_ns").get<long long>(),
            static_cast<long long>(st.st_ctim.tv_sec) * 1000000000LL + st.st_ctim.tv_nsec);
  EXPECT_EQ(record(out, "plane_c.ply").at("input").at("inode").get<unsigned long long>(),
            static_cast<unsigned long long>(st.st_ino));

  // A byte changed in place, its time put back (touch -r): same size and mtime (the issue: "up
  // to date"); its ctime gives it away, and its bytes decide.
  {
    const auto mtime = fs::last_write_time(in / "bar_a.ply");
    std::fstream file(in / "bar_a.ply", std::ios::in | std::ios::out | std::ios::binary);
    file.seekg(-1, std::ios::end);
    char last = 0;
    file.get(last);
    file.seekp(-1, std::ios::end);
    file.put(static_cast<char>(last ^ 0x40));
    file.close();
    fs::last_write_time(in / "bar_a.ply", mtime);
  }
  const Result flipped = cli(batch(in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(flipped.code, 0) << flipped.err;
  EXPECT_TRUE(contains(flipped.out, "bar_a.ply: ok ")) << flipped.out;
  EXPECT_EQ(reasons(rep)["bar_a.ply"], "input changed");
  EXPECT_EQ(countOf(flipped.out, ": skipped (up to date)"), n - 1) << flipped.out;
  const auto t2 = treeTimes(out);

  // New bytes with an old time (older than the output): only that scan again.
  hgd::writeShape((in / "plane_c.ply").string(), hgd::shapes::bumpyPlane(4, 0.08f, 0.03f));
  fs::last_write_time(in / "plane_c.ply", old - std::chrono::hours(1));
  const Result changed = cli(batch(in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(changed.code, 0) << changed.err;
  EXPECT_EQ(countOf(changed.out, ": ok "), 1u) << changed.out;
  EXPECT_TRUE(contains(changed.out, "plane_c.ply: ok ")) << changed.out;
  EXPECT_TRUE(contains(changed.out, " ms (input changed)")) << changed.out;
  EXPECT_EQ(reasons(rep)["plane_c.ply"], "input changed");
  EXPECT_EQ(countOf(changed.out, ": skipped (up to date)"), n - 1) << changed.out;
  const auto t3 = treeTimes(out);
  for (const auto& [rel, t] : t2) {
    if (rel == "plane_c.ply")
      EXPECT_NE(t3.at(rel), t) << rel;
    else
      EXPECT_EQ(t3.at(rel), t) << rel;
  }
}

// The issue: an input replaced during the run got an output newer than itself and was then
// skipped for ever.
TEST(BatchProvenance, InputChangedDuringTheRunIsRedoneNextTime) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", flag = dir.path() / "paused";
  const Folder f = makeScans(in, false);
  auto run = startPaused(batch(in, out, "--recursive"), "plane_b.pcd", flag, dir.path() / "err.txt");
  ASSERT_TRUE(fs::exists(flag)) << run.get().err;
  // Replaced between read and record, with a time before its output's.
  hgd::writeShape((in / "plane_b.pcd").string(), hgd::shapes::bumpyPlane(3, 0.09f, 0.025f));
  fs::last_write_time(in / "plane_b.pcd", fs::last_write_time(out / "plane_b.pcd") - std::chrono::seconds(1));
  fs::remove(flag);
  const Result r = run.get();
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.err, "plane_b.pcd: warning: the input changed while it was being deformed"))
      << r.err;
  EXPECT_TRUE(record(out, "plane_b.pcd").contains("invalid"));

  const Result again = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(again.code, 0) << again.err;
  EXPECT_TRUE(contains(again.out, "plane_b.pcd: ok ")) << again.out;
  EXPECT_TRUE(contains(again.out, " ms (input changed)")) << again.out;
  EXPECT_EQ(countOf(again.out, ": skipped (up to date)"), f.good.size() - 1) << again.out;
  EXPECT_FALSE(record(out, "plane_b.pcd").contains("invalid"));
  const Result third = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(countOf(third.out, ": skipped (up to date)"), f.good.size()) << third.out;
}

TEST(BatchProvenance, SecondRunOnOneOutputFolderRefuses) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", flag = dir.path() / "paused";
  makeScans(in, false);
  auto first = startPaused(batch(in, out), "bar_a.ply", flag, dir.path() / "err1.txt");
  ASSERT_TRUE(fs::exists(flag)) << first.get().err;
  const Result second = cli(batch(in, out));
  EXPECT_EQ(second.code, 1) << second.out << second.err;
  EXPECT_TRUE(contains(second.err, "is in use by another hgdeform batch (pid ")) << second.err;
  EXPECT_TRUE(contains(second.err, "all scans")) << second.err;
  EXPECT_TRUE(second.out.empty()) << second.out;
  const Result shard = cli(batch(in, out, "--shard 1/2"));
  EXPECT_EQ(shard.code, 1) << shard.out << shard.err;
  EXPECT_TRUE(contains(shard.err, "is in use by another hgdeform batch")) << shard.err;
#ifdef HGD_HAVE_MPI
  if (shell("command -v mpirun").code == 0) {
    const Result mpi =
        shell("mpirun --allow-run-as-root --oversubscribe -np 2 " + quote(HGD_TOOL) + " " + batch(in, out));
    EXPECT_NE(mpi.code, 0) << mpi.out << mpi.err;
    EXPECT_EQ(countOf(mpi.err, "is in use by another hgdeform batch"), 1u) << mpi.err;  // rank 0 only
  }
#endif
  fs::remove(flag);
  const Result r1 = first.get();
  EXPECT_EQ(r1.code, 0) << r1.err;
  const Result later = cli(batch(in, out));
  EXPECT_EQ(later.code, 0) << later.err;  // released when the first run ended
  EXPECT_EQ(countOf(later.out, ": skipped (up to date)"), 6u) << later.out;
}

// Shards of one split share an output folder (a job array); other runs do not.
TEST(BatchProvenance, ShardsOfOneSplitShareTheOutputFolder) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", flag = dir.path() / "paused";
  makeScans(in, false);
  auto first = startPaused(batch(in, out, "--shard 0/2"), "bar_a.ply", flag, dir.path() / "err1.txt");
  ASSERT_TRUE(fs::exists(flag)) << first.get().err;
  const Result other = cli(batch(in, out, "--shard 1/2"));
  EXPECT_EQ(other.code, 0) << other.err;
  const Result same = cli(batch(in, out, "--shard 0/2"));
  EXPECT_EQ(same.code, 1) << same.err;
  EXPECT_TRUE(contains(same.err, "shard 0/2 is already running")) << same.err;
  const Result split = cli(batch(in, out, "--shard 0/3"));
  EXPECT_EQ(split.code, 1) << split.err;
  EXPECT_TRUE(contains(split.err, "must all use --shard K/2")) << split.err;
  const Result whole = cli(batch(in, out));
  EXPECT_EQ(whole.code, 1) << whole.err;
  EXPECT_TRUE(contains(whole.err, "--shard K/2")) << whole.err;
  fs::remove(flag);
  EXPECT_EQ(first.get().code, 0);
  EXPECT_EQ(countOf(cli(batch(in, out)).out, ": skipped (up to date)"), 6u);
}

// --- entries that are not scans ---------------------------------------------------------------

// The issue: FIFOs, dangling links and symlinked folders were skipped without a word.
TEST(Batch, SaysWhichEntriesAreNotScans) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", rep = dir.path() / "report";
  const Folder f = makeScans(in, false);
  ASSERT_EQ(::mkfifo((in / "pipe.ply").c_str(), 0644), 0);
  fs::create_symlink(in / "gone" / "scan.pcd", in / "dangling.pcd");
  fs::create_symlink(in / "gone.ply", in / "notes");         // named otherwise, but names a scan
  fs::create_symlink(in / "nothing.txt", in / "other.txt");  // nothing to do with scans: quiet
  fs::create_directory_symlink(in / "sub", in / "linked");
  fs::create_directory_symlink(in, in / "sub" / "cycle");
  const Result r = cli(batch(in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_EQ(countOf(r.out, ": ok "), f.good.size()) << r.out;
  EXPECT_TRUE(contains(r.err, "warning: skipped pipe.ply: a FIFO, not a regular file")) << r.err;
  EXPECT_TRUE(contains(r.err, "warning: skipped dangling.pcd: a dangling symbolic link")) << r.err;
  EXPECT_TRUE(contains(r.err, "warning: skipped notes: a dangling symbolic link")) << r.err;
  EXPECT_TRUE(contains(r.err,
                       "warning: skipped linked: a symbolic link to a folder: not followed, to avoid "
                       "cycles"))
      << r.err;
  EXPECT_TRUE(contains(r.err, "warning: skipped sub/cycle: a symbolic link to a folder")) << r.err;
  EXPECT_FALSE(contains(r.err, "other.txt")) << r.err;
  EXPECT_TRUE(contains(r.out, "; 5 entries skipped (see the warnings)")) << r.out;
  const auto j = nlohmann::json::parse(slurp(rep / "summary.json"));
  EXPECT_EQ(j.at("totals").at("skipped_entries"), 5);
  ASSERT_EQ(j.at("skipped_entries").size(), 5u);
  EXPECT_EQ(j.at("skipped_entries")[0].at("path"), "dangling.pcd");
  EXPECT_TRUE(contains(slurp(rep / "index.html"), "pipe.ply: a FIFO"));
  // Not recursive: folders are not searched, links to them are not worth a word.
  const Result top = cli(batch(in, dir.path() / "top"));
  EXPECT_FALSE(contains(top.err, "linked")) << top.err;
  EXPECT_TRUE(contains(top.err, "pipe.ply")) << top.err;
}

// Issue 48: a link named like a scan to a file that is none (a password file, a log) failed
// quoting its text on stderr and in summary.json. It fails saying the content is of no format.
TEST(Batch, AFileThatIsNoScanIsNotQuoted) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", rep = dir.path() / "report";
  const Folder f = makeScans(in, false);
  writeText((dir.path() / "private.txt").string(), "alpha bravo charlie delta\nsecret words follow here\n");
  fs::create_symlink(dir.path() / "private.txt", in / "linked.xyz");
  const Result r = cli(batch(in, out, "--recursive --report " + q(rep)));
  EXPECT_NE(r.code, 0);
  EXPECT_EQ(countOf(r.out, ": ok "), f.good.size()) << r.out;
  const std::string summary = slurp(rep / "summary.json");
  for (const char* word : {"alpha", "secret", "words"}) {
    EXPECT_FALSE(contains(r.err, word)) << r.err;
    EXPECT_FALSE(contains(r.out, word)) << r.out;
    EXPECT_FALSE(contains(summary, word)) << summary;
  }
  EXPECT_TRUE(contains(r.err, "linked.xyz")) << r.err;
  EXPECT_TRUE(contains(r.err, "matches no format")) << r.err;
}

// Issue 28: a scan's own scenario that is there but cannot be read (a dangling link, a FIFO, a
// folder, a loop of links) was passed over in silence: the scan took the default scenario. It
// fails, saying which file and why; the scans beside it go on.
TEST(Batch, OwnScenarioThatCannotBeReadFailsTheScan) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", rep = dir.path() / "report";
  fs::create_directories(in);
  writeText((in / "scenario.json").string(), kScenario);
  const hgd::Shape plane = hgd::shapes::bumpyPlane(2, 0.08f, 0.025f);
  const std::map<std::string, std::string> why = {
      {"dangling_b",
       "a dangling symbolic link (" + (in / "gone.json").string() + ": No such file or directory)"},
      {"fifo_c", "a FIFO, not a regular file"},
      {"folder_d", "a directory, not a file"},
      {"loop_e", "a loop of symbolic links"}};
  hgd::writeShape((in / "plain_a.ply").string(), plane);
  for (const auto& [stem, reason] : why) hgd::writeShape((in / (stem + ".ply")).string(), plane);
  fs::create_symlink(in / "gone.json", in / "dangling_b.json");
  ASSERT_EQ(::mkfifo((in / "fifo_c.json").c_str(), 0644), 0);
  fs::create_directory(in / "folder_d.json");
  fs::create_symlink(in / "loop_e2.json", in / "loop_e.json");
  fs::create_symlink(in / "loop_e.json", in / "loop_e2.json");

  // (timeout: a FIFO opened for reading would hang the run)
  const Result r = shell("timeout 60 " + quote(HGD_TOOL) + " " + batch(in, out, "--report " + q(rep)));
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_EQ(countOf(r.out, ": ok "), 1u) << r.out;
  EXPECT_EQ(countOf(r.out, ": FAILED: "), why.size()) << r.out;
  EXPECT_EQ(filesUnder(out), std::vector<std::string>{"plain_a.ply"});
  const auto j = nlohmann::json::parse(slurp(rep / "summary.json"));
  std::map<std::string, nlohmann::json> by_file;
  for (const auto& s : j.at("scans")) by_file[s.at("file").get<std::string>()] = s;
  EXPECT_EQ(by_file["plain_a.ply"].at("status"), "ok");
  EXPECT_EQ(by_file["plain_a.ply"].at("own_scenario"), false);
  for (const auto& [stem, reason] : why) {
    const std::string scan = stem + ".ply", own = (in / (stem + ".json")).string();
    const std::string message = own + ": cannot read the scan's own scenario: " + reason;
    EXPECT_TRUE(contains(r.err, scan + ": " + message)) << scan << ": " << r.err;
    ASSERT_TRUE(by_file.count(scan)) << scan;
    EXPECT_EQ(by_file[scan].at("status"), "failed") << scan;
    EXPECT_EQ(by_file[scan].at("own_scenario"), true) << scan;
    EXPECT_TRUE(contains(by_file[scan].at("error").get<std::string>(), message)) << scan;
  }
}

// Issue 28: an entry whose path is longer than the system allows (PATH_MAX) was skipped as "a
// special file". The warning says what is wrong with it.
TEST(Batch, PathLongerThanTheSystemAllowsIsSaidSo) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out";
  fs::create_directories(in);
  writeText((in / "scenario.json").string(), kScenario);
  hgd::writeShape((in / "plain_a.ply").string(), hgd::shapes::bumpyPlane(2, 0.08f, 0.025f));
  // Folders nested to just under PATH_MAX, then a scan whose name takes its path beyond it
  // (created relative to its folder: its whole path cannot be opened).
  fs::path deep = in;
  const std::string part(200, 'd');
  while (deep.native().size() + part.size() + 1 < PATH_MAX - 100) deep /= part;
  fs::create_directories(deep);
  const std::string name = std::string(240, 's') + ".ply";
  ASSERT_GT((deep / name).native().size(), static_cast<std::size_t>(PATH_MAX));
  const int dfd = ::open(deep.c_str(), O_RDONLY | O_DIRECTORY);
  ASSERT_GE(dfd, 0);
  const int fd = ::openat(dfd, name.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
  ASSERT_GE(fd, 0);
  EXPECT_EQ(::write(fd, "ply\n", 4), 4);
  ::close(fd);
  ::close(dfd);

  const Result r = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_EQ(countOf(r.out, ": ok "), 1u) << r.out;
  EXPECT_TRUE(contains(r.err, name + ": its path is longer than the system allows")) << r.err;
  EXPECT_TRUE(contains(r.err, "File name too long")) << r.err;
  EXPECT_FALSE(contains(r.err, "special file")) << r.err;
  // The TempDir cannot remove what it cannot name: the scan goes first, by its folder.
  const int dfd2 = ::open(deep.c_str(), O_RDONLY | O_DIRECTORY);
  ASSERT_GE(dfd2, 0);
  EXPECT_EQ(::unlinkat(dfd2, name.c_str(), 0), 0);
  ::close(dfd2);
}

// The issue: the summary line named a report that could not be written.
TEST(Batch, SummaryLineSaysTheReportFailed) {
  TempDir dir;
  const fs::path in = dir.path() / "in", rep = dir.path() / "report";
  makeScans(in, false);
  fs::create_directories(rep / "index.html");  // cannot be replaced by a file
  const Result r = cli(batch(in, dir.path() / "out", "--report " + q(rep)));
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_TRUE(contains(r.err, "hgdeform batch: report: ")) << r.err;
  EXPECT_FALSE(contains(r.out, "; report " + (rep / "index.html").string())) << r.out;
  EXPECT_TRUE(contains(r.out, "; report FAILED: " + rep.string())) << r.out;
  fs::remove(rep / "index.html");
  const Result ok = cli(batch(in, dir.path() / "out", "--report " + q(rep)));
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_TRUE(contains(ok.out, "; report " + (rep / "index.html").string())) << ok.out;
}

// The report's files are outputs like every other (the issue: with the scenario at
// DIR/summary.json, --report DIR replaced it and the batch exited 0): one that names an input
// (the default scenario, a scan's own scenario, a scan; also through a link) is refused before
// any scan is deformed: exit 1, an error naming both, every input intact, no output.
TEST(Batch, ReportFilesNeverReplaceAnInput) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out", rep = dir.path() / "rep";
  makeScans(in, false);
  fs::create_directories(rep / "thumbs");
  const auto inputs = treeHashes(in);
  // The scenario itself in the report folder, under the name of the summary.
  fs::copy_file(in / "scenario.json", rep / "summary.json");
  const std::string scenario = slurp(rep / "summary.json");
  Result r =
      cli("batch -s " + q(rep / "summary.json") + " " + q(in) + " -o " + q(out) + " --report " + q(rep));
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_TRUE(contains(r.err, (rep / "summary.json").string() + ": refusing to overwrite the input"))
      << r.err;
  EXPECT_EQ(slurp(rep / "summary.json"), scenario);
  fs::remove(rep / "summary.json");
  // Links in the report folder to a scan, to a scan's own scenario, to the default scenario.
  const std::vector<std::pair<std::string, fs::path>> links = {
      {"summary.csv", in / "bar_a.ply"},
      {"index.html", in / "own_f.json"},
      {"thumbs/plane_c.ply.png", in / "scenario.json"}};
  for (const auto& [name, target] : links) {
    SCOPED_TRACE(name);
    fs::create_symlink(target, rep / name);
    r = cli(batch(in, out, "--report " + q(rep)));
    EXPECT_EQ(r.code, 1) << r.out << r.err;
    EXPECT_TRUE(
        contains(r.err, (rep / name).string() + ": refusing to overwrite the input " + target.string()))
        << r.err;
    EXPECT_TRUE(fs::is_symlink(rep / name));
    fs::remove(rep / name);
  }
  EXPECT_EQ(treeHashes(in), inputs) << "an input was replaced";
  if (fs::exists(out)) {
    EXPECT_EQ(filesUnder(out), std::vector<std::string>{});
  }
  EXPECT_EQ(filesUnder(rep), std::vector<std::string>{});
}

// A scan's output that names an input (a link in OUTPUT_DIR to another scan or to the
// scenario) fails that scan with the error of every tool; the input stays, the rest go on.
TEST(Batch, OutputsNeverReplaceAnInput) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out";
  const Folder f = makeScans(in, false);
  const auto inputs = treeHashes(in);
  fs::create_directories(out);
  fs::create_symlink(in / "plane_c.ply", out / "bar_a.ply");
  fs::create_symlink(in / "scenario.json", out / "plane_b.pcd");
  const Result r = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_TRUE(contains(r.err, (out / "bar_a.ply").string() + ": refusing to overwrite the input " +
                                  (in / "plane_c.ply").string()))
      << r.err;
  EXPECT_TRUE(contains(r.err, (out / "plane_b.pcd").string() + ": refusing to overwrite the input " +
                                  (in / "scenario.json").string()))
      << r.err;
  EXPECT_EQ(countOf(r.out, ": ok "), f.good.size() - 2) << r.out;
  EXPECT_EQ(treeHashes(in), inputs) << "an input was replaced";
  EXPECT_TRUE(fs::is_symlink(out / "bar_a.ply"));
  EXPECT_TRUE(fs::is_symlink(out / "plane_b.pcd"));
}

TEST(Batch, RemovesStaleTemporaryFiles) {
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out";
  makeScans(in, false);
  fs::create_directories(out / "sub");
  const auto old = fs::file_time_type::clock::now() - std::chrono::hours(2);
  // Left by a killed process (no such pid), an hour old: removed.
  const std::vector<std::string> stale = {".plane_b.pcd.tmp-99999999-0123456789abcdef",
                                          "sub/.plane_e.pcd.tmp-99999998-00ff00ff00ff00ff"};
  // Not ours, or a live writer (this process), or written a moment ago: kept.
  const std::vector<std::string> kept = {"notes.tmp-1-2", ".plane_c.ply.tmp-x-12",
                                         "plane_c.ply.tmp-99999999-ab",
                                         ".bar_a.ply.tmp-" + std::to_string(::getpid()) + "-0123456789abcdef",
                                         ".mesh_d.obj.tmp-99999997-0123456789abcdef"};
  for (const auto& name : stale) writeText((out / name).string(), "partial");
  for (const auto& name : kept) writeText((out / name).string(), "keep");
  for (const auto& name : stale) fs::last_write_time(out / name, old);
  for (std::size_t i = 0; i + 1 < kept.size(); ++i) fs::last_write_time(out / kept[i], old);
  const Result r = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(r.code, 0) << r.err;
  for (const auto& name : stale) EXPECT_FALSE(fs::exists(out / name)) << name;
  for (const auto& name : kept) EXPECT_TRUE(fs::exists(out / name)) << name;
}

// --- interrupted runs ------------------------------------------------------------------------

class BatchInterrupt : public ::testing::TestWithParam<int> {};

TEST_P(BatchInterrupt, LeavesNoPartialFileAndResumes) {
  const int sig = GetParam();
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out";
  fs::create_directories(in);
  writeText((in / "scenario.json").string(), kScenario);
  const int n = 12;
  const hgd::Shape plane = hgd::shapes::bumpyPlane(4, 0.06f, 1.0f / 244);  // 60k points
  for (int i = 0; i < n; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "scan_%02d.%s", i, i % 2 ? "pcd" : "ply");
    hgd::writeShape((in / name).string(), plane);
  }
  const std::string log = dir.file("log.txt");
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::signal(sig, SIG_DFL);  // not ignored, whatever this test was started under (nohup, ...)
    const std::string scenario = (in / "scenario.json").string(), a = in.string(), b = out.string();
    ::execl(HGD_TOOL, HGD_TOOL, "batch", "-s", scenario.c_str(), a.c_str(), "-o", b.c_str(), "--jobs", "1",
            static_cast<char*>(nullptr));
    ::_exit(127);
  }
  // Wait for the first output, then interrupt.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  auto outputs = [&] {
    std::vector<fs::path> v;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(out, ec))
      if (e.path().filename().string()[0] != '.') v.push_back(e.path());
    return v;
  };
  while (outputs().empty() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_FALSE(outputs().empty()) << slurp(log);
  ::kill(pid, sig);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  // Ended by the signal itself (a shell shows 130 / 143), not by an exit status of its own.
  ASSERT_TRUE(WIFSIGNALED(status)) << slurp(log);
  EXPECT_EQ(WTERMSIG(status), sig) << slurp(log);

  // No temporary file, no partial output: whatever is there reads back whole.
  for (const auto& name : filesUnder(out, true)) EXPECT_FALSE(contains(name, ".tmp-")) << name;
  const auto done = outputs();
  EXPECT_LT(done.size(), static_cast<std::size_t>(n)) << "the batch finished before the signal";
  for (const auto& p : done) {
    const hgd::Shape s = hgd::readShape(p.string());
    EXPECT_EQ(s.size(), plane.size()) << p;
  }

  // A rerun completes the rest and keeps what was done (an output whose record the signal
  // prevented, if any, is redone as "no record").
  const Result r = cli(batch(in, out, "--jobs 2"));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(countOf(r.out, ": skipped (up to date)") + countOf(r.out, "(no record)"), done.size()) << r.out;
  EXPECT_LE(countOf(r.out, "(no record)"), 1u) << r.out;
  EXPECT_EQ(outputs().size(), static_cast<std::size_t>(n));
  for (const auto& name : filesUnder(out, true)) EXPECT_FALSE(contains(name, ".tmp-")) << name;
}

INSTANTIATE_TEST_SUITE_P(Signals, BatchInterrupt, ::testing::Values(SIGINT, SIGTERM, SIGHUP, SIGPIPE),
                         [](const ::testing::TestParamInfo<int>& p) {
                           return std::string(p.param == SIGINT    ? "SIGINT"
                                              : p.param == SIGTERM ? "SIGTERM"
                                              : p.param == SIGHUP  ? "SIGHUP"
                                                                   : "SIGPIPE");
                         });

// --- shards and MPI --------------------------------------------------------------------------

TEST(Batch, ShardsTogetherEqualOneRun) {
  const Reference& ref = reference();
  TempDir dir;
  const fs::path single = dir.path() / "single", sharded = dir.path() / "sharded";
  const Result r = cli(batch(ref.in, single, "--recursive"));
  EXPECT_EQ(r.code, 1);
  // The three shards at once, into one directory, as a job array would run them.
  std::string command;
  for (int k = 0; k < 3; ++k)
    command += quote(HGD_TOOL) + " " +
               batch(ref.in, sharded, "--recursive --shard " + std::to_string(k) + "/3") + " > " +
               quote(dir.file("shard" + std::to_string(k) + ".txt")) + " 2>&1 & ";
  command += "wait";
  shell(command);
  EXPECT_EQ(treeHashes(sharded), treeHashes(single));
  // Each scan in exactly one shard: scan i of the sorted list in shard i % 3.
  std::vector<std::string> all = ref.folder.good;
  all.insert(all.end(), ref.folder.bad.begin(), ref.folder.bad.end());
  std::sort(all.begin(), all.end());
  for (std::size_t i = 0; i < all.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const std::string text = slurp(dir.file("shard" + std::to_string(k) + ".txt"));
      EXPECT_EQ(contains(text, "] " + all[i] + ": "), static_cast<int>(i % 3) == k)
          << all[i] << " shard " << k;
    }
}

#ifdef HGD_HAVE_MPI
TEST(BatchMpi, RanksShareTheScans) {
  if (shell("command -v mpirun").code != 0) GTEST_SKIP() << "mpirun is not on PATH";
  const Reference& ref = reference();
  TempDir dir;
  const fs::path single = dir.path() / "single", mpi = dir.path() / "mpi", rep = dir.path() / "report";
  EXPECT_EQ(cli(batch(ref.in, single, "--recursive")).code, 1);
  const std::string mpirun = "mpirun --allow-run-as-root --oversubscribe -np 3 ";
  const Result r =
      shell(mpirun + quote(HGD_TOOL) + " " + batch(ref.in, mpi, "--recursive --report " + q(rep)));
  EXPECT_NE(r.code, 0) << r.out << r.err;  // two scans fail
  EXPECT_EQ(treeHashes(mpi), treeHashes(single));
  const std::size_t total = ref.folder.good.size() + ref.folder.bad.size();
  const auto j = nlohmann::json::parse(slurp(rep / "summary.json"));
  ASSERT_EQ(j.at("scans").size(), total);
  EXPECT_EQ(j.at("totals").at("ranks"), 3);
  EXPECT_EQ(j.at("totals").at("failed"), 2);
  std::set<std::string> files;
  for (const auto& s : j.at("scans")) files.insert(s.at("file").get<std::string>());
  EXPECT_EQ(files.size(), total);
  EXPECT_EQ(countOf(r.out, "hgdeform batch: "), 1u) << r.out;  // one summary, from rank 0
  EXPECT_EQ(countOf(r.out, "[rank "), total) << r.out;

  // All good: every rank exits 0.
  TempDir good;
  makeScans(good.path() / "in", false);
  const Result r2 =
      shell(mpirun + quote(HGD_TOOL) + " " + batch(good.path() / "in", good.path() / "out", "-q"));
  EXPECT_EQ(r2.code, 0) << r2.out << r2.err;
  EXPECT_EQ(filesUnder(good.path() / "out").size(), 6u);
}
#endif

// --- thumbnails (batch_thumbnails_xvfb runs this under xvfb-run) -----------------------------

TEST(BatchThumbnails, PicturesWhenThereIsADisplay) {
  TempDir dir;
  const fs::path in = dir.path() / "in", rep = dir.path() / "report";
  const Folder f = makeScans(in, false);
  const Result r = cli(batch(in, dir.path() / "out", "--recursive -q --report " + q(rep)));
  EXPECT_EQ(r.code, 0) << r.err;
  const std::string html = slurp(rep / "index.html");
  for (const auto& rel : f.good) EXPECT_TRUE(contains(html, rel)) << rel;
#ifdef HGD_HAVE_RENDER
  if (haveDisplay()) {
    for (const auto& rel : f.good) {
      const fs::path png = rep / "thumbs" / (rel + ".png");
      EXPECT_TRUE(fs::exists(png) && fs::file_size(png) > 0) << png;
      EXPECT_TRUE(contains(html, "<img src=\"thumbs/" + rel + ".png\"")) << rel;
    }
    // Up-to-date scans keep their pictures.
    fs::remove(rep / "thumbs" / "plane_b.pcd.png");
    const Result again = cli(batch(in, dir.path() / "out", "--recursive -q --report " + q(rep)));
    EXPECT_EQ(again.code, 0) << again.err;
    EXPECT_TRUE(fs::exists(rep / "thumbs" / "plane_b.pcd.png"));
    EXPECT_TRUE(contains(slurp(rep / "index.html"), "thumbs/plane_b.pcd.png"));
    return;
  }
#endif
  EXPECT_TRUE(contains(html, "No thumbnails")) << html;
}

}  // namespace
