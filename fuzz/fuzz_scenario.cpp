// libFuzzer target: the scenario parser. Any input must parse or throw hgd::ScenarioError;
// a crash, a sanitizer report or any other exception is a bug.
#include <cstddef>
#include <cstdint>
#include <string>

#include "hgdeform/app/scenario.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const hgd::Scenario s = hgd::parseScenario(text, "fuzz.json");
    // What parses must serialise and parse back to the same regions and moves.
    const hgd::Scenario again = hgd::parseScenario(hgd::scenarioToJson(s), "fuzz-roundtrip.json");
    if (again.fixed.size() != s.fixed.size() || again.joints.size() != s.joints.size() ||
        again.moves.size() != s.moves.size() || again.clusters != s.clusters)
      __builtin_trap();
  } catch (const hgd::ScenarioError&) {
  }
  return 0;
}
