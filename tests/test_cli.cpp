// End-to-end tests of the `hgdeform` command-line tool: the real executable (HGD_TOOL) is run
// on files written into fresh temporary directories, and its outputs are read back with the
// library.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "hgdeform/version.h"
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

/// Runs `hgdeform ARGS` with stdout and stderr captured separately.
Result cli(const std::string& args) {
  return shell(quote(HGD_TOOL) + " " + args);
}

std::set<std::string> listing(const TempDir& dir) {
  const std::vector<std::string> v = dir.list();
  return {v.begin(), v.end()};
}

double value(const hgd::Shape& s, std::size_t point, const std::string& name, std::size_t element = 0) {
  const int i = hgd::findField(s.cloud, name);
  if (i < 0) {
    ADD_FAILURE() << "no field " << name;
    return std::numeric_limits<double>::quiet_NaN();
  }
  return hgd::readValue(s.cloud, point, s.cloud.fields[static_cast<std::size_t>(i)], element);
}

Eigen::Vector3d position(const hgd::Shape& s, std::size_t i) {
  return {value(s, i, "x"), value(s, i, "y"), value(s, i, "z")};
}

double diagonal(const hgd::Shape& s) {
  return hgd::boundingBoxDiagonal(hgd::extractGeometry(s));
}

bool sameValue(double a, double b) {
  return (std::isnan(a) && std::isnan(b)) || a == b;
}

/// Every field of `in` is in `out` with the same type, count and values (NaN == NaN).
void expectFieldsKept(const hgd::Shape& in, const hgd::Shape& out) {
  ASSERT_EQ(in.size(), out.size());
  for (const auto& f : in.cloud.fields) {
    const int k = hgd::findField(out.cloud, f.name);
    ASSERT_GE(k, 0) << "field " << f.name << " lost";
    const auto& g = out.cloud.fields[static_cast<std::size_t>(k)];
    EXPECT_EQ(f.datatype, g.datatype) << f.name;
    EXPECT_EQ(f.count, g.count) << f.name;
    int bad = 0;
    for (std::size_t i = 0; i < in.size(); ++i)
      for (std::size_t e = 0; e < std::max<std::uint32_t>(f.count, 1); ++e) {
        const double a = hgd::readValue(in.cloud, i, f, e), b = hgd::readValue(out.cloud, i, g, e);
        if (!sameValue(a, b) && ++bad <= 5)
          ADD_FAILURE() << "field " << f.name << " point " << i << ": " << a << " became " << b;
      }
  }
}

const std::string kBarScenario = R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.045, 1, 1] } } ],
  "manipulated": { "box": { "min": [0.955, -1, -1], "max": [2, 1, 1] } }
})";

std::string bunnyPath() {
  return hgdtest::datasetsDir() + "/bunny_1839.ply";
}
std::string bunnyScenarioPath() {
  return hgdtest::datasetsDir() + "/bunny_ears.json";
}

// --- usage -----------------------------------------------------------------------------------

TEST(Cli, HelpListsCommands) {
  const Result r = cli("--help");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "field")) << r.out;
  EXPECT_TRUE(contains(r.out, "deform")) << r.out;
}

TEST(Cli, FieldHelpListsOptions) {
  const Result r = cli("field --help");
  EXPECT_EQ(r.code, 0) << r.err;
  for (const char* opt : {"--scenario", "--output", "--k", "--solver", "--mesh-ring", "--color", "--ascii",
                          "--quiet", "--help"})
    EXPECT_TRUE(contains(r.out, opt)) << opt << " missing from:\n" << r.out;
}

TEST(Cli, DeformHelpListsOptions) {
  const Result r = cli("deform --help");
  EXPECT_EQ(r.code, 0) << r.err;
  for (const char* opt : {"--scenario", "--output", "--report", "--clusters", "--k", "--samples",
                          "--reweight", "--solver", "--ascii", "--quiet", "--help"})
    EXPECT_TRUE(contains(r.out, opt)) << opt << " missing from:\n" << r.out;
}

TEST(Cli, VersionOnEveryCommand) {
  EXPECT_EQ(hgd::version(), std::string(HGDEFORM_VERSION));
  for (const std::string cmd : {"", "field ", "deform ", "batch "}) {
    const Result r = cli(cmd + "--version");
    EXPECT_EQ(r.code, 0) << cmd << r.err;
    EXPECT_EQ(r.out, "hgdeform " + cmd + HGDEFORM_VERSION + "\n") << cmd;
  }
}

TEST(Cli, NoArgumentsIsUsageError) {
  const Result r = cli("");
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(contains(r.err, "usage")) << r.err;
}

TEST(Cli, UnknownCommandIsUsageError) {
  const Result r = cli("frobnicate x.ply");
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(contains(r.err, "frobnicate")) << r.err;
}

TEST(Cli, UnknownOptionIsUsageError) {
  for (const char* cmd : {"field", "deform"}) {
    const Result r = cli(std::string(cmd) + " in.ply -s s.json -o out.ply --bogus-option");
    EXPECT_EQ(r.code, 2) << cmd;
    EXPECT_TRUE(contains(r.err, "--bogus-option")) << cmd << ": " << r.err;
  }
}

TEST(Cli, MissingRequiredOptionIsUsageError) {
  TempDir dir;
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar());
  const Result r = cli("deform " + quote(dir.file("bar.ply")) + " -o " + quote(dir.file("out.ply")));
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(contains(r.err, "--scenario")) << r.err;
  EXPECT_FALSE(hgdtest::exists(dir.file("out.ply")));
}

// --- field -----------------------------------------------------------------------------------

class CliField : public ::testing::TestWithParam<std::string> {};

TEST_P(CliField, WritesHarmonicFieldAndKeepsFields) {
  const std::string ext = GetParam();
  TempDir dir;
  const std::string input = dir.file("bar." + ext), output = dir.file("field." + ext),
                    coloured = dir.file("coloured." + ext), scenario = dir.file("s.json");
  hgd::writeShape(input, hgd::shapes::bar());
  writeText(scenario, kBarScenario);

  const Result r = cli("field " + quote(input) + " --scenario " + quote(scenario) + " -o " + quote(output));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "points")) << r.out;
  EXPECT_TRUE(contains(r.out, "ms")) << r.out;
  ASSERT_TRUE(hgdtest::exists(output));

  const hgd::Shape in = hgd::readShape(input);
  const hgd::Shape out = hgd::readShape(output);
  ASSERT_EQ(out.size(), in.size());
  const int hf = hgd::findField(out.cloud, "harmonic");
  ASSERT_GE(hf, 0) << "no 'harmonic' field";
  EXPECT_EQ(out.cloud.fields[static_cast<std::size_t>(hf)].datatype, pcl::PCLPointField::FLOAT32);
  EXPECT_EQ(out.cloud.fields[static_cast<std::size_t>(hf)].count, 1u);
  std::size_t fixed = 0, manipulated = 0;
  bool inside = false;
  for (std::size_t i = 0; i < out.size(); ++i) {
    const double phi = value(out, i, "harmonic");
    const double x = value(in, i, "x");
    EXPECT_TRUE(phi >= 0 && phi <= 1) << "point " << i << ": " << phi;
    if (x < 0.045) {
      EXPECT_EQ(phi, 0.0) << "fixed point " << i;
      ++fixed;
    } else if (x > 0.955) {
      EXPECT_EQ(phi, 1.0) << "manipulated point " << i;
      ++manipulated;
    } else if (phi > 0.2 && phi < 0.8) {
      inside = true;
    }
  }
  EXPECT_GT(fixed, 0u);
  EXPECT_GT(manipulated, 0u);
  EXPECT_TRUE(inside) << "the field does not vary between the handles";
  expectFieldsKept(in, out);

  // --color adds a colour map.
  const Result rc =
      cli("field " + quote(input) + " -s " + quote(scenario) + " --color -q -o " + quote(coloured));
  ASSERT_EQ(rc.code, 0) << rc.err;
  EXPECT_TRUE(rc.out.empty()) << "--quiet printed: " << rc.out;
  const hgd::Shape col = hgd::readShape(coloured);
  const bool rgb = hgd::findField(col.cloud, "rgb") >= 0;
  const bool channels = hgd::findField(col.cloud, "red") >= 0 && hgd::findField(col.cloud, "green") >= 0 &&
                        hgd::findField(col.cloud, "blue") >= 0;
  EXPECT_TRUE(rgb || channels) << "no colour fields in " << coloured;
  EXPECT_FALSE(hgd::findField(in.cloud, "rgb") >= 0 || hgd::findField(in.cloud, "red") >= 0);
  EXPECT_GE(hgd::findField(col.cloud, "harmonic"), 0);
  expectFieldsKept(in, col);
}

