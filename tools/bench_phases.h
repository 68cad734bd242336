// hgdeform-bench's thread scaling of the build: the Deformer built on one thread and on every
// thread, alternately, and each phase's time (BuildTimings::phases) at both; between the builds,
// what the machine itself gives at both: an arithmetic loop (no memory, nothing serial), a
// streaming pass and random reads over every point.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>

#include "hgdeform/deformer/deformer.h"

namespace hgdbench {

/// `repeat` builds at 1 thread and `repeat` at every thread (omp_get_max_threads()),
/// alternating; medians: {"threads", "build_1_ms", "build_n_ms", "arithmetic_1_ms",
/// "arithmetic_n_ms", "stream_1_ms", "stream_n_ms", "random_1_ms", "random_n_ms", "phases":
/// [{"name", "ms_1", "ms_n"}]} (a phase run twice in one build counts once, summed).
nlohmann::json buildPhaseScaling(const std::shared_ptr<const hgd::Geometry>& geometry,
                                 const hgd::Handles& handles, const hgd::DeformOptions& options, int repeat);

/// Prints the table of buildPhaseScaling()'s result for one (model, size).
void printPhaseScaling(const std::string& model, long points, const nlohmann::json& scaling);

}  // namespace hgdbench
