// End-to-end tests of `hgdeform batch`: folders of generated scans in fresh temporary
// directories, the real executable (HGD_TOOL) run on them, outputs read back with the library
// and compared with what `hgdeform deform` writes for each scan.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "hgdeform/fields.h"
#include "hgdeform/geometry.h"
#include "hgdeform/io.h"
#include "hgdeform/shapes.h"
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

/// Relative path -> FNV hash of every file under `dir`.
std::map<std::string, std::uint64_t> treeHashes(const fs::path& dir) {
  std::map<std::string, std::uint64_t> m;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) m[e.path().lexically_relative(dir).generic_string()] = fnv(e.path());
  return m;
}

/// Relative path -> modification time of every file under `dir`.
std::map<std::string, fs::file_time_type> treeTimes(const fs::path& dir) {
  std::map<std::string, fs::file_time_type> m;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) m[e.path().lexically_relative(dir).generic_string()] = e.last_write_time();
  return m;
}

std::vector<std::string> filesUnder(const fs::path& dir) {
  std::vector<std::string> v;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) v.push_back(e.path().lexically_relative(dir).generic_string());
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

// DISPLAY names an X server that is not there (VTK would abort the process): every scan is
// still deformed and summarised; the thumbnails are skipped with a note that says why.
TEST(Batch, AbsentXServerSkipsThumbnailsOnly) {
  const Reference& ref = reference();
  TempDir dir;
  const fs::path out = dir.path() / "out", rep = dir.path() / "report";
  const Result r =
      shell("DISPLAY=:4711 " + quote(HGD_TOOL) + " " + batch(ref.in, out, "--recursive --report " + q(rep)));
  EXPECT_EQ(r.code, 1) << r.out << r.err;  // the folder's two bad scans
  for (const auto& rel : ref.folder.good) EXPECT_TRUE(fs::exists(out / rel)) << rel;
  const auto j = nlohmann::json::parse(slurp(rep / "summary.json"));
  EXPECT_EQ(j.at("scans").size(), ref.folder.good.size() + ref.folder.bad.size());
  EXPECT_TRUE(fs::exists(rep / "summary.csv"));
  const std::string html = slurp(rep / "index.html");
  EXPECT_TRUE(contains(html, "cannot open the X display")) << html;
  EXPECT_FALSE(contains(html, "<img")) << html;
}

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
      "ms_build", "ms_field", "ms_sampling", "ms_clusters", "ms_solve", "ms_interpolation", "ms_total"};
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

  // A newer input: only that one again.
  fs::last_write_time(in / "plane_c.ply", fs::file_time_type::clock::now());
  const Result r3 = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(r3.code, 0) << r3.err;
  EXPECT_EQ(countOf(r3.out, ": ok "), 1u) << r3.out;
  EXPECT_TRUE(contains(r3.out, "plane_c.ply: ok ")) << r3.out;
  auto t3 = treeTimes(out);
  for (const auto& [rel, t] : t1) {
    if (rel == "plane_c.ply")
      EXPECT_GT(t3[rel], t) << rel;
    else
      EXPECT_EQ(t3[rel], t) << rel;
  }

  // A newer own scenario: that scan again.
  fs::last_write_time(in / "own_f.json", fs::file_time_type::clock::now());
  const Result r4 = cli(batch(in, out, "--recursive"));
  EXPECT_EQ(countOf(r4.out, ": ok "), 1u) << r4.out;
  EXPECT_TRUE(contains(r4.out, "own_f.pcd: ok ")) << r4.out;

  // --force: everything.
  const auto t4 = treeTimes(out);
  const Result r5 = cli(batch(in, out, "--recursive --force"));
  EXPECT_EQ(r5.code, 0) << r5.err;
  EXPECT_EQ(countOf(r5.out, ": ok "), n) << r5.out;
  const auto t5 = treeTimes(out);
  for (const auto& [rel, t] : t4) EXPECT_GT(t5.at(rel), t) << rel;
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
  ASSERT_TRUE(WIFEXITED(status)) << slurp(log);
  EXPECT_EQ(WEXITSTATUS(status), sig == SIGINT ? 130 : 143) << slurp(log);

  // No temporary file, no partial output: whatever is there reads back whole.
  for (const auto& name : filesUnder(out)) EXPECT_FALSE(contains(name, ".tmp-")) << name;
  const auto done = outputs();
  EXPECT_LT(done.size(), static_cast<std::size_t>(n)) << "the batch finished before the signal";
  for (const auto& p : done) {
    const hgd::Shape s = hgd::readShape(p.string());
    EXPECT_EQ(s.size(), plane.size()) << p;
  }

  // A rerun completes the rest and keeps what was done.
  const Result r = cli(batch(in, out, "--jobs 2"));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(countOf(r.out, ": skipped (up to date)"), done.size()) << r.out;
  EXPECT_EQ(outputs().size(), static_cast<std::size_t>(n));
  for (const auto& name : filesUnder(out)) EXPECT_FALSE(contains(name, ".tmp-")) << name;
}

INSTANTIATE_TEST_SUITE_P(Signals, BatchInterrupt, ::testing::Values(SIGINT, SIGTERM),
                         [](const ::testing::TestParamInfo<int>& p) {
                           return std::string(p.param == SIGINT ? "SIGINT" : "SIGTERM");
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