INSTANTIATE_TEST_SUITE_P(Cli, CliField, ::testing::Values("ply", "pcd"));

// Issue 28: `field` replaced a 'harmonic' field the input already had, and with --color its
// colours, without a word. Both are said (stderr), and done.
TEST(CliFieldReplaces, ExistingFieldAndColoursAreSaid) {
  TempDir dir;
  const std::string input = dir.file("bar.ply"), scenario = dir.file("s.json");
  hgd::writeShape(input, hgd::shapes::bar());
  writeText(scenario, kBarScenario);
  auto field = [&](const std::string& in, const std::string& out, const std::string& extra) {
    const Result r = cli("field " + quote(in) + " -s " + quote(scenario) + " -q -o " + quote(out) + extra);
    EXPECT_EQ(r.code, 0) << r.err;
    return r.err;
  };
  // A fresh input: nothing replaced, nothing said.
  const std::string once = dir.file("once.ply"), coloured = dir.file("coloured.ply");
  EXPECT_FALSE(contains(field(input, once, ""), "replaced"));
  // Its output again: the field is replaced.
  std::string err = field(once, dir.file("twice.ply"), "");
  EXPECT_TRUE(contains(
      err, "hgdeform: warning: " + once + ": its field 'harmonic' is replaced in " + dir.file("twice.ply")))
      << err;
  EXPECT_FALSE(contains(err, "colours")) << err;
  // With --color on a shape without colours: the field only.
  err = field(once, coloured, " --color");
  EXPECT_TRUE(contains(err, "its field 'harmonic' is replaced")) << err;
  EXPECT_FALSE(contains(err, "colours")) << err;
  // With --color on a coloured shape: the colours too.
  ASSERT_GE(hgd::findField(hgd::readShape(coloured).cloud, "red"), 0);
  err = field(coloured, dir.file("recoloured.ply"), " --color");
  EXPECT_TRUE(contains(err, coloured + ": its colours (red/green/blue) are replaced in ")) << err;
  // PCD: the packed rgb.
  const std::string plain_pcd = dir.file("bar.pcd"), pcd = dir.file("coloured.pcd");
  hgd::writeShape(plain_pcd, hgd::shapes::bar());
  EXPECT_FALSE(contains(field(plain_pcd, pcd, " --color"), "replaced"));
  ASSERT_GE(hgd::findField(hgd::readShape(pcd).cloud, "rgb"), 0);
  err = field(pcd, dir.file("recoloured.pcd"), " --color");
  EXPECT_TRUE(contains(err, pcd + ": its colours (field 'rgb') are replaced in ")) << err;
  EXPECT_TRUE(contains(err, pcd + ": its field 'harmonic' is replaced in ")) << err;
}

namespace {

// Deforms `input` by `scenario` with one thread and with two; the files must be byte-identical.
void expectSameOnOneAndTwoThreads(TempDir& dir, const std::string& input, const std::string& scenario) {
  std::string first;
  for (const int threads : {1, 2}) {
    const std::string out = dir.file("out" + std::to_string(threads) + ".ply");
    const Result r = shell("OMP_NUM_THREADS=" + std::to_string(threads) + " " + quote(HGD_TOOL) + " deform " +
                           quote(input) + " -s " + quote(scenario) + " -q -o " + quote(out));
    ASSERT_EQ(r.code, 0) << r.err;
    const std::string bytes = slurp(out);
    ASSERT_FALSE(bytes.empty());
    if (threads == 1)
      first = bytes;
    else
      EXPECT_TRUE(bytes == first) << "one and two threads gave different outputs";
  }
}

const char* const kSphereScenario = R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ { "box": { "min": [-2, -2, -2], "max": [2, 2, -0.85] } } ],
  "manipulated": { "box": { "min": [0.9, -2, -2], "max": [2, 2, 2] } },
  "move": { "drag": { "from": [1, 0, 0], "to": [1, 0, 0.25] } }
})";

}  // namespace

// The parallel passes (kNN, graph, multigrid sums, clustering) give the same result whatever
// the thread count: a 60k-point sphere (multilevel solve, parallel paths) deformed with one
// thread and with two writes byte-identical files.
TEST(CliDeform, SameResultOnOneAndTwoThreads) {
  TempDir dir;
  const std::string input = dir.file("sphere.ply"), scenario = dir.file("s.json");
  hgd::writeShape(input, hgd::shapes::bumpySphere(60000));
  writeText(scenario, kSphereScenario);
  expectSameOnOneAndTwoThreads(dir, input, scenario);
}

// The same for a mid-sized scan, whose coarse level (a tenth of its points) is small enough
// that the loops over its rows go parallel only from kParallelMinCostly (2,048), and whose
// strays are more than that (their nearest coarse point searched on every thread): 160,000
// points of a noisy sphere in random order, no normals, and 5,000 strays around it.
TEST(CliDeform, SameResultOnOneAndTwoThreadsOnAMidSizedScanWithStrays) {
  TempDir dir;
  std::mt19937 rng(7);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  std::uniform_real_distribution<float> box(-1.6f, 1.6f);
  std::vector<Eigen::Vector3f> points;
  while (points.size() < 160000) {
    const Eigen::Vector3f d(gauss(rng), gauss(rng), gauss(rng));
    if (d.norm() < 1e-3f) continue;
    points.push_back(d.normalized() * (1.0f + 0.003f * gauss(rng)));
  }
  for (int s = 0; s < 5000;) {
    const Eigen::Vector3f p(box(rng), box(rng), box(rng));
    if (p.norm() < 1.2f) continue;
    points.push_back(p);
    ++s;
  }
  std::shuffle(points.begin(), points.end(), rng);
  const std::string input = dir.file("scan.ply"), scenario = dir.file("s.json");
  hgd::writeShape(input, hgd::shapes::cloudShape(points, {}));
  // (The boxes apart: strays lie in the corners too.)
  writeText(scenario, R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ { "box": { "min": [-2, -2, -2], "max": [0.5, 2, -0.85] } } ],
  "manipulated": { "box": { "min": [0.9, -2, -0.8], "max": [2, 2, 2] } },
  "move": { "drag": { "from": [1, 0, 0], "to": [1, 0, 0.25] } }
})");
  {
    // The shape takes the paths meant: a coarse level between 2,048 and 20,000 points, and
    // over 2,048 strays.
    hgd::ScenarioRunner run = hgd::ScenarioRunner::read(input);
    run.setScenario(hgd::readScenario(scenario));
    const hgd::CoarseLevel& coarse = run.deformer().coarseLevel();
    EXPECT_GT(coarse.points.size(), 2048u);
    EXPECT_LT(coarse.points.size(), 20000u);
    EXPECT_GT(coarse.strays.size(), 2048u);
  }
  expectSameOnOneAndTwoThreads(dir, input, scenario);
}

// --- deform ----------------------------------------------------------------------------------

