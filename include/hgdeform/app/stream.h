// A scenario run on a scan streamed from its file (`hgdeform deform --stream`): the coarse
// level by passes, the build and the moves on it, the deformed file written block by block.
// What it writes is what the run on the file read whole writes, byte for byte.
#pragma once

#include <string>

#include "hgdeform/app/report.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/app/session.h"
#include "hgdeform/io/records.h"
#include "hgdeform/multires/streamed.h"

namespace hgd {

/// The scenario's regions over the file's records (as resolveHandles resolves them over the
/// shape read whole: the file's own values, the points `level` keeps). Throws ScenarioError as
/// resolveHandles does.
/// With `ranks` (a split run), each rank tests its share of the records and the lists are
/// gathered: every rank returns the same handles.
RecordHandles streamHandles(const Scenario& scenario, const RecordLayout& layout, const StreamedLevel& level,
                            StreamRanks* ranks = nullptr);

/// Whether a streamed run can deform `input` into `output`, by the header alone (a mesh's faces
/// are not read): a cloud whose points are records read in place (binary PLY or PCD:
/// readRecordLayout), written in its own format. What a front end asks before choosing to
/// stream a shape that does not fit in memory (the memory's reason stands otherwise).
bool canStream(const std::string& input, const std::string& output);

/// Runs `scenario` on `input` streamed and writes the deformed file at `output` (binary, the
/// input's format). A mesh, or a shape whose build the file read whole would make at full
/// resolution (not more points than multires_above), is refused before the build. Throws IoError or
/// ScenarioError naming the problem; nothing is left at `output` then.
/// With `ranks` (a split run: `mpirun hgdeform deform --mpi`), every rank calls it with the same
/// arguments: each reads its share of the records, the passes are gathered, every rank builds the
/// same deformer from the same level and writes its share of the one output (the bytes one
/// process writes); every rank returns the same report, and throws what any rank met.
DeformReport streamDeform(const std::string& input, const Scenario& scenario, const RunOptions& options,
                          const std::string& output, StreamRanks* ranks = nullptr);

}  // namespace hgd
