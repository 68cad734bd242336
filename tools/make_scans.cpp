// hgdeform-make-scans OUT_DIR COUNT POINTS: writes COUNT procedural scans (bumpy planes of about
// POINTS points, alternately PLY and PCD) and scenario.json, for timing `hgdeform batch`.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>

#include "cli_common.h"
#include "hgdeform/io/cleanup.h"
#include "hgdeform/io/io.h"
#include "support/shapes.h"

int main(int argc, char** argv) {
  hgd::removeTemporaryFilesOnSignals();  // no partial scan left by an interrupted run
  std::filesystem::path dir;
  long count = 0, points = 0;
  {
    CLI::App app(
        "Writes COUNT procedural scans (bumpy planes of about POINTS points, alternately PLY and\n"
        "PCD) and scenario.json into OUT_DIR, for timing `hgdeform batch`.");
    hgdcli::configureApp(app, "hgdeform-make-scans");
    app.add_option("OUT_DIR", dir, "the folder to write (created)")->required()->type_name("");
    app.add_option("COUNT", count, "number of scans, at least 1")
        ->required()
        ->check(hgdcli::integerFrom(1, 1000000))
        ->type_name("");
    app.add_option("POINTS", points, "points per scan, at least 100")
        ->required()
        ->check(hgdcli::integerFrom(100, 1000000000))
        ->type_name("");
    if (const int status = hgdcli::parse(app, argc, argv); status >= 0) return status;
  }
  // bumpyPlane samples (cells + 1)^2 points with cells = round(1 / h).
  const double cells = std::max(2.0, std::round(std::sqrt(static_cast<double>(points))) - 1);
  try {
    std::filesystem::create_directories(dir);
    const float h = static_cast<float>(1.0 / cells);
    for (long i = 0; i < count; ++i) {
      char name[64];
      std::snprintf(name, sizeof name, "scan_%03ld.%s", i, i % 2 ? "pcd" : "ply");
      const int bumps = 3 + static_cast<int>(i % 4);
      const float height = 0.04f + 0.01f * static_cast<float>(i % 3);
      hgd::shapes::writeBumpyPlane((dir / name).string(), bumps, height, h);  // a row at a time
    }
    hgd::writeFileAtomically((dir / "scenario.json").string(), hgd::shapes::kBumpyPlaneScenario);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hgdeform-make-scans: %s\n", e.what());
    return 1;
  }
  std::printf("%ld scans of %.0f points and scenario.json in %s\n", count, (cells + 1) * (cells + 1),
              dir.c_str());
  return 0;
}