// Large inputs run with glibc's huge-page malloc where the kernel gives huge pages on request
// only: the program restarts itself with glibc.malloc.hugetlb=1 added to GLIBC_TUNABLES, and its
// report says so. A user's own hugetlb setting is kept (0: no restart), another tunable does not
// stop it, a small input does not restart, a restarted program does not restart again (and a
// mark it did not set itself does not stop it), and the bytes written are the same either way.
TEST(CliDeform, LargeInputsRunWithHugePageMallocAndWriteTheSameBytes) {
#ifdef HGD_TEST_ASAN
  GTEST_SKIP() << "AddressSanitizer's allocator replaces glibc's malloc, whose tunable this is";
#endif
  std::string thp;
  std::getline(std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled"), thp);
  const bool on_request = thp.find("[madvise]") != std::string::npos;
  TempDir dir;
  // 720,000 points of a noisy sphere in random order: a float x/y/z PLY over 8 MiB.
  std::mt19937 rng(11);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  std::vector<Eigen::Vector3f> points;
  while (points.size() < 720000) {
    const Eigen::Vector3f d(gauss(rng), gauss(rng), gauss(rng));
    if (d.norm() < 1e-3f) continue;
    points.push_back(d.normalized() * (1.0f + 0.003f * gauss(rng)));
  }
  const std::string big = dir.file("big.ply"), small = dir.file("small.ply"), scenario = dir.file("s.json");
  hgd::writeShape(big, hgd::shapes::cloudShape(points, {}));
  ASSERT_GE(std::filesystem::file_size(big), std::uintmax_t{8} << 20);
  hgd::writeShape(small, hgd::shapes::bumpySphere(20000));
  writeText(scenario, kSphereScenario);
  const auto run = [&](const std::string& env, const std::string& input, const std::string& out) {
    const std::string report = out + ".json";
    const Result r = shell(env + " " + quote(HGD_TOOL) + " deform " + quote(input) + " -s " +
                           quote(scenario) + " -q -o " + quote(out) + " --report " + quote(report));
    EXPECT_EQ(r.code, 0) << r.err;
    return nlohmann::json::parse(slurp(report)).value("huge_page_malloc", false);
  };
  const std::string unset = "env -u GLIBC_TUNABLES";
  EXPECT_EQ(run(unset, big, dir.file("a.ply")), on_request) << thp;
  EXPECT_FALSE(run("GLIBC_TUNABLES=glibc.malloc.hugetlb=0", big, dir.file("b.ply")));
  EXPECT_EQ(run("GLIBC_TUNABLES=glibc.malloc.arena_max=2", big, dir.file("c.ply")), on_request) << thp;
  EXPECT_FALSE(run(unset, small, dir.file("d.ply")));
  // A restarted program (its mark is its own process id, which exec keeps) never restarts
  // again, whatever glibc made of the tunable; a mark from another process does not count.
  EXPECT_FALSE(run("unset GLIBC_TUNABLES; HGDEFORM_HUGE_PAGE_RESTART=$$ exec", big, dir.file("e.ply")));
  EXPECT_EQ(run(unset + " HGDEFORM_HUGE_PAGE_RESTART=1", big, dir.file("f.ply")), on_request) << thp;
  const std::string a = slurp(dir.file("a.ply"));
  EXPECT_FALSE(a.empty());
  EXPECT_TRUE(a == slurp(dir.file("b.ply")) && a == slurp(dir.file("c.ply")) &&
              a == slurp(dir.file("e.ply")));
  // The restart cannot happen (no /proc/self/exe to run again, in a mount namespace whose /proc
  // is an empty directory): the program goes on in its first process and writes the same bytes.
  if (on_request && shell("unshare --mount --fork sh -c 'mount -t tmpfs none /proc' 2>&1").code == 0) {
    const std::string g = dir.file("g.ply");
    EXPECT_FALSE(
        run("unshare --mount --fork sh -c 'mount -t tmpfs none /proc && exec \"$@\"' sh env -u "
            "GLIBC_TUNABLES",
            big, g));
    EXPECT_TRUE(slurp(g) == a) << "the run whose restart failed wrote other bytes";
  }
}

// --reweight is the solver's option (GaussNewtonOptions::reweight_rounds) and nothing else: 0
// (the default) writes what no flag does; 8 rounds with 32 isovalues write what the library
// writes with those options, and something else than the paper's solve; a count outside 0-100
// is a usage error.
TEST(CliDeform, ReweightIsTheSolversOptionAndOnlyWhenAsked) {
  TempDir dir;
  const std::string input = dir.file("sphere.ply"), scenario = dir.file("s.json");
  hgd::writeShape(input, hgd::shapes::bumpySphere(20000));
  writeText(scenario, kSphereScenario);
  const auto run = [&](const std::string& flags, const std::string& name) {
    const std::string out = dir.file(name);
    const Result r = shell(quote(HGD_TOOL) + " deform " + quote(input) + " -s " + quote(scenario) +
                           " -q -o " + quote(out) + flags);
    EXPECT_EQ(r.code, 0) << flags << r.err;
    return slurp(out);
  };
  const std::string plain = run("", "plain.ply");
  EXPECT_TRUE(run(" --reweight 0", "zero.ply") == plain);
  const std::string reweighted = run(" --reweight 8 -c 32", "reweighted.ply");
  EXPECT_FALSE(reweighted == plain);
  EXPECT_FALSE(reweighted == run(" -c 32", "c32.ply"));  // the rounds, not the isovalues alone
  hgd::RunOptions ro;
  ro.clusters = 32;
  ro.deform.gauss_newton.reweight_rounds = 8;
  hgd::ScenarioRunner lib = hgd::ScenarioRunner::read(input, ro);
  lib.setScenario(hgd::readScenario(scenario));
  lib.applyMoves();
  const std::string lib_out = dir.file("library.ply");
  lib.write(lib_out);
  EXPECT_TRUE(slurp(lib_out) == reweighted) << "the CLI's --reweight is not the library's option";
  // A move that moves nothing: rounding is no bending, so no round starts and nothing more is
  // said than without rounds (weights from rounding made the rounds fail to decrease and warn
  // that the shape may not follow the handle).
  const std::string still = dir.file("still.json");
  writeText(still, R"({
  "fixed": [ { "box": { "min": [-2, -2, -2], "max": [2, 2, -0.85] } } ],
  "manipulated": { "box": { "min": [0.9, -2, -2], "max": [2, 2, 2] } },
  "move": { "frame": { "translate": [0, 0, 0] } }
})");
  std::string said[2];
  int iterations[2] = {0, 0};
  for (const int k : {0, 1}) {
    const std::string rep = dir.file("still" + std::to_string(k) + ".json");
    const Result r =
        shell(quote(HGD_TOOL) + " deform " + quote(input) + " -s " + quote(still) + " -q -o " +
              quote(dir.file("still.ply")) + (k == 0 ? "" : " --reweight 100") + " --report " + quote(rep));
    ASSERT_EQ(r.code, 0) << r.err;
    said[k] = r.err;
    iterations[k] = nlohmann::json::parse(slurp(rep))["iterations"].get<int>();
  }
  EXPECT_EQ(said[1], said[0]);
  EXPECT_EQ(iterations[1], iterations[0]);
  for (const char* bad : {" --reweight -1", " --reweight 101", " --reweight x"}) {
    const Result r = shell(quote(HGD_TOOL) + " deform " + quote(input) + " -s " + quote(scenario) +
                           " -q -o " + quote(dir.file("bad.ply")) + bad);
    EXPECT_EQ(r.code, 2) << bad << r.err;
    EXPECT_TRUE(contains(r.err, "--reweight")) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir.file("bad.ply"))) << bad;
  }
}

