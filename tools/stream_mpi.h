// One scan split across MPI ranks (`mpirun hgdeform deform --mpi`): MPI as hgd::StreamRanks.
#pragma once

#include <memory>

#include "hgdeform/io/records.h"

namespace hgdcli {

/// MPI for one run: initialised when the program was started by an MPI launcher (mpirun,
/// srun), finalised when this goes. Without one, or in a build without MPI, one process.
class StreamMpi {
 public:
  StreamMpi();
  ~StreamMpi();
  StreamMpi(const StreamMpi&) = delete;
  StreamMpi& operator=(const StreamMpi&) = delete;
  /// Whether this build has MPI at all.
  static bool available();
  /// Whether an MPI launcher started the program (MPI was initialised).
  bool launched() const { return launched_; }
  int rank() const { return rank_; }
  int size() const { return size_; }
  /// Waits until every rank got here, or 30 seconds (a rank that left does not hold the others).
  void settle();
  /// The ranks as a streamed run takes them (null for one process).
  hgd::StreamRanks* ranks() { return size_ > 1 ? ranks_.get() : nullptr; }

 private:
  bool launched_ = false;
  int rank_ = 0, size_ = 1;
  std::unique_ptr<hgd::StreamRanks> ranks_;
};

}  // namespace hgdcli