// Above 131,072 points deform builds on a coarse level and says so in the report; --full-field
// keeps every point in the field. The two outputs agree within a bound (the Multires tests
// bound the difference in detail).
TEST(CliDeform, LargeShapesBuildOnACoarseLevelUnlessAskedNot) {
  TempDir dir;
  const std::string input = dir.file("sphere.ply"), scenario = dir.file("s.json");
  hgd::writeShape(input, hgd::shapes::bumpySphere(520000));
  writeText(scenario, R"({
  "fixed": [ { "box": { "min": [-2, -2, -2], "max": [2, 2, -0.85] } } ],
  "manipulated": { "box": { "min": [0.9, -2, -2], "max": [2, 2, 2] } },
  "move": { "drag": { "from": [1, 0, 0], "to": [1, 0, 0.25] } }
})");
  std::vector<hgd::Shape> outs;
  for (const std::string extra : {"", " --full-field"}) {
    SCOPED_TRACE(extra);
    const std::string out = dir.file("out" + std::to_string(outs.size()) + ".ply"), rep = dir.file("r.json");
    const Result r = shell(quote(HGD_TOOL) + " deform " + quote(input) + " -s " + quote(scenario) +
                           " -q -o " + quote(out) + " --report " + quote(rep) + extra);
    ASSERT_EQ(r.code, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(slurp(rep));
    bool coarse = false;
    for (const auto& note : j["notes"])
      coarse = coarse || contains(note.get<std::string>(), "multi-resolution");
    EXPECT_EQ(coarse, extra.empty()) << j["notes"].dump();
    outs.push_back(hgd::readShape(out));
  }
  // (Geometry orders points along a space-filling curve: compare them in file order.)
  auto inFileOrder = [](const hgd::Shape& shape) {
    const hgd::Geometry g = hgd::extractGeometry(shape);
    std::vector<Eigen::Vector3d> p(g.size());
    for (std::size_t i = 0; i < g.size(); ++i) p[static_cast<std::size_t>(g.raw_index[i])] = g.world(i);
    return p;
  };
  const std::vector<Eigen::Vector3d> a = inFileOrder(outs[0]), b = inFileOrder(outs[1]);
  ASSERT_EQ(a.size(), b.size());
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, (a[i] - b[i]).norm());
  std::printf("520k sphere: coarse vs full outputs differ by at most %.4f (drag 0.25)\n", worst);
  EXPECT_LT(worst, 0.25 * 0.09);  // measured 0.0153, 6.1% of the drag
}

// The report's peak memory is the command's own: run from a process that holds 512 MB more, as
// a benchmark holding its clouds does, the bunny's deform reports far less than its parent's
// resident size (getrusage's ru_maxrss would give at least the parent's: a forked child counts
// the image it was forked from until its exec).
double residentMb() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::strtod(line.c_str() + 6, nullptr) / 1024.0;
  return 0;
}

TEST(CliDeform, ReportsItsOwnPeakMemoryNotItsParents) {
  std::vector<char> ballast(512u << 20);
  for (std::size_t i = 0; i < ballast.size(); i += 4096) ballast[i] = static_cast<char>(i >> 12);  // resident
  const double parent = residentMb();
  TempDir dir;
  const std::string report = dir.file("r.json");
  const Result r = cli("deform " + quote(bunnyPath()) + " --scenario " + quote(bunnyScenarioPath()) + " -o " +
                       quote(dir.file("out.ply")) + " -q --report " + quote(report));
  ASSERT_EQ(r.code, 0) << r.err;
  const double mb = nlohmann::json::parse(slurp(report)).value("peak_rss_mb", 0.0);
  std::printf("bunny deform: peak %.1f MB (parent resident %.0f MB)\n", mb, parent);
  EXPECT_GT(mb, 4.0);               // its libraries and the shape: measured 11-15 MB (270 under ASan)
  EXPECT_LT(mb, parent - 256.0);    // far below the parent's, which holds 512 MB more
  EXPECT_NE(ballast[4096 * 7], 1);  // keeps the ballast alive until here
}

TEST(CliDeform, BunnyMatchesLibraryAndReports) {
  TempDir dir;
  const std::string output = dir.file("bunny_out.ply"), report = dir.file("r.json");
  const Result r = cli("deform " + quote(bunnyPath()) + " --scenario " + quote(bunnyScenarioPath()) + " -o " +
                       quote(output) + " --report " + quote(report));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "bunny_out.ply")) << r.out;

  const hgd::Shape in = hgd::readShape(bunnyPath());
  const hgd::Shape out = hgd::readShape(output);
  ASSERT_EQ(in.size(), 1839u);
  ASSERT_EQ(out.size(), in.size());
  ASSERT_EQ(out.polygons.size(), in.polygons.size());
  for (std::size_t i = 0; i < in.polygons.size(); ++i)
    ASSERT_EQ(out.polygons[i].vertices, in.polygons[i].vertices) << "face " << i;

  // The report.
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(slurp(report))) << slurp(report);
  for (const char* key : {"version", "points", "clusters", "iterations", "energy", "ms"})
    EXPECT_TRUE(j.contains(key)) << key << " missing from " << j.dump();
  EXPECT_EQ(j.value("version", ""), HGDEFORM_VERSION);
  EXPECT_EQ(j.value("points", 0u), 1839u);
  EXPECT_GT(j.value("clusters", 0u), 0u);
  EXPECT_GT(j.value("iterations", 0), 0);
  // The isovalue count asked for (bunny_ears.json: 12), under its 0.2 name and its old one.
  EXPECT_EQ(j.value("isovalues", 0), 12);
  EXPECT_EQ(j.value("isoclusters", 0), 12);
  for (const char* key : {"detail", "prop", "manip", "length"}) {
    ASSERT_TRUE(j["energy"].contains(key)) << "energy." << key;
    EXPECT_TRUE(j["energy"][key].is_number()) << "energy." << key;
  }
  for (const char* key :
       {"build", "field", "sampling", "clusters", "solve", "solve_per_iteration", "interpolation", "total"}) {
    ASSERT_TRUE(j["ms"].contains(key)) << "ms." << key;
    EXPECT_TRUE(j["ms"][key].is_number()) << "ms." << key;
    EXPECT_GE(j["ms"][key].get<double>(), 0.0) << "ms." << key;
  }

  // Same positions as the library gives in-process.
  hgd::Shape lib = hgd::readShape(bunnyPath());
  hgd::deformShape(lib, hgd::readScenario(bunnyScenarioPath()));
  const double diag = diagonal(in);
  double worst = 0, moved = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    worst = std::max(worst, (position(out, i) - position(lib, i)).norm());
    moved = std::max(moved, (position(out, i) - position(in, i)).norm());
  }
  EXPECT_LE(worst, 1e-5 * diag);
  EXPECT_GT(moved, 0.05 * diag) << "the ears did not move";

  // The fixed handle (y < 0.8) did not move.
  std::size_t fixed = 0;
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (!(value(in, i, "y") < 0.8)) continue;
    ++fixed;
    EXPECT_LE((position(out, i) - position(in, i)).norm(), 1e-6 * diag) << "fixed point " << i;
  }
  EXPECT_GT(fixed, 0u);
  EXPECT_EQ(listing(dir), (std::set<std::string>{"bunny_out.ply", "r.json"}));
}

TEST(CliDeform, FrameMoveIsExactOnManipulatedHandle) {
  TempDir dir;
  const std::string input = dir.file("bar.ply"), output = dir.file("out.ply"), scenario = dir.file("s.json");
  hgd::writeShape(input, hgd::shapes::bar());
  writeText(scenario, R"({
    "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.045, 1, 1] } } ],
    "manipulated": { "box": { "min": [0.955, -1, -1], "max": [2, 1, 1] } },
    "clusters": 8,
    "move": { "frame": { "translate": [0.05, 0.2, -0.1], "rotate": { "axis": [0, 0, 1], "degrees": 30 } } }
  })");
  const Result r = cli("deform " + quote(input) + " -s " + quote(scenario) + " -o " + quote(output));
  ASSERT_EQ(r.code, 0) << r.err;
  const hgd::Shape in = hgd::readShape(input);
  const hgd::Shape out = hgd::readShape(output);
  ASSERT_EQ(out.size(), in.size());
  const double diag = diagonal(in);

  std::vector<std::size_t> manip;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < in.size(); ++i)
    if (value(in, i, "x") > 0.955) {
      manip.push_back(i);
      centre += position(in, i);
    }
  ASSERT_FALSE(manip.empty());
  centre /= static_cast<double>(manip.size());
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(30.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d t(0.05, 0.2, -0.1);
  double worst = 0;
  for (std::size_t i : manip) {
    const Eigen::Vector3d expected = R * (position(in, i) - centre) + centre + t;
    worst = std::max(worst, (position(out, i) - expected).norm());
  }
  EXPECT_LE(worst, 1e-5 * diag);
  for (std::size_t i = 0; i < in.size(); ++i)
    if (value(in, i, "x") < 0.045) {
      EXPECT_LE((position(out, i) - position(in, i)).norm(), 1e-6 * diag) << "fixed point " << i;
    }
}

// A bar whose fixed and manipulated handles touch at x = 0.5, the manipulated half lifted by
// 0.3: the surface has to come apart along x = 0.5. Beside it, a box no handle reaches. The
// deform says both on stderr and in the report (surface.split_points, surface.max_stretch,
// pieces, warnings), and exits 0: the result is what was asked for, but a user must not find
// the split or the object left behind by looking first.
TEST(CliDeform, SurfacePulledApartAndObjectLeftAreSaid) {
  TempDir dir;
  const std::string input = dir.file("bar.ply"), output = dir.file("out.ply"), scenario = dir.file("s.json"),
                    report = dir.file("r.json");
  hgd::writeShape(input, hgd::shapes::barBesideABox());
  writeText(scenario, R"({
    "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.5, 0.3, 1] } } ],
    "manipulated": { "box": { "min": [0.5001, -1, -1], "max": [2, 0.3, 1] } },
    "move": { "frame": { "translate": [0, 0.3, 0] } }
  })");
  const Result r = cli("deform " + quote(input) + " -s " + quote(scenario) + " -o " + quote(output) +
                       " --report " + quote(report));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(slurp(report));
  const std::size_t split = j.at("surface").at("split_points").get<std::size_t>();
  // Every point within a spacing of x = 0.5 has a neighbour across it (the bar's grid has
  // 40 points round each of the two columns there), and no point farther than the graph's
  // reach (10 neighbours: under 3 spacings) has one.
  EXPECT_GE(split, 80u) << r.err;
  EXPECT_LE(split, 6u * 40u) << r.err;
  EXPECT_GT(j.at("surface").at("max_stretch").get<double>(), 10.0);  // 0.01 apart, then ~0.3
  EXPECT_TRUE(contains(r.err, "warning: the surface is pulled apart at " + std::to_string(split) + " points"))
      << r.err;
  bool warned = false;
  for (const auto& w : j.at("warnings")) warned = warned || contains(w.get<std::string>(), "pulled apart");
  EXPECT_TRUE(warned) << j.dump();
  // The box: 2 x (0.3 x 0.2 + 0.3 x 0.1 + 0.2 x 0.1) at spacing 0.01 (counted from the file).
  const hgd::Shape in = hgd::readShape(input);
  std::size_t box = 0;
  for (std::size_t i = 0; i < in.size(); ++i) box += value(in, i, "y") > 0.5;
  EXPECT_EQ(j.at("pieces").at("stayed_points").get<std::size_t>(), box);
  EXPECT_TRUE(contains(
      r.err, "warning: " + std::to_string(box) + " points in 1 piece that touch no handle lie apart"))
      << r.err;
}

// `deform --mesh-ring`: the field's graph is the faces' 1-ring. Its output is the library's
// with that option, and differs from the default graph's (kNN plus mesh edges).
TEST(CliDeform, MeshRingUsesTheFacesOneRing) {
  TempDir dir;
  const std::string input = dir.file("bar.ply"), scenario = dir.file("s.json");
  const hgd::Shape mesh = hgd::shapes::barMesh(1.0f, 0.1f, 0.02f);
  hgd::writeShape(input, mesh);
  writeText(scenario, R"({
    "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.05, 1, 1] } } ],
    "manipulated": { "box": { "min": [0.95, -1, -1], "max": [2, 1, 1] } },
    "move": { "frame": { "translate": [0, 0.2, 0.1], "rotate": { "axis": [0, 0, 1], "degrees": 30 } } }
  })");
  const std::string ring = dir.file("ring.ply"), knn = dir.file("knn.ply");
  const Result a =
      cli("deform " + quote(input) + " -s " + quote(scenario) + " -o " + quote(ring) + " --mesh-ring");
  const Result b = cli("deform " + quote(input) + " -s " + quote(scenario) + " -o " + quote(knn));
  ASSERT_EQ(a.code, 0) << a.err;
  ASSERT_EQ(b.code, 0) << b.err;
  hgd::Shape lib = hgd::readShape(input);
  hgd::DeformOptions opt;
  opt.field.mesh_ring = true;
  hgd::deformShape(lib, hgd::readScenario(scenario), opt);
  const hgd::Shape out_ring = hgd::readShape(ring), out_knn = hgd::readShape(knn);
  double same = 0, apart = 0;
  for (std::size_t i = 0; i < lib.size(); ++i) {
    same = std::max(same, (position(out_ring, i) - position(lib, i)).norm());
    apart = std::max(apart, (position(out_ring, i) - position(out_knn, i)).norm());
  }
  EXPECT_EQ(same, 0.0);
  EXPECT_GT(apart, 1e-4);
}

// An organized PCD (10 x 8, some NaN points): the grid layout and the NaNs survive a deformation.
TEST(CliDeform, OrganizedPcdKeepsLayoutAndNaNs) {
  TempDir dir;
  const std::string input = dir.file("grid.pcd"), output = dir.file("out.pcd"), scenario = dir.file("s.json");
  const std::uint32_t W = 10, H = 8;
  hgd::Shape s;
  s.format = hgd::FileFormat::Pcd;
  s.cloud.width = W;
  s.cloud.height = H;
  s.cloud.is_dense = false;
  for (std::uint32_t k = 0; k < 3; ++k) {
    pcl::PCLPointField f;
    f.name = std::string(1, "xyz"[k]);
    f.offset = 4 * k;
    f.datatype = pcl::PCLPointField::FLOAT32;
    f.count = 1;
    s.cloud.fields.push_back(f);
  }
  s.cloud.point_step = 12;
  s.cloud.row_step = 12 * W;
  s.cloud.data.resize(static_cast<std::size_t>(s.cloud.row_step) * H);
  const std::set<std::size_t> nans = {13, 25, 46, 62, 79};
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (std::uint32_t v = 0; v < H; ++v)
    for (std::uint32_t u = 0; u < W; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * W + u;
      const float x = 0.1f * static_cast<float>(u), y = 0.1f * static_cast<float>(v);
      float p[3] = {x, y, 0.2f * (x - 0.45f) * (x - 0.45f) + 0.1f * (y - 0.35f) * (y - 0.35f)};
      if (nans.count(i)) p[0] = p[1] = p[2] = nan;
      std::memcpy(s.cloud.data.data() + i * 12, p, sizeof p);
    }
  hgd::writeShape(input, s);
  writeText(scenario, R"({
    "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.15, 1, 1] } } ],
    "manipulated": { "box": { "min": [0.75, -1, -1], "max": [2, 1, 1] } },
    "clusters": 4,
    "move": { "drag": { "from": [0.9, 0.4, 0.05], "to": [0.9, 0.4, 0.1] } }
  })");
  const Result r = cli("deform " + quote(input) + " -s " + quote(scenario) + " -o " + quote(output));
  ASSERT_EQ(r.code, 0) << r.err;
  const hgd::Shape in = hgd::readShape(input);
  const hgd::Shape out = hgd::readShape(output);
  EXPECT_EQ(out.cloud.width, W);
  EXPECT_EQ(out.cloud.height, H);
  ASSERT_EQ(out.size(), static_cast<std::size_t>(W) * H);
  double moved = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    const Eigen::Vector3d p = position(out, i);
    if (nans.count(i)) {
      EXPECT_TRUE(std::isnan(p.x()) && std::isnan(p.y()) && std::isnan(p.z())) << "point " << i;
    } else {
      EXPECT_TRUE(p.allFinite()) << "point " << i;
      moved = std::max(moved, (p - position(in, i)).norm());
    }
  }
  EXPECT_GT(moved, 0.02) << "nothing moved";
}

// --- interrupted runs ------------------------------------------------------------------------

/// Starts `hgdeform ARGS` with stdout on `out_fd` (closed here) and stderr into `log`, the
/// signals of the tests at their default action whatever this test was started under.
pid_t startTool(const std::vector<std::string>& args, int out_fd, const std::string& log) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(out_fd, 1);
    ::dup2(fd, 2);
    for (const int s : {SIGINT, SIGTERM, SIGHUP, SIGPIPE}) ::signal(s, SIG_DFL);
    std::vector<char*> argv = {const_cast<char*>(HGD_TOOL)};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(HGD_TOOL, argv.data());
    ::_exit(127);
  }
  if (out_fd > 2) ::close(out_fd);
  return pid;
}

// A plane of about two million points and a scenario that bends it: `deform` spends a good
// part of a second writing it as text, time to be interrupted while it writes.
struct LargePlane {
  TempDir dir;
  std::string input = dir.file("plane.ply"), scenario = dir.file("s.json");
  LargePlane() {
    hgd::writeShape(input, hgd::shapes::bumpyPlane(4, 0.06f, 1.0f / 1400));
    writeText(scenario, R"({
  "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.05, 2, 1] } } ],
  "manipulated": { "box": { "min": [0.95, -1, -1], "max": [2, 2, 1] } },
  "move": { "frame": { "translate": [0, 0, 0.15] } }
})");
  }
};

// Issue 28: SIGINT, SIGTERM (timeout, Slurm), SIGHUP or SIGPIPE while `deform` wrote a large
// output left its temporary file (.o.ply.tmp-PID-HEX) behind. The temporary file goes, and the
// run ends by the signal itself (a shell shows 128 + its number).
class CliInterrupt : public ::testing::TestWithParam<int> {};

TEST_P(CliInterrupt, WhileWritingLeavesNoTemporaryFile) {
  const int sig = GetParam();
  static LargePlane plane;  // made once for the four signals
  TempDir out;
  const std::string output = out.file("o.ply"), log = plane.dir.file("log.txt");
  const int null = ::open("/dev/null", O_WRONLY);
  const pid_t pid =
      startTool({"deform", plane.input, "-s", plane.scenario, "-o", output, "--ascii", "-q"}, null, log);
  ASSERT_GT(pid, 0);
  // Wait for the temporary file, then the signal.
  bool writing = false;
  int status = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!writing && std::chrono::steady_clock::now() < deadline) {
    for (const std::string& name : out.list()) writing = writing || contains(name, ".o.ply.tmp-");
    if (!writing) std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  ASSERT_TRUE(writing) << slurp(log);
  ::kill(pid, sig);
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(status)) << "finished before the signal, or exited " << WEXITSTATUS(status) << ": "
                                   << slurp(log);
  EXPECT_EQ(WTERMSIG(status), sig);
  EXPECT_EQ(out.list(), std::vector<std::string>{}) << "left behind";
}

INSTANTIATE_TEST_SUITE_P(Signals, CliInterrupt,
                         ::testing::Values(SIGINT, SIGTERM, SIGHUP, SIGPIPE, SIGUSR1, SIGALRM),
                         [](const ::testing::TestParamInfo<int>& p) {
                           return std::string(p.param == SIGINT    ? "SIGINT"
                                              : p.param == SIGTERM ? "SIGTERM"
                                              : p.param == SIGHUP  ? "SIGHUP"
                                              : p.param == SIGUSR1 ? "SIGUSR1"
                                              : p.param == SIGALRM ? "SIGALRM"
                                                                   : "SIGPIPE");
                         });

// An output that passes `ulimit -f` ended the run by SIGXFSZ with no message and its temporary
// file left (10 MB of it): the file goes, and the status still says SIGXFSZ.
TEST(CliInterruptXfsz, AnOutputPastTheFileSizeLimitLeavesNoTemporaryFile) {
  static LargePlane plane;
  TempDir out;
  const Result r = shell("ulimit -c 0; ulimit -f 2048; " + quote(HGD_TOOL) + " deform " + quote(plane.input) +
                         " -s " + quote(plane.scenario) + " -o " + quote(out.file("o.ply")) + " --ascii -q");
  EXPECT_EQ(r.code, 128 + SIGXFSZ) << r.err;
  EXPECT_EQ(out.list(), std::vector<std::string>{}) << "left behind";
}

// --- errors ----------------------------------------------------------------------------------

class CliErrors : public ::testing::Test {
 public:
  void SetUp() override {
    bar_ = in_.file("bar.ply");
    scenario_ = in_.file("s.json");
    hgd::writeShape(bar_, hgd::shapes::bar());
    writeText(scenario_, kBarScenario);
  }

  /// Runs `hgdeform CMD INPUT -s SCENARIO -o OUT_DIR/OUTPUT EXTRA` and checks that it fails,
  /// that stderr has every one of `phrases`, and that the output directory stays empty.
  void expectFailure(const std::string& cmd, const std::string& input, const std::string& scenario,
                     std::initializer_list<std::string> phrases, const std::string& extra = "",
                     const std::string& output = "out.ply") {
    const Result r = cli(cmd + " " + quote(input) + " -s " + quote(scenario) + " -o " +
                         quote(out_.file(output)) + " " + extra);
    EXPECT_NE(r.code, 0) << cmd << " succeeded";
    for (const auto& p : phrases)
      EXPECT_TRUE(contains(r.err, p)) << cmd << ": '" << p << "' not in: " << r.err;
    const std::set<std::string> left = listing(out_);
    EXPECT_TRUE(left.empty()) << cmd << " left " << left.size() << " file(s), e.g. " << *left.begin();
  }

  TempDir in_, out_;
  std::string bar_, scenario_;
};

TEST_F(CliErrors, MissingInput) {
  for (const char* cmd : {"field", "deform"})
    expectFailure(cmd, in_.file("nothere.ply"), scenario_, {"nothere.ply", "cannot open"});
}

TEST_F(CliErrors, EmptyInput) {
  writeText(in_.file("empty.ply"), "");
  for (const char* cmd : {"field", "deform"})
    expectFailure(cmd, in_.file("empty.ply"), scenario_, {"empty.ply", "empty"});
}

TEST_F(CliErrors, TruncatedBinaryPly) {
  const std::string bytes = slurp(bar_);
  const std::size_t header = bytes.find("end_header\n");
  ASSERT_NE(header, std::string::npos);
  writeText(in_.file("cut.ply"), bytes.substr(0, header + 11 + (bytes.size() - header - 11) / 2));
  for (const char* cmd : {"field", "deform"})
    expectFailure(cmd, in_.file("cut.ply"), scenario_, {"cut.ply", "truncated"});
}

TEST_F(CliErrors, UnsupportedExtension) {
  // An input is read by its content: one of no format is refused, naming the file.
  writeText(in_.file("cloud.e57"), "ASTM-E57\n");
  for (const char* cmd : {"field", "deform"}) {
    expectFailure(cmd, in_.file("cloud.e57"), scenario_, {"cloud.e57", "matches no format"});
    expectFailure(cmd, bar_, scenario_, {"out.e57", "extension"}, "", "out.e57");
  }
}

TEST_F(CliErrors, MissingScenario) {
  for (const char* cmd : {"field", "deform"})
    expectFailure(cmd, bar_, in_.file("none.json"), {"none.json", "cannot open"});
}

TEST_F(CliErrors, ScenarioInvalidJson) {
  writeText(in_.file("bad.json"), "{ \"fixed\": [ ");
  for (const char* cmd : {"field", "deform"})
    expectFailure(cmd, bar_, in_.file("bad.json"), {"bad.json", "invalid JSON"});
}

TEST_F(CliErrors, ScenarioUnknownKey) {
  writeText(in_.file("typo.json"), R"({
    "fixd": [ { "box": { "min": [-1, -1, -1], "max": [0.045, 1, 1] } } ],
    "manipulated": { "box": { "min": [0.955, -1, -1], "max": [2, 1, 1] } }
  })");
  for (const char* cmd : {"field", "deform"})
    expectFailure(cmd, bar_, in_.file("typo.json"), {"typo.json", "/fixd", "unknown key"});
}

TEST_F(CliErrors, RegionSelectsNoPoint) {
  writeText(in_.file("far.json"), R"({
    "fixed": [ { "sphere": { "center": [50, 50, 50], "radius": 1 } } ],
    "manipulated": { "box": { "min": [0.955, -1, -1], "max": [2, 1, 1] } }
  })");
  for (const char* cmd : {"field", "deform"})
    expectFailure(cmd, bar_, in_.file("far.json"), {"far.json", "/fixed/0", "selects no point"});
}

TEST_F(CliErrors, PointBothFixedAndManipulated) {
  writeText(in_.file("overlap.json"), R"({
    "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.6, 1, 1] } } ],
    "manipulated": { "box": { "min": [0.4, -1, -1], "max": [2, 1, 1] } }
  })");
  for (const char* cmd : {"field", "deform"})
    expectFailure(cmd, bar_, in_.file("overlap.json"), {"overlap.json", "both fixed and manipulated"});
}

TEST_F(CliErrors, ClustersNotANumber) {
  const Result r = cli("deform " + quote(bar_) + " -s " + quote(scenario_) + " -o " +
                       quote(out_.file("o.ply")) + " --clusters abc");
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(contains(r.err, "--clusters")) << r.err;
  EXPECT_TRUE(contains(r.err, "abc")) << r.err;
  EXPECT_TRUE(listing(out_).empty());
}

TEST_F(CliErrors, OutputIsInput) {
  const std::string before = slurp(bar_);
  const std::set<std::string> files = listing(in_);
  // The same file, spelled as given and spelled differently.
  for (const std::string& output : {bar_, (in_.path() / "." / "bar.ply").string()})
    for (const char* cmd : {"field", "deform"}) {
      const Result r =
          cli(std::string(cmd) + " " + quote(bar_) + " -s " + quote(scenario_) + " -o " + quote(output));
      EXPECT_NE(r.code, 0) << cmd << " -o " << output;
      EXPECT_TRUE(contains(r.err, "bar.ply")) << r.err;
      EXPECT_TRUE(contains(r.err, "input")) << r.err;
      EXPECT_EQ(slurp(bar_), before) << cmd << " changed its input";
      EXPECT_EQ(listing(in_), files) << cmd << " left a file beside its input";
    }
}

TEST_F(CliErrors, OutputDirectoryMissing) {
  for (const char* cmd : {"field", "deform"}) {
    expectFailure(cmd, bar_, scenario_, {"nodir/out.ply", "cannot write"}, "", "nodir/out.ply");
    EXPECT_FALSE(fs::exists(out_.path() / "nodir"));
  }
}

TEST_F(CliErrors, ReportIntoMissingDirectory) {
  // The report cannot be written: a failure that names the report, and no output at all (the
  // shape was written first; a failed run takes it back).
  const Result r = cli("deform " + quote(bar_) + " -s " + quote(scenario_) + " -o " +
                       quote(out_.file("o.ply")) + " --report " + quote(out_.file("nodir/r.json")));
  EXPECT_NE(r.code, 0);
  EXPECT_TRUE(contains(r.err, "nodir/r.json")) << r.err;
  EXPECT_TRUE(listing(out_).empty()) << "left " << *listing(out_).begin();
}

// A run that fails after writing its output (its report cannot be written) leaves the file an
// earlier run wrote there as it was, also through a symbolic link, and no file beside it.
TEST_F(CliErrors, AFailedReportLeavesThePreviousOutputAsItWas) {
  const std::string earlier =
      "ply\nformat ascii 1.0\ncomment an earlier run's\nelement vertex 0\nend_header\n";
  writeText(out_.file("o.ply"), earlier);
  writeText(out_.file("target.ply"), earlier + "comment\n");
  fs::create_symlink("target.ply", out_.file("link.ply"));
  for (const char* out : {"o.ply", "link.ply"}) {
    const Result r = cli("deform " + quote(bar_) + " -s " + quote(scenario_) + " -o " +
                         quote(out_.file(out)) + " --report " + quote(out_.file("nodir/r.json")));
    EXPECT_NE(r.code, 0) << out;
    EXPECT_TRUE(contains(r.err, "nodir/r.json")) << r.err;
  }
  EXPECT_EQ(slurp(out_.file("o.ply")), earlier);
  EXPECT_EQ(slurp(out_.file("target.ply")), earlier + "comment\n");
  EXPECT_TRUE(fs::is_symlink(out_.file("link.ply")));
  EXPECT_EQ(listing(out_), (std::set<std::string>{"link.ply", "o.ply", "target.ply"}));
}

// An output's name may take all the 255 bytes a name can have: the temporary file beside it is
// named within that limit (a multibyte character is not cut in two).
TEST_F(CliErrors, OutputNamesUpTo255BytesAreWritten) {
  for (const std::size_t length : {229u, 240u, 255u}) {
    std::string name(length - 4, 'n');
    if (length == 240) name.replace(200, 6, "\xc3\xa9\xc3\xa9\xc3\xa9");  // UTF-8 "ééé"
    name += ".ply";
    ASSERT_EQ(name.size(), length);
    const Result r = cli("deform " + quote(bar_) + " -s " + quote(scenario_) + " -o " +
                         quote(out_.file(name)) + " --report " + quote(out_.file("r.json")));
    EXPECT_EQ(r.code, 0) << length << ": " << r.err;
    EXPECT_EQ(listing(out_), (std::set<std::string>{name, "r.json"})) << length;
    EXPECT_EQ(hgd::readShape(out_.file(name)).size(), hgd::readShape(bar_).size());
    fs::remove(out_.file(name));
    fs::remove(out_.file("r.json"));
  }
}

// No output replaces an input, however it is spelt: through a symbolic link, a hard link or
// "./"; the input stays byte for byte.
TEST_F(CliErrors, NoOutputReplacesAnInput) {
  const std::string before = slurp(bar_), scenario_before = slurp(scenario_);
  fs::create_symlink(bar_, in_.file("link.ply"));
  fs::create_hard_link(bar_, in_.file("hard.ply"));
  const std::string dot = (fs::path(in_.path()) / "." / "bar.ply").string();
  for (const char* cmd : {"field", "deform"})
    for (const std::string& out : {in_.file("link.ply"), in_.file("hard.ply"), dot}) {
      const Result r =
          cli(std::string(cmd) + " " + quote(bar_) + " -s " + quote(scenario_) + " -o " + quote(out));
      EXPECT_NE(r.code, 0) << cmd << " -o " << out;
      EXPECT_TRUE(contains(r.err, "refusing to overwrite the input")) << r.err;
    }
  // The report may not replace the input or the scenario either.
  for (const std::string& report : {in_.file("link.ply"), scenario_}) {
    const Result r = cli("deform " + quote(bar_) + " -s " + quote(scenario_) + " -o " +
                         quote(out_.file("o.ply")) + " --report " + quote(report));
    EXPECT_NE(r.code, 0) << report;
    EXPECT_TRUE(listing(out_).empty());
  }
  EXPECT_EQ(slurp(bar_), before);
  EXPECT_EQ(slurp(scenario_), scenario_before);
  EXPECT_TRUE(fs::is_symlink(in_.file("link.ply")));
}

// --report at paths that are not plain files: "-" is stdout (the summary then goes to stderr);
// a symbolic link is followed and stays a link; a FIFO (and so /dev/stdout, a pipe here) is
// written to, not replaced.
TEST_F(CliErrors, ReportToStdoutLinksAndFifos) {
  const std::string base = "deform " + quote(bar_) + " -s " + quote(scenario_) + " -o ";
  Result r = cli(base + quote(out_.file("a.ply")) + " --report -");
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);  // stdout is the report alone
  EXPECT_GT(j.at("points").get<int>(), 0);
  EXPECT_TRUE(contains(r.err, "clusters")) << r.err;  // the summary line

  fs::create_directories(out_.path() / "reports");
  fs::create_symlink("reports/real.json", out_.file("link.json"));
  r = cli(base + quote(out_.file("b.ply")) + " --report " + quote(out_.file("link.json")));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::is_symlink(out_.file("link.json")));
  EXPECT_GT(nlohmann::json::parse(slurp(out_.file("reports/real.json"))).at("points").get<int>(), 0);

  const std::string fifo = out_.file("r.fifo"), got = out_.file("got.json");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  r = shell("timeout 60 cat " + quote(fifo) + " > " + quote(got) + " & " + quote(HGD_TOOL) + " " + base +
            quote(out_.file("c.ply")) + " --report " + quote(fifo) + "; s=$?; wait; exit $s");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_GT(nlohmann::json::parse(slurp(got)).at("points").get<int>(), 0);

  // /dev/stdout through a link (never the real /dev/stdout: a regression would replace it).
  fs::create_symlink("/dev/stdout", out_.file("stdout.json"));
  r = cli(base + quote(out_.file("d.ply")) + " -q --report " + quote(out_.file("stdout.json")));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_GT(nlohmann::json::parse(r.out).at("points").get<int>(), 0);
  EXPECT_TRUE(fs::is_symlink(out_.file("stdout.json")));
}

// `--report -` into a pipe whose reader went away: SIGPIPE ended the run after the shape was
// written, so the output of a failed run stayed. The run fails with a message and takes the
// shape back, as for any report that cannot be written.
TEST_F(CliErrors, ReportToAClosedPipeFailsAndLeavesNoOutput) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  ::close(fds[0]);  // no reader
  const std::string log = in_.file("log.txt");
  const pid_t pid =
      startTool({"deform", bar_, "-s", scenario_, "-o", out_.file("o.ply"), "--report", "-"}, fds[1], log);
  ASSERT_GT(pid, 0);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status) << ": " << slurp(log);
  EXPECT_EQ(WEXITSTATUS(status), 1) << slurp(log);
  EXPECT_TRUE(
      contains(slurp(log), "hgdeform deform: -: cannot write the report to standard output: Broken pipe"))
      << slurp(log);
  EXPECT_TRUE(listing(out_).empty()) << "left " << *listing(out_).begin();
}

// A full disk (/dev/full: every write fails with ENOSPC). The report cannot be written: exit 1
// and the shape written before it is taken back. The shape cannot be written (a link named .ply
// to /dev/full, as outputs are told by their extension): exit 1 and no report.
TEST_F(CliErrors, FullDiskLeavesNoOutput) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  const std::string base = "deform " + quote(bar_) + " -s " + quote(scenario_) + " -o ";
  Result r = cli(base + quote(out_.file("o.ply")) + " --report /dev/full");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "/dev/full: cannot write: No space left on device")) << r.err;
  EXPECT_TRUE(listing(out_).empty()) << "left " << *listing(out_).begin();

  fs::create_symlink("/dev/full", out_.file("full.ply"));
  for (const char* cmd : {"field", "deform"}) {
    r = cli(std::string(cmd) + " " + quote(bar_) + " -s " + quote(scenario_) + " -o " +
            quote(out_.file("full.ply")) +
            (cmd == std::string("deform") ? " --report " + quote(out_.file("r.json")) : ""));
    EXPECT_EQ(r.code, 1) << cmd << ": " << r.err;
    EXPECT_TRUE(contains(r.err, "full.ply: cannot write: No space left on device")) << cmd << ": " << r.err;
    EXPECT_EQ(listing(out_), std::set<std::string>{"full.ply"}) << cmd;
    EXPECT_TRUE(fs::is_symlink(out_.file("full.ply")));
  }
}

// A report at /dev/stdout, /dev/stderr, /dev/fd/N or /proc/self/fd/N is written to that
// descriptor, as "-" is (the issue: with stdout redirected to a file, /dev/stdout led through
// /proc/self/fd/1 to that file, which was replaced: `>> log.txt` lost the log's earlier lines).
TEST_F(CliErrors, ReportAtADescriptorPathIsWrittenToTheDescriptor) {
  const std::string earlier = "an earlier line of the log\n";
  fs::create_symlink("/dev/stdout", out_.file("stdout.json"));
  struct Case {
    std::string report, redirect;
  };
  const std::vector<Case> cases = {
      {"/dev/stdout", ">>"},           {"/dev/stderr", "2>>"}, {"/dev/fd/1", ">>"},
      {"/proc/self/fd/1", ">>"},       {"/dev/fd/3", "3>>"},   {"/proc/self/fd/3", "3>>"},
      {out_.file("stdout.json"), ">>"}};
  int k = 0;
  for (const Case& c : cases) {
    SCOPED_TRACE(c.report + " " + c.redirect);
    const std::string log = in_.file("log.txt");
    writeText(log, earlier);
    struct stat before {};
    ASSERT_EQ(::stat(log.c_str(), &before), 0);
    const std::string output = out_.file("o" + std::to_string(k++) + ".ply");
    const Result r =
        shell("( " + quote(HGD_TOOL) + " deform " + quote(bar_) + " -s " + quote(scenario_) + " -o " +
              quote(output) + " -q --report " + quote(c.report) + " " + c.redirect + " " + quote(log) + " )");
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::exists(output));
    struct stat after {};
    ASSERT_EQ(::stat(log.c_str(), &after), 0);
    EXPECT_EQ(after.st_ino, before.st_ino) << "the log was replaced";
    const std::string text = slurp(log);
    ASSERT_EQ(text.rfind(earlier, 0), 0u) << text.substr(0, 200);
    std::string json = text.substr(earlier.size());
    json = json.substr(
        0, json.find("\nhgdeform: ") == std::string::npos ? json.size() : json.find("\nhgdeform: "));
    EXPECT_GT(nlohmann::json::parse(json).at("points").get<int>(), 0);
  }
  EXPECT_TRUE(fs::is_symlink(out_.file("stdout.json")));
}

// A loop of symbolic links is refused, naming the path (the issue: the report replaced l1 with
// a regular file); the shape written before the report is taken back.
TEST_F(CliErrors, SymlinkLoopIsRefused) {
  fs::create_symlink("l1", out_.file("l2"));
  fs::create_symlink("l2", out_.file("l1"));
  fs::create_symlink("b.ply", out_.file("a.ply"));
  fs::create_symlink("a.ply", out_.file("b.ply"));
  const std::string base = "deform " + quote(bar_) + " -s " + quote(scenario_) + " -o ";
  const std::set<std::string> links = {"l1", "l2", "a.ply", "b.ply"};
  Result r = cli(base + quote(out_.file("o.ply")) + " --report " + quote(out_.file("l1")));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(contains(r.err, out_.file("l1") + ": cannot write: Too many levels of symbolic links"))
      << r.err;
  EXPECT_EQ(listing(out_), links);
  for (const char* cmd : {"field", "deform"}) {
    r = cli(std::string(cmd) + " " + quote(bar_) + " -s " + quote(scenario_) + " -o " +
            quote(out_.file("a.ply")));
    EXPECT_EQ(r.code, 1) << cmd << ": " << r.err;
    EXPECT_TRUE(contains(r.err, out_.file("a.ply") + ": cannot write: Too many levels of symbolic links"))
        << cmd << ": " << r.err;
    EXPECT_EQ(listing(out_), links) << cmd;
  }
  for (const auto& name : links) EXPECT_TRUE(fs::is_symlink(out_.file(name))) << name;
}

// hgdeform-bench's --json is an output like every other: it never replaces the mesh it reads
// (the issue: --armadillo m.ply --json m.ply overwrote the mesh with JSON), however spelt.
TEST(CliBench, JsonNeverReplacesTheMesh) {
  TempDir dir;
  const std::string mesh = dir.file("m.ply");
  hgd::writeShape(mesh, hgd::shapes::barMesh());
  const std::string before = slurp(mesh);
  for (const std::string& json : {mesh, (dir.path() / "." / "m.ply").string()}) {
    const Result r = shell(quote(HGD_BENCH) + " --models armadillo --armadillo " + quote(mesh) + " --json " +
                           quote(json) + " --sizes 500 --clusters 4 --repeat 1");
    EXPECT_EQ(r.code, 1) << r.out << r.err;
    EXPECT_TRUE(contains(r.err, json + ": refusing to overwrite the input " + mesh)) << r.err;
    EXPECT_TRUE(slurp(mesh) == before) << "the mesh was replaced";
  }
  EXPECT_EQ(listing(dir), std::set<std::string>{"m.ply"});
}

}  // namespace
